//! `rths link`: drive and record a test on a board over the command link (a serial port, a TCP socket
//! to QEMU's serial port, or a QEMU started here).

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::{Args as ClapArgs, Subcommand};

use crate::cmd::analyze::load_motion;
use crate::link_host::{self, Link, Qemu, RecordSummary, RunHeader};
use crate::machinery::model_file::ModelFile;

/// `rths link` arguments.
#[derive(Debug, ClapArgs)]
#[command(group(clap::ArgGroup::new("to").required(true).args(["port", "tcp", "qemu"])))]
pub struct Args {
    /// A serial device (a USB-serial adapter on the board's link UART, e.g. /dev/ttyUSB0, or a pty).
    #[arg(long, value_name = "PATH")]
    pub port: Option<String>,
    /// Baud rate of --port.
    #[arg(long, default_value_t = 2_000_000)]
    pub baud: u32,
    /// A TCP address of QEMU's link port (its second serial port: `-serial null -serial
    /// tcp:127.0.0.1:PORT,server=on,wait=off`); loopback.
    #[arg(long, value_name = "HOST:PORT")]
    pub tcp: Option<String>,
    /// Start QEMU here on this firmware ELF (built with `--features link`) for this one command.
    #[arg(long, value_name = "ELF")]
    pub qemu: Option<PathBuf>,
    /// How long to wait for an answer, s.
    #[arg(long, default_value_t = 10.0)]
    pub timeout_s: f64,
    /// What to do.
    #[command(subcommand)]
    pub command: LinkCommand,
}

