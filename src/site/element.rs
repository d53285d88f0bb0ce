//! One experimental element of `rths site`: a client's connection (TCP or UDP), its own actuator
//! on the virtual rig, the predictor-corrector, the identified rig's lead compensation and the
//! supervisor, every controller tick recorded (docs/site.md).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::time::{Duration, Instant};

use rths_core::compensator::{Compensator, Lead, LeadParams};
use rths_core::hal::{Actuator, Daq, Error as _, Sample};
use rths_core::params::{SpecimenScale, DT_S};
use rths_core::predictor_corrector::{PcParams, PredictorCorrector};
use rths_core::supervisor::{Limits, State, Supervisor};
use rths_hal_sim::{RigConfig, VirtualRig};

use super::protocol::{self, Action, Handshake, Message, HANDSHAKE_BYTES};
use crate::link_host;

/// Polynomial order of the predictor-corrector (cubic).
pub const PC_ORDER: usize = 3;

/// What an element knows of its rig before the test: what was identified.
#[derive(Debug, Clone, Copy)]
pub struct ElementSetup {
    /// The virtual rig.
    pub rig: RigConfig,
    /// The identified lead filter (the rig's delay compensation).
    pub lead: LeadParams,
    /// The identified specimen stiffness at the actuator, kN/mm (specimen scale).
    pub specimen_k_kn_per_mm: f64,
    /// Rig time over analysis time (≥ 1: a slowed-down test).
    pub rate_factor: f64,
}

/// One controller tick, as `rths link run --out` records it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SiteRow {
    /// Tick from the start.
    pub tick: u32,
    /// Supervisor state after the tick.
    pub state: State,
    /// Command sent at this tick, mm.
    pub command_mm: f64,
    /// Target (the predictor-corrector's) at this tick, mm.
    pub target_mm: f64,
    /// Measured displacement read at this tick, mm.
    pub measured_mm: f64,
    /// Measured force read at this tick, kN.
    pub force_kn: f64,
}

/// How an element's test ended.
#[derive(Debug, Clone)]
pub struct ElementOutcome {
    /// Integration steps served.
    pub steps: u64,
    /// Ticks per step.
    pub ticks_per_step: u32,
    /// Server time per step (a new target received → its force replied), s, each step.
    pub step_latency_s: Vec<f64>,
    /// The supervisor's last state.
    pub state: State,
    /// Why the test stopped early (the client's fault or a supervisor trip), if it did.
    pub stop_reason: Option<String>,
    /// Every tick.
    pub rows: Vec<SiteRow>,
    /// The client's DOFs.
    pub dofs: usize,
}

/// A client's connection: whole messages in, replies out.
pub enum Channel {
    /// TCP: a stream, Nagle off, quick ACKs re-armed after each receive.
    Tcp(TcpStream),
    /// UDP: one datagram per message, to and from the client's address.
    Udp(UdpSocket, SocketAddr),
}

impl Channel {
    /// Exactly `len` bytes (TCP) or one datagram of at most `len + 1` bytes (UDP: longer is
    /// oversized and reported by its length).
    fn recv(&mut self, len: usize) -> std::io::Result<Vec<u8>> {
        match self {
            Channel::Tcp(s) => {
                let mut b = vec![0u8; len];
                s.read_exact(&mut b)?;
                // The client leaves Nagle on and waits for ACKs of its no-reply messages.
                let _ = socket2::SockRef::from(&*s).set_quickack(true);
                Ok(b)
            }
            Channel::Udp(s, peer) => loop {
                let mut b = vec![0u8; len + 1];
                let (got, from) = s.recv_from(&mut b)?;
                if from != *peer {
                    eprintln!("site: ignored a datagram from {from}: a test with {peer} runs");
                    continue;
                }
                b.truncate(got);
                return Ok(b);
            },
        }
    }

    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        match self {
            Channel::Tcp(s) => s.write_all(bytes),
            Channel::Udp(s, peer) => s.send_to(bytes, *peer).map(|_| ()),
        }
    }
}

