//! One experimental element of `rths site`: a client's connection (TCP or UDP) served to its
//! DIE, its targets imposed by the element's [`Experiment`] (the virtual rig or the board), the
//! force returned, every controller tick recorded (docs/site.md).

use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream, UdpSocket};
use std::sync::mpsc;
use std::time::{Duration, Instant};

use rths_core::params::{SpecimenScale, DT_S};
use rths_link::RunState;

use super::experiment::{Experiment, PacingStats, SiteRow};
use super::protocol::{self, Action, Handshake, Message, HANDSHAKE_BYTES};
use crate::link_host;

/// What an element knows of its rig before the test: what was identified, and the pace.
#[derive(Debug, Clone, Copy)]
pub struct ElementSetup {
    /// The identified specimen stiffness at the actuator, kN/mm (specimen scale).
    pub specimen_k_kn_per_mm: f64,
    /// Rig time over analysis time (≥ 1: a slowed-down test).
    pub rate_factor: f64,
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
    pub state: RunState,
    /// Why the test stopped early (the client's fault or a supervisor trip), if it did.
    pub stop_reason: Option<String>,
    /// Every tick.
    pub rows: Vec<SiteRow>,
    /// The client's DOFs.
    pub dofs: usize,
    /// The wall-clock pacing achieved (a paced virtual rig).
    pub pacing: Option<PacingStats>,
}

/// A client's connection: whole messages in, replies out.
pub enum ElementChannel {
    /// TCP: a stream, Nagle off, quick ACKs re-armed after each receive.
    Tcp(TcpStream),
    /// UDP: one datagram per message, to and from the client's address.
    Udp(UdpSocket, SocketAddr),
}