/// The link's requests.
#[derive(Debug, Subcommand)]
pub enum LinkCommand {
    /// Print what the device holds and its state: the analytical part (kind, compiled in or
    /// uploaded, checksum), the ground-motion record (source, length, checksum), the rig
    /// compensation (checksum), the limits, the rate, the firmware build, and the counters.
    Status {
        /// One JSON object on stdout instead of the table.
        #[arg(long)]
        json: bool,
    },
    /// Upload a model file, a ground-motion record and/or a rig file's compensation (each validated
    /// on the device; refused whole, the old one kept).
    #[command(group(clap::ArgGroup::new("what").required(true).multiple(true).args(["model", "structure", "fe_ats", "motion", "rig"])))]
    Upload {
        /// A model file of any kind (`rths train lr|lrx|rnn`: LR, LRX, an RNN of up to 32 units;
        /// with --structure that structure's model: `rths train meta|nonlinear`), whatever the
        /// firmware's compiled-in part; refused `TickBudget` if the board's tick cannot run it
        /// (RNN-10 on a Cortex-M4 at 2048 Hz).
        #[arg(long, conflicts_with = "fe_ats")]
        model: Option<PathBuf>,
        /// A structure file: alone, its finite elements (linear, or its yielding stories); with
        /// --model, that structure's metamodel, modal-hysteretic model or (an imported structure)
        /// reduced model. With --rig, the structure part gets the rig's compensation (`nl-online`,
        /// `meta-online`, `fe-online-lead`).
        #[arg(long, value_name = "S.json", conflicts_with = "fe_ats")]
        structure: Option<PathBuf>,
        /// With --structure and --rig: the displacement scale (prototype over rig) of the
        /// structure's specimen on the rig; the force scale follows from the rig file's
        /// identified specimen stiffness.
        #[arg(long, default_value_t = 1.0, value_name = "L")]
        length_scale: f64,
        /// Make the analytical part the device's finite elements with the ATS, starting from the
        /// paper's delay (`rths simulate --scenario fe-online-ats`), whatever its compiled-in part.
        #[arg(long)]
        fe_ats: bool,
        /// A ground motion: an AT2/CSV file or an embedded record name, held whole (up to the
        /// device's capacity; `run --motion` streams a longer one).
        #[arg(long, value_name = "PATH|NAME")]
        motion: Option<String>,
        /// Multiplies the ground acceleration (applied here, before the upload).
        #[arg(long, default_value_t = 1.0, value_name = "S")]
        scale: f64,
        /// A rig file (`rths identify`): the compensation the firmware's controller takes from it
        /// (FE + ATS: the ATS's initial values; LRX: the lead filter and the specimen's mass and
        /// damping; a structure part: the lead filter with its adaptation, the identified specimen
        /// that corrects the measured force, the specimen scale). Sent after --model.
        #[arg(long, value_name = "RIG.json")]
        rig: Option<PathBuf>,
        /// LRX or a structure part with --rig: the lead's adaptation time constant, ticks (0:
        /// fixed), as `rths train lrx --rig` and `rths simulate --scenario nl-online` default it.
        #[arg(long, default_value_t = crate::machinery::train::lrx::RIG_LEAD_ADAPT_TICKS)]
        lead_adapt_ticks: f64,
    },
    /// Set the stroke, velocity and force limits (at rest, command at 0 mm).
    Limits {
        /// ±mm.
        #[arg(long)]
        stroke_mm: f64,
        /// mm/s.
        #[arg(long)]
        velocity_mm_s: f64,
        /// ±kN.
        #[arg(long)]
        force_kn: f64,
    },
    /// Arm the test.
    Arm {
        /// Telemetry decimation: one record every N ticks.
        #[arg(long, default_value_t = 1)]
        telemetry_every: u16,
        /// If the host falls silent for 1 s during the run, or a streamed record's samples do not
        /// arrive in time: complete the test (those ticks at 0 g, counted), or ramp down.
        #[arg(long, value_enum, default_value = "complete")]
        on_link_loss: LinkLossArg,
    },
    /// Start the armed test.
    Start,
    /// Abort: ramp the command to zero.
    Abort,
    /// Record the telemetry of the run in progress until it ends.
    Record {
        /// CSV output.
        #[arg(long)]
        out: PathBuf,
        /// Give up after this long without a message, s.
        #[arg(long, default_value_t = 30.0)]
        idle_timeout_s: f64,
    },
    /// The whole test: [upload], arm, start, record to CSV (with a header for `rths report`) until
    /// the run ends.
    Run {
        /// Upload this model first (any kind, as `upload --model`).
        #[arg(long, conflicts_with = "fe_ats")]
        model: Option<PathBuf>,
        /// Upload this structure's part first (as `upload --structure`: its finite elements, or
        /// with --model its model).
        #[arg(long, value_name = "S.json", conflicts_with = "fe_ats")]
        structure: Option<PathBuf>,
        /// With --structure and --rig: the displacement scale of the structure's specimen on the
        /// rig (as `upload --length-scale`).
        #[arg(long, default_value_t = 1.0, value_name = "L")]
        length_scale: f64,
        /// Make the analytical part the device's FE + ATS first (as `upload --fe-ats`).
        #[arg(long)]
        fe_ats: bool,
        /// Upload this rig file's compensation first (after --model; as `upload --rig`, with the
        /// lead's adaptation of `rths train lrx --rig`).
        #[arg(long, value_name = "RIG.json")]
        rig: Option<PathBuf>,
        /// Upload this ground motion first (an AT2/CSV file or an embedded record name; one longer
        /// than the device holds is streamed during the run); without it the device plays the
        /// record it holds.
        #[arg(long, value_name = "PATH|NAME")]
        motion: Option<String>,
        /// Multiplies the ground acceleration of --motion (applied here, before the upload).
        #[arg(long, default_value_t = 1.0, value_name = "S")]
        scale: f64,
        /// Telemetry decimation.
        #[arg(long, default_value_t = 1)]
        telemetry_every: u16,
        /// If this host falls silent for 1 s during the run (it sends a status every 250 ms while
        /// recording), or a streamed record's samples do not arrive in time: complete the test
        /// (those ticks at 0 g, counted), or ramp down.
        #[arg(long, value_enum, default_value = "complete")]
        on_link_loss: LinkLossArg,
        /// CSV output.
        #[arg(long)]
        out: PathBuf,
        /// Give up after this long without a message, s.
        #[arg(long, default_value_t = 30.0)]
        idle_timeout_s: f64,
    },
    /// Characterize the rig through the board: the device plays the identification excitation
    /// (supervisor armed as in a test) and streams every tick back; the host estimates as `rths
    /// identify` does and writes the same rig file (refused, nothing written, on a lost sample or
    /// a trip).
    Identify {
        /// The rig file to write (only if every sample arrived and every check passed).
        #[arg(long, value_name = "RIG.json")]
        out: PathBuf,
        /// The figure (default: the rig file's name with `.png`).
        #[arg(long, value_name = "PNG")]
        figure: Option<PathBuf>,
        /// Peak excitation, mm (at most 2.54, 10% of the stroke).
        #[arg(long, default_value_t = 2.0, value_name = "MM")]
        amplitude_mm: f64,
        /// Lead-filter tap spacing, ticks (1..=8).
        #[arg(long, default_value_t = 8)]
        lead_stride: usize,
        /// Give up after this long without a message, s.
        #[arg(long, default_value_t = 30.0)]
        idle_timeout_s: f64,
    },
}

/// Record to `out` (no header); fails (after writing the file) if anything was lost.
pub fn record_csv(
    link: &mut Link,
    out: &std::path::Path,
    idle: Duration,
) -> anyhow::Result<RecordSummary> {
    record_csv_with(link, out, idle, None)
}