/// Set up a TCP connection for the protocol: no Nagle, quick ACKs.
pub fn tune_tcp(s: &TcpStream) {
    let _ = s.set_nodelay(true);
    let _ = socket2::SockRef::from(s).set_quickack(true);
}

/// The actuator of one element and its control: rig, predictor-corrector, lead, supervisor.
struct Actuation {
    rig: VirtualRig,
    supervisor: Supervisor,
    lead: Compensator,
    pc: Option<PredictorCorrector>,
    scale: SpecimenScale,
    last: Sample,
    rows: Vec<SiteRow>,
    tick: u32,
    stop: Option<String>,
}

impl Actuation {
    /// One controller tick: read the DAQ, ask for `requested_mm` (specimen), the supervisor
    /// decides, the rig holds the command for the tick.
    fn tick(&mut self, requested_mm: f64, target_mm: f64) {
        let sample = self.rig.read().map_err(|e| e.kind());
        if let Ok(s) = sample {
            self.last = s;
        }
        let d = self.supervisor.tick(requested_mm, sample, false);
        let (m, f) = sample.map_or((f64::NAN, f64::NAN), |s| (s.disp_mm, s.force_kn));
        self.rows.push(SiteRow {
            tick: self.tick,
            state: d.state,
            command_mm: d.command_mm,
            target_mm,
            measured_mm: m,
            force_kn: f,
        });
        if let (State::Fault(r), None) = (d.state, &self.stop) {
            self.stop = Some(format!("supervisor: {}", r.name()));
        }
        self.tick = self.tick.saturating_add(1);
        // The supervisor's command is finite and within the stroke: the rig takes it.
        let _ = self.rig.command(d.command_mm);
        self.rig.advance_tick();
    }

    /// The step to `target_mm` (specimen) over the predictor-corrector's ticks; false if the
    /// supervisor tripped.
    fn step_to(&mut self, target_mm: f64) -> bool {
        let Some(pc) = self.pc.as_mut() else {
            return false;
        };
        if pc.set_target(target_mm).is_err() {
            return false;
        }
        loop {
            let Some(pc) = self.pc.as_mut() else {
                return false;
            };
            let t = pc.tick();
            let requested = self
                .lead
                .compensate(t.command_mm, self.last.disp_mm)
                .unwrap_or(f64::NAN);
            self.tick(requested, t.command_mm);
            if matches!(self.supervisor.state(), State::Fault(_)) {
                return false;
            }
            if t.step_done {
                return true;
            }
        }
    }

    /// Bring the actuator to a safe state: trip the supervisor (its ramp to the safe position)
    /// with `reason` logged, and run the ramp to its end.
    fn safe_stop(&mut self, reason: String) {
        eprintln!("site: {reason}: the actuator ramps to its safe position");
        if self.stop.is_none() {
            self.stop = Some(reason);
        }
        self.supervisor.emergency_stop();
        self.settle();
    }

    /// Tick (holding the request) until the supervisor is at rest; bounded (a ramp over the whole
    /// stroke at the slowest rate is well inside).
    fn settle(&mut self) {
        let out = self.supervisor.output_mm();
        for _ in 0..(120.0 / DT_S) as usize {
            if self.supervisor.at_rest() {
                break;
            }
            self.tick(out, f64::NAN);
        }
    }
}

/// The element's force of the actuator's measured force at the target (corrected to the
/// target with the identified stiffness: `F + k̂·(d − x_m)`), prototype units, in the basic
/// system of an element of `dofs` (1: the DOF's force; 2: `[−F, F]`).
fn element_force(dofs: usize, force_kn: f64) -> Vec<f64> {
    if dofs == 1 {
        vec![force_kn]
    } else {
        vec![-force_kn, force_kn]
    }
}

/// The element's n × n stiffness of a spring of `k` (column-major).
fn element_matrix(dofs: usize, k: f64) -> Vec<f64> {
    if dofs == 1 {
        vec![k]
    } else {
        vec![k, -k, -k, k]
    }
}

