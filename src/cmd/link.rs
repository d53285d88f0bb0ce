//! `rths link`: drive and record a test on a board over the command link (a serial port, a TCP socket
//! to QEMU's serial port, or a QEMU started here).

use std::io::Write as _;
use std::path::PathBuf;
use std::time::Duration;

use anyhow::Context;
use clap::{Args as ClapArgs, Subcommand};

use crate::link_host::{self, Link, Qemu, RecordSummary};
use crate::model_file::ModelFile;

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
    /// Print the device's state, model checksum, limits and counters.
    Status,
    /// Upload an LR model file (validated on the device; refused whole, old model kept).
    Upload {
        /// The model file (`rths train lr` / `rths reproduce`'s lr.json).
        #[arg(long)]
        model: PathBuf,
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
    /// The whole test: [upload], arm, start, record to CSV until the run ends.
    Run {
        /// Upload this model first.
        #[arg(long)]
        model: Option<PathBuf>,
        /// Telemetry decimation.
        #[arg(long, default_value_t = 1)]
        telemetry_every: u16,
        /// CSV output.
        #[arg(long)]
        out: PathBuf,
        /// Give up after this long without a message, s.
        #[arg(long, default_value_t = 30.0)]
        idle_timeout_s: f64,
    },
}

/// Record to `out`; fails (after writing the file) if anything was lost.
pub fn record_csv(
    link: &mut Link,
    out: &std::path::Path,
    idle: Duration,
) -> anyhow::Result<RecordSummary> {
    let f =
        std::fs::File::create(out).with_context(|| format!("cannot create {}", out.display()))?;
    let mut w = std::io::BufWriter::new(f);
    writeln!(w, "{}", link_host::CSV_HEADER)?;
    let s = link.record(idle, 0, |t| writeln!(w, "{}", link_host::csv_row(t)))?;
    w.flush()?;
    Ok(s)
}

fn report(s: &RecordSummary, out: &std::path::Path) -> anyhow::Result<()> {
    println!("wrote {} ({} records)", out.display(), s.records);
    if let Some((state, ticks, sent, dropped)) = s.end {
        println!(
            "run ended: {} after {ticks} ticks; device sent {sent} records, its queue dropped {dropped}",
            link_host::state_name(state)
        );
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
    Ok(())
}

/// Run `rths link`.
pub fn run(a: Args) -> anyhow::Result<()> {
    let timeout = Duration::from_secs_f64(a.timeout_s.max(0.01));
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
        LinkCommand::Status => {
            let s = link.status()?;
            println!("state            {}", link_host::state_name(s.state));
            println!("model checksum   {:08x}", s.model_checksum);
            println!("tick             {}", s.tick);
            println!(
                "records sent     {} (dropped by the device: {})",
                s.records_sent, s.records_dropped
            );
            println!(
                "limits           ±{} mm, {} mm/s, ±{} kN",
                s.stroke_mm, s.velocity_mm_s, s.force_kn
            );
            println!("bad frames       {}", s.bad_frames);
        }
        LinkCommand::Upload { model } => {
            let m = ModelFile::load(&model)?;
            let c = link.upload(&m)?;
            println!("uploaded {} (checksum {c:08x})", model.display());
        }
        LinkCommand::Limits {
            stroke_mm,
            velocity_mm_s,
            force_kn,
        } => {
            link.set_limits(stroke_mm, velocity_mm_s, force_kn)?;
            println!("limits set");
        }
        LinkCommand::Arm { telemetry_every } => {
            link.arm(telemetry_every)?;
            println!("armed");
        }
        LinkCommand::Start => {
            link.start()?;
            println!("started");
        }
        LinkCommand::Abort => {
            link.abort()?;
            println!("aborting: ramp to zero");
        }
        LinkCommand::Record {
            out,
            idle_timeout_s,
        } => {
            let s = record_csv(&mut link, &out, Duration::from_secs_f64(idle_timeout_s))?;
            report(&s, &out)?;
        }
        LinkCommand::Run {
            model,
            telemetry_every,
            out,
            idle_timeout_s,
        } => {
            if let Some(p) = model {
                let m = ModelFile::load(&p)?;
                let c = link.upload(&m)?;
                println!("uploaded {} (checksum {c:08x})", p.display());
            }
            link.arm(telemetry_every)?;
            link.start()?;
            println!("running");
            let s = record_csv(&mut link, &out, Duration::from_secs_f64(idle_timeout_s))?;
            report(&s, &out)?;
        }
    }
    if let Some(q) = qemu {
        let out = q.stdout();
        if let Some(line) = out.lines().rev().find(|l| l.starts_with("RESULT ")) {
            println!("{line}");
        }
        drop(q);
        let _ = std::fs::remove_dir_all(&dir);
    }
    Ok(())
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