/// Record to `out`, `header` first (`# key: value` lines, what `rths report` reads).
pub fn record_csv_with(
    link: &mut Link,
    out: &std::path::Path,
    idle: Duration,
    header: Option<&RunHeader>,
) -> anyhow::Result<RecordSummary> {
    let f =
        std::fs::File::create(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut w = std::io::BufWriter::new(f);
    if let Some(h) = header {
        for l in h.lines() {
            writeln!(w, "{l}")?;
        }
    }
    writeln!(w, "{}", link_host::CSV_HEADER)?;
    let s = link.record(idle, 0, |t| writeln!(w, "{}", link_host::csv_row(t)))?;
    w.flush()?;
    Ok(s)
}

fn report(s: &RecordSummary, out: &std::path::Path) -> anyhow::Result<()> {
    crate::outln!("wrote {} ({} records)", out.display(), s.records);
    if let Some((state, ticks, sent, dropped)) = s.end {
        crate::outln!(
            "run ended: {} after {ticks} ticks; device sent {sent} records, its queue dropped {dropped}",
            link_host::state_name(state)
        );
    }
    if let Some(e) = &s.stream_status_error {
        anyhow::bail!(
            "the device did not say whether the streamed record reached it in time ({e}): the run \
             cannot be trusted as the record's"
        );
    }
    if let Some(st) = &s.stream {
        crate::outln!(
            "record streamed: {} samples arrived, {} chunk(s) sent again, checksum {}, {} tick(s) \
             without their samples{}",
            st.received,
            s.stream_resent,
            match st.checksum_ok {
                Some(true) => "matched",
                Some(false) => "MISMATCHED",
                None => "not checked (samples missing)",
            },
            st.underrun_ticks,
            st.first_underrun_tick
                .map_or(String::new(), |t| format!(" (the first at tick {t})"))
        );
        if st.underrun_ticks > 0 || st.checksum_ok != Some(true) {
            anyhow::bail!(
                "the streamed record did not reach the device in time: {} tick(s) ran without \
                 their samples (0 g under --on-link-loss complete; ramp-down stops at the first); \
                 the link carries too few samples per second for this record: a faster link, or \
                 the record at a lower sampling rate (docs/link.md \"Records streamed\")",
                st.underrun_ticks
            );
        }
    }
    if !s.complete() {
        anyhow::bail!(
            "the recording is incomplete: {} gap(s), {} record(s) missing, {} bad frame(s), end {:?}",
            s.gaps.len(),
            s.missing,
            s.bad_frames,
            s.end
        );
    }
    match s.end {
        Some((state, ticks, _, _)) if link_host::state_name(state).starts_with("fault-") => {
            Err(crate::cmd::RunStopped(format!(
                "the device's run ended in {} after {ticks} ticks",
                link_host::state_name(state)
            ))
            .into())
        }
        _ => Ok(()),
    }
}

/// The duration of a `--…-s` flag: a positive number of seconds that a `Duration` holds (a
/// negative, NaN or huge one is refused, never a panic).
fn seconds(flag: &str, s: f64) -> anyhow::Result<Duration> {
    match Duration::try_from_secs_f64(s) {
        Ok(d) if s > 0.0 => Ok(d),
        _ => anyhow::bail!(
            "{flag} must be a positive number of seconds, got {}",
            rths_files::readable(s)
        ),
    }
}

/// Run `rths link`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let timeout = seconds("--timeout-s", a.timeout_s)?.max(Duration::from_millis(10));
    let dir = if a.qemu.is_some() {
        tempfile_dir()?
    } else {
        PathBuf::new()
    };
    let mut qemu = None;
    let mut link = if let Some(p) = &a.port {
        Link::serial(p, a.baud)?
    } else if let Some(t) = &a.tcp {
        Link::tcp(t)?
    } else if let Some(elf) = &a.qemu {
        let q = Qemu::start(elf, &dir)?;
        qemu = Some(q);
        match qemu.as_mut() {
            Some(q) => std::mem::replace(&mut q.link, Link::new(Box::new(NullPort))),
            None => anyhow::bail!("qemu did not start"),
        }
    } else {
        anyhow::bail!("one of --port, --tcp, --qemu is required");
    };
    link.timeout = timeout;
    if qemu.is_none() {
        link.wait_ready(timeout)?;
    }
    match a.command {
        LinkCommand::Status { json } => {
            let s = link.status()?;
            let h = link.holdings()?;
            if json {
                crate::outln!("{}", status_json(&s, &h));
            } else {
                print_status(&s, &h);
            }
        }
        LinkCommand::Upload {
            model,
            structure,
            length_scale,
            fe_ats,
            motion,
            scale,
            rig,
            lead_adapt_ticks,
        } => {
            let part = upload_part(&mut link, model.as_deref(), structure.as_deref())?;
            if fe_ats {
                upload_fe_ats(&mut link)?;
            }
            if let Some(p) = rig {
                upload_rig(&mut link, &p, lead_adapt_ticks, part.as_ref(), length_scale)?;
            }
            if let Some(spec) = motion {
                upload_motion(&mut link, &spec, scale, MotionTo::Whole)?;
            }
        }
        LinkCommand::Limits {
            stroke_mm,
            velocity_mm_s,
            force_kn,
        } => {
            link.set_limits(stroke_mm, velocity_mm_s, force_kn)?;
            crate::outln!("limits set");
        }
        LinkCommand::Arm {
            telemetry_every,
            on_link_loss,
        } => {
            link.arm_with(telemetry_every, on_link_loss.into())?;
            crate::outln!("armed");
        }
        LinkCommand::Start => {
            link.start()?;
            crate::outln!("started");
        }
        LinkCommand::Abort => {
            link.abort()?;
            crate::outln!("aborting: ramp to zero");
        }
        LinkCommand::Record {
            out,
            idle_timeout_s,
        } => {
            let s = record_csv(
                &mut link,
                &out,
                seconds("--idle-timeout-s", idle_timeout_s)?,
            )?;
            report(&s, &out)?;
        }
        LinkCommand::Run {
            model,
            structure,
            length_scale,
            fe_ats,
            rig,
            motion,
            scale,
            telemetry_every,
            on_link_loss,
            out,
            idle_timeout_s,
        } => {
            let mut h = RunHeader::default();
            let part = upload_part(&mut link, model.as_deref(), structure.as_deref())?;
            if let Some(p) = &model {
                h.set("model", p.display());
            }
            if fe_ats {
                upload_fe_ats(&mut link)?;
                h.set("model", "fe-ats");
            }
            if let Some(p) = &rig {
                let c = upload_rig(
                    &mut link,
                    p,
                    crate::machinery::train::lrx::RIG_LEAD_ADAPT_TICKS,
                    part.as_ref(),
                    length_scale,
                )?;
                h.set("rig", p.display());
                h.set("rig_checksum", format!("{c:08x}"));
            }
            match &motion {
                Some(spec) => {
                    let (name, streamed) = upload_motion(&mut link, spec, scale, MotionTo::Run)?;
                    h.set("motion", spec);
                    h.set("motion_name", name);
                    h.set("record_streamed", if streamed { "yes" } else { "no" });
                    if streamed && matches!(on_link_loss, LinkLossArg::Complete) {
                        crate::outln!(
                            "note: under --on-link-loss complete a tick whose samples arrive late \
                             plays 0 g (counted, and the run fails afterwards); ramp-down stops \
                             the test at the first instead"
                        );
                    }
                    h.set("scale", format!("{scale:?}"));
                }
                None => {
                    // The compiled-in record: El Centro (`firmware/build.rs`), embedded in the host
                    // too; `rths report` checks its checksum against the device's.
                    h.set("motion", "el-centro");
                    h.set("scale", "1.0");
                }
            }
            let st = link.status()?;
            if motion.is_none() && st.record.source == rths_link::RecordSource::Uploaded {
                anyhow::bail!(
                    "the device holds an uploaded record (checksum {:08x}) that this host cannot \
                     name: give --motion",
                    st.record.checksum
                );
            }
            if motion.is_none() && st.record.source == rths_link::RecordSource::Streamed {
                anyhow::bail!(
                    "the device's record in force is a streamed one (checksum {:08x}), which only \
                     the host that streams it can run: give --motion",
                    st.record.checksum
                );
            }
            h.set("record_checksum", format!("{:08x}", st.record.checksum));
            h.set("record_samples", st.record.samples);
            h.set("record_dt_s", format!("{:?}", st.record.dt_s));
            h.set("record_ticks", st.record.ticks);
            h.set("model_kind", link_host::model_kind_name(st.model_kind));
            h.set("model_checksum", format!("{:08x}", st.model_checksum));
            h.set("scenario", scenario_of(st.model_kind, rig.is_some()));
            match &structure {
                // A structure part: the structure file it stands for, and the rig's mapping.
                Some(s) => {
                    h.set("structure", s.display());
                    // `rths report` refuses a structure file of another checksum.
                    let text = std::fs::read_to_string(s)
                        .with_context(|| format!("reading structure file {}", s.display()))?;
                    h.set(
                        "structure_checksum",
                        rths_files::nl_model_file::structure_checksum(&text)
                            .with_context(|| format!("structure file {}", s.display()))?,
                    );
                    h.set("length_scale", format!("{length_scale:?}"));
                }
                // The structure the firmware's controller is built for (`analytical.rs`): the
                // paper's frame with its nominal brace; the reference is that structure's response.
                None => h.set("structure", "paper"),
            }
            h.set("specimen", "linear");
            h.set("specimen_stiffness_factor", "1.0");
            h.set("telemetry_every", telemetry_every);
            h.set(
                "limits",
                format!(
                    "{:?} mm, {:?} mm/s, {:?} kN",
                    st.stroke_mm, st.velocity_mm_s, st.force_kn
                ),
            );
            h.set(
                "link",
                match (&a.port, &a.tcp) {
                    (Some(p), _) => format!("serial {p}"),
                    (_, Some(t)) => format!("tcp {t}"),
                    _ => "qemu".to_string(),
                },
            );
            h.set("on_link_loss", format!("{on_link_loss:?}"));
            // One connection arms and starts: the test is this host's (another host's start is
            // refused; an abort is not).
            link.arm_owned(telemetry_every, on_link_loss.into())?;
            link.start()?;
            crate::outln!("running");
            let s = record_csv_with(
                &mut link,
                &out,
                seconds("--idle-timeout-s", idle_timeout_s)?,
                Some(&h),
            )?;
            report(&s, &out)?;
        }
        LinkCommand::Identify {
            out,
            figure,
            amplitude_mm,
            lead_stride,
            idle_timeout_s,
        } => {
            let to = match (&a.port, &a.tcp) {
                (Some(p), _) => To::Serial(p.clone()),
                (_, Some(t)) => To::Emulated(format!("tcp {t}")),
                _ => To::Emulated("qemu".into()),
            };
            identify(
                &mut link,
                &to,
                out,
                figure,
                amplitude_mm,
                lead_stride,
                seconds("--idle-timeout-s", idle_timeout_s)?,
            )?;
        }
    }
    if let Some(q) = qemu {
        let out = q.stdout();
        if let Some(line) = out.lines().rev().find(|l| l.starts_with("RESULT ")) {
            crate::outln!("{line}");
        }
        drop(q);
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(())
}

/// What the device does if the host falls silent during a run.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum LinkLossArg {
    /// Run the test to its end.
    Complete,
    /// Ramp the command down to zero and end the run.
    RampDown,
}