/// The actuator's deformation for an element's displacements: the DOF (n = 1) or the second
/// node's minus the first's (n = 2).
fn deformation(m: &Message) -> f64 {
    match m.disp.as_slice() {
        [d] => *d,
        [a, b] => b - a,
        _ => f64::NAN,
    }
}

/// Serve one client on `channel` to its DIE (or a fault): the whole test of one element.
pub fn serve(mut channel: Channel, setup: &ElementSetup) -> anyhow::Result<ElementOutcome> {
    let hs_bytes = channel.recv(HANDSHAKE_BYTES)?;
    let hs: Handshake = protocol::parse_handshake(&hs_bytes)?;
    if hs.dofs > 2 {
        anyhow::bail!(
            "the element has {} basic DOFs: an element drives one actuator, from one DOF (n = 1) \
             or the deformation between two nodes' DOFs (n = 2)",
            hs.dofs
        );
    }
    let params = setup.rig.build()?;
    let mut a = Actuation {
        rig: VirtualRig::new(params),
        supervisor: Supervisor::new(Limits::paper_actuator()),
        lead: Compensator::Lead(Lead::new(setup.lead)),
        pc: None,
        scale: SpecimenScale::default(),
        last: Sample::default(),
        rows: Vec::new(),
        tick: 0,
        stop: None,
    };
    // The supervisor armed from the start: its checks run while the client connects.
    a.supervisor
        .arm()
        .map_err(|e| anyhow::anyhow!("arming: {e:?}"))?;
    a.supervisor
        .start()
        .map_err(|e| anyhow::anyhow!("starting: {e:?}"))?;
    a.tick(0.0, 0.0);
    let k_proto =
        a.scale.prototype_force_kn(setup.specimen_k_kn_per_mm) / a.scale.prototype_disp_mm(1.0);
    let (mut steps, mut ticks_per_step) = (0u64, 0u32);
    let mut latency = Vec::new();
    // (time, deformation) of the step under way: at rest at time 0 (the analysis's first update).
    let mut last_trial: Option<(f64, f64)> = Some((0.0, 0.0));
    let mut t_prev = 0.0f64;
    let mut force_proto = 0.0f64;
    let mut step_started: Option<Instant> = None;
    let zero = vec![0.0; hs.dofs * hs.dofs];
    loop {
        let bytes = match channel.recv(hs.message_bytes()) {
            Ok(b) => b,
            Err(e) => {
                a.safe_stop(format!("the client vanished mid-test ({e})"));
                break;
            }
        };
        let msg = match protocol::parse_message(&bytes, &hs) {
            Ok(m) => m,
            Err(e) => {
                a.safe_stop(format!("bad message from the client: {e}"));
                break;
            }
        };
        match msg.action {
            Action::SetTrialResponse => {
                let d = deformation(&msg);
                match last_trial {
                    // The corrected velocity and acceleration of the same target: nothing to do.
                    Some((t, d0)) if t == msg.time_s && d0.to_bits() == d.to_bits() => continue,
                    Some((t, _)) if t == msg.time_s => {
                        a.safe_stop(
                            "a second trial displacement within a step (an iterative algorithm: \
                             use an explicit integrator with algorithm Linear)"
                                .into(),
                        );
                        break;
                    }
                    _ => {}
                }
                let dt = msg.time_s - t_prev;
                let ticks = dt * setup.rate_factor / DT_S;
                let n = ticks.round();
                if !(n >= 1.0 && (ticks - n).abs() < 1e-3 && n <= f64::from(u32::MAX)) {
                    a.safe_stop(format!(
                        "the integration step {dt} s × rate factor {} is {ticks:.4} controller \
                         ticks, not a whole number ≥ 1 (Δt = 1/2048 s)",
                        setup.rate_factor
                    ));
                    break;
                }
                let n = n as u32;
                match a.pc {
                    None => {
                        a.pc = Some(PredictorCorrector::new(
                            PcParams::new(n, PC_ORDER)
                                .map_err(|e| anyhow::anyhow!("predictor-corrector: {e:?}"))?,
                        ));
                        ticks_per_step = n;
                    }
                    Some(_) if n != ticks_per_step => {
                        a.safe_stop(format!(
                            "the integration step changed from {ticks_per_step} to {n} ticks"
                        ));
                        break;
                    }
                    Some(_) => {}
                }
                step_started = Some(Instant::now());
                last_trial = Some((msg.time_s, d));
                t_prev = msg.time_s;
                let target = a.scale.specimen_disp_mm(d);
                if !a.step_to(target) {
                    let why = a
                        .stop
                        .clone()
                        .unwrap_or_else(|| "the step was refused".into());
                    a.safe_stop(why);
                    break;
                }
                steps += 1;
                let f_spec =
                    a.last.force_kn + setup.specimen_k_kn_per_mm * (target - a.last.disp_mm);
                force_proto = a.scale.prototype_force_kn(f_spec);
            }
            Action::CommitState => {}
            Action::GetForce => {
                channel.send(&protocol::encode_reply(
                    &element_force(hs.dofs, force_proto),
                    hs.data_size,
                ))?;
                if let Some(t0) = step_started.take() {
                    latency.push(t0.elapsed().as_secs_f64());
                }
            }
            Action::GetInitialStiff | Action::GetTangentStiff => channel.send(
                &protocol::encode_reply(&element_matrix(hs.dofs, k_proto), hs.data_size),
            )?,
            // The specimen's damping and inertia are in the measured force.
            Action::GetDamp | Action::GetMass => {
                channel.send(&protocol::encode_reply(&zero, hs.data_size))?
            }
            Action::Die => {
                // The end of the test: the supervisor ramps the actuator to zero.
                let _ = a.supervisor.finish();
                a.settle();
                break;
            }
        }
    }
    Ok(ElementOutcome {
        steps,
        ticks_per_step,
        step_latency_s: latency,
        state: a.supervisor.state(),
        stop_reason: a.stop,
        rows: a.rows,
        dofs: hs.dofs,
    })
}