impl ElementChannel {
    /// Exactly `len` bytes (TCP) or one datagram of at most `len + 1` bytes (UDP: longer is
    /// oversized and reported by its length).
    fn recv(&mut self, len: usize) -> std::io::Result<Vec<u8>> {
        match self {
            ElementChannel::Tcp(s) => {
                let mut b = vec![0u8; len];
                s.read_exact(&mut b)?;
                // The client leaves Nagle on and waits for ACKs of its no-reply messages.
                let _ = socket2::SockRef::from(&*s).set_quickack(true);
                Ok(b)
            }
            ElementChannel::Udp(s, peer) => loop {
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

    fn try_clone(&self) -> std::io::Result<Self> {
        Ok(match self {
            ElementChannel::Tcp(s) => ElementChannel::Tcp(s.try_clone()?),
            ElementChannel::Udp(s, peer) => ElementChannel::Udp(s.try_clone()?, *peer),
        })
    }

    fn send(&mut self, bytes: &[u8]) -> std::io::Result<()> {
        match self {
            ElementChannel::Tcp(s) => s.write_all(bytes),
            ElementChannel::Udp(s, peer) => s.send_to(bytes, *peer).map(|_| ()),
        }
    }
}

/// Set up a TCP connection for the protocol: no Nagle, quick ACKs.
pub fn tune_tcp(s: &TcpStream) {
    let _ = s.set_nodelay(true);
    let _ = socket2::SockRef::from(s).set_quickack(true);
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

/// The client's messages, read by their own thread (so that a paced rig ticks while it waits).
fn reader(mut ch: ElementChannel, len: usize) -> mpsc::Receiver<std::io::Result<Vec<u8>>> {
    let (tx, rx) = mpsc::sync_channel(64);
    std::thread::spawn(move || loop {
        let r = ch.recv(len);
        let failed = r.is_err();
        if tx.send(r).is_err() || failed {
            break;
        }
    });
    rx
}

/// The next message: waiting for it, a paced rig ticks at its deadlines.
fn next_message(
    rx: &mpsc::Receiver<std::io::Result<Vec<u8>>>,
    exp: &mut dyn Experiment,
) -> std::io::Result<Vec<u8>> {
    loop {
        let wait = match exp.idle_deadline() {
            Some(dl) => dl.saturating_duration_since(Instant::now()),
            None => SILENT_CLIENT,
        };
        match rx.recv_timeout(wait) {
            Ok(r) => return r,
            Err(mpsc::RecvTimeoutError::Timeout) if exp.idle_deadline().is_some() => {
                exp.idle_tick()
            }
            Err(mpsc::RecvTimeoutError::Timeout) => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::TimedOut,
                    "no message for 60 s",
                ))
            }
            Err(mpsc::RecvTimeoutError::Disconnected) => {
                return Err(std::io::Error::new(
                    std::io::ErrorKind::UnexpectedEof,
                    "the connection's reader ended",
                ))
            }
        }
    }
}

/// Serve one client on `channel` to its DIE (or a fault): the whole test of one element.
pub fn serve(
    mut channel: ElementChannel,
    setup: &ElementSetup,
    exp: &mut dyn Experiment,
) -> anyhow::Result<ElementOutcome> {
    let hs_bytes = channel.recv(HANDSHAKE_BYTES)?;
    let hs: Handshake = protocol::parse_handshake(&hs_bytes)?;
    if hs.dofs > 2 {
        anyhow::bail!(
            "the element has {} basic DOFs: an element drives one actuator, from one DOF (n = 1) \
             or the deformation between two nodes' DOFs (n = 2)",
            hs.dofs
        );
    }
    let rx = reader(channel.try_clone()?, hs.message_bytes());
    let scale = SpecimenScale::default();
    let k_proto =
        scale.prototype_force_kn(setup.specimen_k_kn_per_mm) / scale.prototype_disp_mm(1.0);
    let (mut steps, mut ticks_per_step) = (0u64, 0u32);
    let mut latency = Vec::new();
    // (time, deformation) of the step under way: at rest at time 0 (the analysis's first update).
    let mut last_trial: Option<(f64, f64)> = Some((0.0, 0.0));
    let mut t_prev = 0.0f64;
    let mut force_proto = 0.0f64;
    let mut step_started: Option<Instant> = None;
    let mut stop: Option<String> = None;
    let mut stop_with = |exp: &mut dyn Experiment, reason: String| {
        eprintln!("site: {reason}: the actuator ramps to its safe position");
        exp.safe_stop();
        stop.get_or_insert(reason);
    };
    let zero = vec![0.0; hs.dofs * hs.dofs];
    loop {
        let bytes = match next_message(&rx, exp) {
            Ok(b) => b,
            Err(e) => {
                stop_with(exp, format!("the client vanished mid-test ({e})"));
                break;
            }
        };
        let msg = match protocol::parse_message(&bytes, &hs) {
            Ok(m) => m,
            Err(e) => {
                stop_with(exp, format!("bad message from the client: {e}"));
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
                        stop_with(
                            exp,
                            "a second trial displacement within a step (an iterative algorithm: \
                             use an explicit integrator with algorithm Linear)"
                                .into(),
                        );
                        break;
                    }
                    Some((t, _)) if msg.time_s < t => {
                        stop_with(
                            exp,
                            format!(
                                "a trial at time {} s after one at {t} s (a datagram out of order \
                                 or repeated)",
                                msg.time_s
                            ),
                        );
                        break;
                    }
                    _ => {}
                }
                let dt = msg.time_s - t_prev;
                let ticks = dt * setup.rate_factor / DT_S;
                let n = ticks.round();
                if !(n >= 1.0 && (ticks - n).abs() < 1e-3 && n <= f64::from(u32::MAX)) {
                    stop_with(
                        exp,
                        format!(
                            "the integration step {dt} s × rate factor {} is {ticks:.4} controller \
                             ticks, not a whole number ≥ 1 (Δt = 1/2048 s)",
                            setup.rate_factor
                        ),
                    );
                    break;
                }
                let n = n as u32;
                if ticks_per_step == 0 {
                    if let Err(e) = exp.begin(n) {
                        stop_with(exp, format!("the site could not start: {e}"));
                        break;
                    }
                    ticks_per_step = n;
                } else if n != ticks_per_step {
                    stop_with(
                        exp,
                        format!(
                            "the integration step changed from {ticks_per_step} to {n} ticks (a \
                             datagram lost, or a variable step)"
                        ),
                    );
                    break;
                }
                step_started = Some(Instant::now());
                last_trial = Some((msg.time_s, d));
                t_prev = msg.time_s;
                let target = scale.specimen_disp_mm(d);
                let r = match exp.step(d) {
                    Ok(r) => r,
                    Err(e) => {
                        stop_with(exp, e.to_string());
                        break;
                    }
                };
                if !(r.measured_mm.is_finite() && r.force_kn.is_finite()) {
                    stop_with(exp, "no DAQ reading at the step's end".into());
                    break;
                }
                steps += 1;
                let f_spec = r.force_kn + setup.specimen_k_kn_per_mm * (target - r.measured_mm);
                force_proto = scale.prototype_force_kn(f_spec);
            }
            Action::CommitState => {}
            Action::GetForce => {
                // The client sends the last trial's response with every action: a getForce of
                // another trial means that trial never arrived (UDP: a datagram lost or
                // reordered), and the force of the last one would be taken for it.
                let d = deformation(&msg);
                if let Some((t, d0)) = last_trial {
                    if t != msg.time_s || d0.to_bits() != d.to_bits() {
                        stop_with(
                            exp,
                            format!(
                                "a getForce for the trial at {} s that the site never received \
                                 (the last was at {t} s: a datagram lost or reordered)",
                                msg.time_s
                            ),
                        );
                        break;
                    }
                }
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
                exp.finish();
                break;
            }
        }
    }
    Ok(ElementOutcome {
        steps,
        ticks_per_step,
        step_latency_s: latency,
        state: exp.state(),
        stop_reason: stop,
        rows: exp.take_rows(),
        dofs: hs.dofs,
        pacing: exp.pacing(),
    })
}

/// Accept the UDP client: its 'a', our 'b'; then its address is the test's.
pub fn udp_accept(sock: UdpSocket) -> std::io::Result<ElementChannel> {
    let mut b = [0u8; 64];
    loop {
        let (n, from) = sock.recv_from(&mut b)?;
        if n == 1 && b[0] == b'a' {
            sock.send_to(b"b", from)?;
            return Ok(ElementChannel::Udp(sock, from));
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
            state: r.state,
            command_mm: r.command_mm,
            target_mm: r.target_mm,
            measured_mm: r.measured_mm,
            force_kn: r.force_kn,
        };
        writeln!(w, "{}", link_host::csv_row(&t))?;
    }
    w.flush()
}

/// Median and largest of `xs`, s (0 for none).
pub fn median_max(xs: &[f64]) -> (f64, f64) {
    let mut v = xs.to_vec();
    let med = rths_core::metrics::median(&mut v).unwrap_or(0.0);
    (med, v.last().copied().unwrap_or(0.0))
}

/// A read timeout that ends a test whose client has gone silent (a client that hangs without
/// closing its socket), long enough for any analysis step.
pub const SILENT_CLIENT: Duration = Duration::from_secs(60);