impl From<LinkLossArg> for rths_link::LinkLoss {
    fn from(a: LinkLossArg) -> Self {
        match a {
            LinkLossArg::Complete => Self::Complete,
            LinkLossArg::RampDown => Self::RampDown,
        }
    }
}

/// The scenario a device's analytical part runs (its figures' id in `rths report`); a structure
/// part is named by its rig compensation (`compensated`), as core's controller names it.
fn scenario_of(kind: rths_link::ModelKind, compensated: bool) -> &'static str {
    use rths_link::ModelKind as K;
    match (kind, compensated) {
        (K::Lr, _) => "lr-online",
        (K::Lrx, _) => "lrx-online",
        // The shipped RNN is the 10-unit one.
        (K::Rnn, _) => "rnn-online-10",
        (K::FeAts, _) => "fe-online-ats",
        (K::StructureModal | K::StructureHysteron, true) => "nl-online",
        (K::StructureReduced | K::StructureMeta, true) => "meta-online",
        (K::StructureFe | K::StructureNl, true) => "fe-online-lead",
        (K::StructureFe, false) => "structure-fe",
        (K::StructureNl, false) => "structure-nl",
        (K::StructureMeta, false) => "structure-meta",
        (K::StructureModal, false) => "structure-modal",
        (K::StructureReduced, false) => "structure-reduced",
        (K::StructureHysteron, false) => "structure-hysteron",
    }
}