/// Accept the UDP client: its 'a', our 'b'; then its address is the test's.
pub fn udp_accept(sock: UdpSocket) -> std::io::Result<Channel> {
    let mut b = [0u8; 64];
    loop {
        let (n, from) = sock.recv_from(&mut b)?;
        if n == 1 && b[0] == b'a' {
            sock.send_to(b"b", from)?;
            return Ok(Channel::Udp(sock, from));
        }
        eprintln!("site: ignored a {n}-byte datagram from {from} before the client's 'a'");
    }
}

/// The recording of an element: `# key: value` header lines and the rows in `rths link run
/// --out`'s CSV.
pub fn write_recording(
    path: &std::path::Path,
    header: &link_host::RunHeader,
    rows: &[SiteRow],
) -> std::io::Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    for l in header.lines() {
        writeln!(w, "{l}")?;
    }
    writeln!(w, "{}", link_host::CSV_HEADER)?;
    for r in rows {
        let t = rths_link::Telemetry {
            seq: r.tick,
            tick: r.tick,
            state: run_state(r.state),
            command_mm: r.command_mm,
            target_mm: r.target_mm,
            measured_mm: r.measured_mm,
            force_kn: r.force_kn,
        };
        writeln!(w, "{}", link_host::csv_row(&t))?;
    }
    w.flush()
}

/// The link's state of a supervisor state (the recording's names).
fn run_state(s: State) -> rths_link::RunState {
    use rths_link::RunState as R;
    match s {
        State::Idle => R::Idle,
        State::Armed => R::Armed,
        State::Running => R::Running,
        State::RampDown => R::RampDown,
        State::Done => R::Done,
        State::Fault(r) => R::Fault(r.code()),
    }
}

/// Median and largest of `xs`, s (0 for none).
pub fn median_max(xs: &[f64]) -> (f64, f64) {
    let mut v = xs.to_vec();
    v.sort_by(f64::total_cmp);
    let med = v.get(v.len() / 2).copied().unwrap_or(0.0);
    (med, v.last().copied().unwrap_or(0.0))
}

/// A read timeout that ends a test whose client has gone silent (a client that hangs without
/// closing its socket), long enough for any analysis step.
pub const SILENT_CLIENT: Duration = Duration::from_secs(60);