/// The status table of `rths link status`.
fn print_status(s: &rths_link::Status, h: &rths_link::Holdings) {
    crate::outln!("state            {}", link_host::state_name(s.state));
    crate::outln!(
        "model            {}, {}, checksum {:08x}",
        link_host::model_kind_name(h.model_kind),
        link_host::record_source_name(h.model_source),
        h.model_checksum
    );
    let r = s.record;
    crate::outln!(
        "record           {}: {} samples at {} s ({:.2} s, {} ticks), scale {}, checksum {:08x}",
        link_host::record_source_name(r.source),
        r.samples,
        r.dt_s,
        f64::from(r.samples.saturating_sub(1)) * r.dt_s,
        r.ticks,
        r.scale,
        r.checksum
    );
    crate::outln!(
        "record capacity  {} samples ({:.1} s at 0.01 s, {:.1} s at 0.02 s)",
        s.record_capacity,
        f64::from(s.record_capacity.saturating_sub(1)) * 0.01,
        f64::from(s.record_capacity.saturating_sub(1)) * 0.02
    );
    if h.rig_checksum == 0 {
        crate::outln!("rig compensation none (this analytical part has none)");
    } else {
        crate::outln!(
            "rig compensation {}, checksum {:08x}",
            link_host::record_source_name(h.rig_source),
            h.rig_checksum
        );
    }
    crate::outln!(
        "limits           ±{} mm, {} mm/s, ±{} kN",
        s.stroke_mm,
        s.velocity_mm_s,
        s.force_kn
    );
    crate::outln!("rate             {} Hz", h.rate_hz);
    crate::outln!("build            {:08x}", h.build_id);
    crate::outln!("tick             {}", s.tick);
    crate::outln!(
        "records sent     {} (dropped by the device: {})",
        s.records_sent,
        s.records_dropped
    );
    crate::outln!("bad frames       {}", s.bad_frames);
}

/// The JSON of `rths link status --json`.
fn status_json(s: &rths_link::Status, h: &rths_link::Holdings) -> serde_json::Value {
    let r = s.record;
    let hex = |c: u32| format!("{c:08x}");
    serde_json::json!({
        "state": link_host::state_name(s.state),
        "model": {
            "kind": link_host::model_kind_name(h.model_kind),
            "source": link_host::record_source_name(h.model_source),
            "checksum": hex(h.model_checksum),
        },
        "record": {
            "source": link_host::record_source_name(r.source),
            "samples": r.samples,
            "dt_s": r.dt_s,
            "duration_s": f64::from(r.samples.saturating_sub(1)) * r.dt_s,
            "ticks": r.ticks,
            "scale": r.scale,
            "checksum": hex(r.checksum),
            "capacity_samples": s.record_capacity,
        },
        "rig": if h.rig_checksum == 0 {
            serde_json::Value::Null
        } else {
            serde_json::json!({
                "source": link_host::record_source_name(h.rig_source),
                "checksum": hex(h.rig_checksum),
            })
        },
        "limits": {
            "stroke_mm": s.stroke_mm,
            "velocity_mm_s": s.velocity_mm_s,
            "force_kn": s.force_kn,
        },
        "rate_hz": h.rate_hz,
        "build_id": hex(h.build_id),
        "tick": s.tick,
        "records_sent": s.records_sent,
        "records_dropped": s.records_dropped,
        "bad_frames": s.bad_frames,
    })
}

/// Upload the compensation rig file `p` gives the device's analytical part; its checksum. A
/// structure part (`part`, uploaded in the same command) maps the rig's specimen to the
/// structure's at `length_scale`.
fn upload_rig(
    link: &mut Link,
    p: &std::path::Path,
    lead_adapt_ticks: f64,
    part: Option<&rths_files::upload::LaidOut>,
    length_scale: f64,
) -> anyhow::Result<u32> {
    let rig = crate::machinery::identify::RigFile::load(p)
        .with_context(|| format!("rig file {}", p.display()))?;
    let kind = link.status()?.model_kind;
    let v = match part.and_then(|l| l.specimen_k_kn_per_mm.filter(|_| l.kind == kind)) {
        Some(k) => link_host::structure_rig_values(&rig, k, length_scale, lead_adapt_ticks)?,
        None => link_host::rig_values(&rig, kind, lead_adapt_ticks)?,
    };
    let c = link.upload_rig(kind, &v).map_err(|e| {
        with_budget_reason(e, || match part {
            Some(l) => budget_figures_laid(l, true),
            None => String::from("the board's tick cannot run it"),
        })
    })?;
    crate::outln!(
        "uploaded the rig compensation of {} for {} (checksum {c:08x})",
        p.display(),
        link_host::model_kind_name(kind)
    );
    Ok(c)
}

/// Upload the analytical part the files name: a model file alone (`upload_model`; a floor-hysteron
/// model alone is a structure's part), or a structure's part (its finite elements, or with `model`
/// its model); the structure's part laid out, for its rig compensation.
fn upload_part(
    link: &mut Link,
    model: Option<&std::path::Path>,
    structure: Option<&std::path::Path>,
) -> anyhow::Result<Option<rths_files::upload::LaidOut>> {
    // A floor-hysteron model carries its floors: it goes alone as a structure's part.
    let alone = structure.is_none() && model.is_some_and(rths_files::upload::is_self_contained);
    if structure.is_none() && !alone {
        if let Some(p) = model {
            upload_model(link, p)?;
        }
        return Ok(None);
    }
    if let (Some(m), Some(s)) = (model, structure) {
        if rths_files::upload::is_self_contained(m) {
            let text = std::fs::read_to_string(s)
                .with_context(|| format!("reading structure file {}", s.display()))?;
            crate::machinery::train::nonlinear::floors::check_model_file_elastic(m, &text)?;
        }
    }
    let laid = rths_files::upload::lay_out_files(model, structure, rths_core::params::DT_S)?;
    let c = link
        .upload_laid_out(&laid)
        .map_err(|e| with_budget_reason(e, || budget_figures_laid(&laid, false)))?;
    crate::outln!(
        "uploaded the {} ({} values, checksum {c:08x})",
        laid.what,
        laid.values.len()
    );
    Ok(Some(laid))
}

/// The board cannot run the structure part `laid` (with its rig compensation if `with_rig`): the
/// estimate on each core at the controller's rate.
fn budget_figures_laid(laid: &rths_files::upload::LaidOut, with_rig: bool) -> String {
    use rths_app::tick_cost::TickBudget;
    let Ok(dims) = rths_link::layout::dims(laid.kind, &laid.values) else {
        return format!("the board's tick cannot run the {}", laid.what);
    };
    let rate = f64::from(rths_core::params::CONTROL_RATE_HZ);
    let est = |b: &TickBudget| {
        if with_rig {
            b.instr_with_rig(laid.kind, &dims)
        } else {
            b.instr_dims(laid.kind, &dims)
        }
    };
    let (m4, m7) = (
        TickBudget::cortex_m4_168mhz(rate),
        TickBudget::cortex_m7_480mhz(rate),
    );
    let pct = |b: &TickBudget| 100.0 * est(b) / b.instr_per_tick();
    format!(
        "the board's tick cannot run the {}{}: estimated {:.0} instructions per tick on a \
         Cortex-M4, {:.0} % of its tick at 168 MHz and {rate} Hz ({:.0} on a Cortex-M7: {:.1} % \
         at 480 MHz; not measured on a core: infinite) (docs/link.md)",
        laid.what,
        if with_rig {
            " with its rig compensation"
        } else {
            ""
        },
        est(&m4),
        pct(&m4),
        est(&m7),
        pct(&m7),
    )
}

fn upload_model(link: &mut Link, p: &std::path::Path) -> anyhow::Result<()> {
    let m = ModelFile::load(p).with_context(|| format!("model {}", p.display()))?;
    let c = link
        .upload(&m)
        .map_err(|e| with_budget_reason(e, || tick_budget_reason(&m)))?;
    crate::outln!("uploaded {} (checksum {c:08x})", p.display());
    Ok(())
}

/// Make the device's analytical part its FE + ATS (the ATS from the paper's delay).
fn upload_fe_ats(link: &mut Link) -> anyhow::Result<()> {
    let delay_s = rths_core::params::PAPER_DELAY_STEPS as f64 * rths_core::params::DT_S;
    let c = link.upload_fe_ats(delay_s).map_err(|e| {
        with_budget_reason(e, || {
            budget_figures(rths_link::ModelKind::FeAts, 0, "FE + ATS")
        })
    })?;
    crate::outln!(
        "analytical part: the device's FE + ATS, the ATS from {:.4} s (checksum {c:08x})",
        delay_s
    );
    Ok(())
}

/// `e`, with `why()` as its context if the device refused the upload `TickBudget`.
fn with_budget_reason(e: link_host::LinkHostError, why: impl FnOnce() -> String) -> anyhow::Error {
    let budget = matches!(
        e,
        link_host::LinkHostError::Refused(_, rths_link::NackReason::TickBudget)
    );
    let e = anyhow::Error::new(e);
    if budget {
        e.context(why())
    } else {
        e
    }
}

/// Why the board's tick cannot run `m`, in the budget's figures for both cores (the host does not
/// know which core the board has).
fn tick_budget_reason(m: &ModelFile) -> String {
    use crate::machinery::model_file::ModelKind as FileKind;
    match (m.kind, m.rnn.as_ref()) {
        (FileKind::Rnn, Some(r)) => budget_figures(
            rths_link::ModelKind::Rnn,
            r.hidden,
            &format!("RNN-{}", r.hidden),
        ),
        (FileKind::Lrx, _) => budget_figures(rths_link::ModelKind::Lrx, 0, "LRX"),
        _ => budget_figures(rths_link::ModelKind::Lr, 0, "LR"),
    }
}

/// The board cannot run `name` in its tick: the estimate on each core at the controller's rate.
fn budget_figures(kind: rths_link::ModelKind, hidden: usize, name: &str) -> String {
    use rths_app::tick_cost::TickBudget;
    let rate = f64::from(rths_core::params::CONTROL_RATE_HZ);
    let m4 = TickBudget::cortex_m4_168mhz(rate);
    let m7 = TickBudget::cortex_m7_480mhz(rate);
    format!(
        "the board's tick cannot run {name}: estimated {:.0} instructions per tick on a Cortex-M4,          {:.0} % of its tick at 168 MHz and {rate} Hz ({:.0} on a Cortex-M7: {:.1} % at 480 MHz);          a smaller model or a Cortex-M7 board (docs/link.md)",
        m4.instr(kind, hidden),
        m4.pct_of_tick(kind, hidden),
        m7.instr(kind, hidden),
        m7.pct_of_tick(kind, hidden),
    )
}

/// How a ground motion goes to the device.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum MotionTo {
    /// Held whole before the run (`rths link upload`): a record longer than the device holds is
    /// refused here, naming the command that streams it.
    Whole,
    /// For the run that follows (`rths link run`): held whole if it fits, else streamed during
    /// the run.
    Run,
}

/// Upload the ground motion `spec` (a file or an embedded name) × `scale`; its name and whether it
/// is streamed.
fn upload_motion(
    link: &mut Link,
    spec: &str,
    scale: f64,
    to: MotionTo,
) -> anyhow::Result<(String, bool)> {
    if !(scale.is_finite() && scale > 0.0) {
        anyhow::bail!(
            "--scale must be a positive number, got {}",
            rths_files::readable(scale)
        );
    }
    let m = load_motion(Some(spec))?;
    let scaled = m.scaled(scale);
    let capacity = link.status()?.record_capacity as usize;
    let n = scaled.accel_g.len();
    let streamed = capacity > 0 && n > capacity;
    if streamed && to == MotionTo::Whole {
        anyhow::bail!(
            "ground motion {}: {n} samples, the device holds {capacity}; `rths link run --motion` \
             streams a longer record during the run",
            scaled.name
        );
    }
    let c = if streamed {
        link.stream_record(&scaled.accel_g, scaled.dt_s, scale)?
    } else {
        link.upload_record(&scaled.accel_g, scaled.dt_s, scale)?
    };
    crate::outln!(
        "{} ground motion {} ({n} samples at {} s, checksum {c:08x}{})",
        if streamed { "streaming" } else { "uploaded" },
        scaled.name,
        scaled.dt_s,
        if streamed {
            format!("; {capacity} held at a time, the rest sent during the run")
        } else {
            String::new()
        }
    );
    Ok((scaled.name, streamed))
}

/// A port that is never used (the placeholder left in `Qemu` once its link is taken).
struct NullPort;

impl std::io::Read for NullPort {
    fn read(&mut self, _: &mut [u8]) -> std::io::Result<usize> {
        Ok(0)
    }
}

impl std::io::Write for NullPort {
    fn write(&mut self, b: &[u8]) -> std::io::Result<usize> {
        Ok(b.len())
    }
    fn flush(&mut self) -> std::io::Result<()> {
        Ok(())
    }
}

impl link_host::Port for NullPort {
    fn set_timeout(&mut self, _: Duration) -> std::io::Result<()> {
        Ok(())
    }
}

/// A directory for QEMU's files (defmt.bin, stdout): `rths-link-qemu` in the system temp dir.
fn tempfile_dir() -> anyhow::Result<PathBuf> {
    let d = std::env::temp_dir().join(format!("rths-link-qemu-{}", std::process::id()));
    std::fs::create_dir_all(&d)?;
    Ok(d)
}

/// Which rig a link drives.
enum To {
    /// A board on a serial port: a real rig (its rig file's board is `link`).
    Serial(String),
    /// An emulated board (QEMU): its plant is `boards/emulated`'s virtual rig, the `unr-compact`
    /// preset with a linear specimen and noise seed 1, so its rig file is that virtual rig's
    /// (board `virtual`): `rths simulate` and `rths train lrx` accept it for the same plant.
    Emulated(String),
}

/// `rths link ... identify`: the device plays the excitation and streams its samples; the host's
/// `rths identify` estimation (`identify::estimate`) makes the rig file. Nothing is written unless
/// every sample arrived, the supervisor ended `Done` and every check passed.
fn identify(
    link: &mut Link,
    to: &To,
    out: PathBuf,
    figure: Option<PathBuf>,
    amplitude_mm: f64,
    lead_stride: usize,
    idle: Duration,
) -> anyhow::Result<()> {
    use crate::cmd::identify as host;
    use crate::machinery::identify::{
        estimate, excitation, runner::IdentificationRecord, Outcome, Signals,
    };
    let args = host::Args {
        preset: crate::cmd::plant::PresetArg::UnrCompact,
        seed: 1,
        uncertainty: false,
        specimen: crate::cmd::plant::SpecimenArg::Linear,
        specimen_stiffness_factor: 1.0,
        amplitude_mm,
        lead_stride,
        out,
        plot: figure,
    };
    let cfg = host::config(&args)?;
    // The same excitation the device plays (rths-core's, its tables computed alike): its design
    // (analysed window, lines) for the estimators and its figures for the rig file.
    let exc = excitation::generate(&cfg.excitation).context("excitation")?;
    let st = link.status()?;
    crate::outln!(
        "identifying through the board: {} s of excitation at {:.0} Hz, peak {:.2} mm",
        cfg.excitation.duration_s(),
        1.0 / cfg.excitation.dt_s,
        exc.peak_mm
    );
    let s = link.identify(amplitude_mm, idle)?;
    let (state, ticks, sent, dropped) = s.end;
    crate::outln!(
        "identification ended: {} after {ticks} ticks; device sent {sent} samples, its queue \
         dropped {dropped}; received {}",
        link_host::state_name(state),
        s.command_mm.len()
    );
    if !s.complete() {
        anyhow::bail!(
            "identification refused, nothing written: samples lost ({} gap(s), {} missing, {} \
             bad frame(s), {dropped} dropped by the device, {} of {ticks} received)",
            s.gaps.len(),
            s.missing,
            s.bad_frames,
            s.command_mm.len()
        );
    }
    if state != rths_link::RunState::Done {
        anyhow::bail!(
            "identification refused, nothing written: the device's supervisor ended in {} \
             (excitation stopped, actuator ramped to rest)",
            link_host::state_name(state)
        );
    }
    let daq_errors = s.measured_mm.iter().filter(|v| !v.is_finite()).count();
    let record = IdentificationRecord {
        dt_s: cfg.excitation.dt_s,
        command_mm: s.command_mm,
        measured_mm: s.measured_mm,
        force_kn: s.force_kn,
        daq_errors,
        actuator_errors: 0,
    };
    let sig = Signals {
        dt_s: record.dt_s,
        command_mm: &record.command_mm,
        measured_mm: &record.measured_mm,
        force_kn: &record.force_kn,
    };
    let identification = estimate::identify(sig, &cfg.design(&exc))
        .context("identification refused, nothing written")?;
    let o = Outcome {
        excitation: exc,
        record,
        identification,
    };
    let mut file = host::rig_file(&args, &cfg, &o);
    let how = match to {
        To::Serial(p) => {
            file.board = "link".into();
            format!("serial {p}")
        }
        To::Emulated(l) => format!("emulated board ({l}; plant unr-compact, linear, seed 1)"),
    };
    file.provenance.device = Some(format!(
        "rths link {how}: excitation played by the device's control task, {ticks} ticks \
         streamed; firmware model {} checksum {:08x}, limits ±{:?} mm, {:?} mm/s, ±{:?} kN",
        link_host::model_kind_name(st.model_kind),
        st.model_checksum,
        st.stroke_mm,
        st.velocity_mm_s,
        st.force_kn
    ));
    host::write_outputs(&args, &cfg, &o, file)?;
    Ok(())
}
