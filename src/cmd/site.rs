//! `rths site`: be the experimental site of an OpenSees analysis (its `genericClient` elements),
//! on the virtual rig or the board (docs/site.md).

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::Context;
use rths_core::compensator::LeadParams;
use rths_hal_sim::{FaultPlan, Specimen};

use crate::cmd::plant::PresetArg;
use crate::link_host::{Link, Qemu};
use crate::machinery::identify::rig_file::VIRTUAL_BOARD;
use crate::machinery::identify::{identify_virtual, IdentifyConfig, RigFile};
use crate::machinery::site::board::{BoardExperiment, BoardLink};
use crate::machinery::site::element::{median_max, ElementSetup};
use crate::machinery::site::virtual_rig::VirtualExperiment;
use crate::machinery::site::{self, SiteConfig, SiteElement};

/// Arguments of `rths site`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Address of the first element's server (element i: port + i). Binds 127.0.0.1 unless
    /// another address is given.
    #[arg(long, default_value = "127.0.0.1:8090", value_name = "ADDR:PORT")]
    pub listen: SocketAddr,
    /// UDP instead of TCP (`genericClient ... -udp`).
    #[arg(long)]
    pub udp: bool,
    /// Number of experimental elements (each its own connection and actuator).
    #[arg(long, default_value_t = 1, value_name = "K")]
    pub elements: usize,
    /// Plant preset of the virtual rig (identified at start).
    #[arg(long, value_enum, conflicts_with = "rig")]
    pub preset: Option<PresetArg>,
    /// Rig file (`rths identify`, or `rths link ... identify` for the board): its identified lead
    /// and specimen stiffness. Several elements: once for all of them, or once per element
    /// (element i: the i-th, each its own rig or board).
    #[arg(long, value_name = "RIG.json")]
    pub rig: Vec<PathBuf>,
    /// The boards through the command link, one per element (`--qemu ELF`, or `--port TTY` once
    /// per element; the rig files are `--rig`, by default `rig.json`).
    #[arg(long, conflicts_with = "preset")]
    pub link: bool,
    /// With --link: the emulated board's ELF (a `--features link` build); each element gets its
    /// own emulated board (one QEMU each).
    #[arg(long, value_name = "ELF", requires = "link", conflicts_with = "port")]
    pub qemu: Option<PathBuf>,
    /// With --link: a board's serial port, once per element (element i: the i-th).
    #[arg(long, value_name = "TTY", requires = "link")]
    pub port: Vec<PathBuf>,
    /// With --port: the serial ports' baud rate.
    #[arg(long, default_value_t = 2_000_000, requires = "port")]
    pub baud: u32,
    /// Hold the virtual rig's ticks to the wall clock (2048 per second), as a lab's rig runs: the
    /// rig never waits for its client, the predictor runs while the client computes. Without it
    /// the virtual rig runs in simulated time, as fast as the host computes. (A real board always
    /// keeps its own time; the emulated one waits for its targets.)
    #[arg(long, conflicts_with = "link")]
    pub real_time: bool,
    /// Rig time over analysis time (≥ 1): each integration step imposed over F times its
    /// duration (a slowed-down test). F × Δt_analysis must be a whole number of controller ticks.
    #[arg(long, default_value_t = 1.0, value_name = "F")]
    pub rate_factor: f64,
    /// Recording (`rths link run --out`'s CSV, read by `rths report`); several elements:
    /// `RUN-1.csv`, `RUN-2.csv`, ...
    #[arg(long, value_name = "RUN.csv")]
    pub out: Option<PathBuf>,
    /// Sensor-noise seed of the virtual rig (element i: seed + i).
    #[arg(long, default_value_t = 1)]
    pub seed: u64,
}

/// The rig file a board site uses when `--rig` is not given.
const DEFAULT_BOARD_RIG: &str = "rig.json";

/// Element `i`'s rig file of `--rig` given once (every element's) or once per element; `None`
/// when not given.
fn rig_of(args: &Args, i: usize) -> anyhow::Result<Option<&PathBuf>> {
    match args.rig.len() {
        0 => Ok(None),
        1 => Ok(args.rig.first()),
        n if n == args.elements => Ok(args.rig.get(i)),
        n => anyhow::bail!(
            "--rig given {n}× for {} elements: once for all of them, or once per element",
            args.elements
        ),
    }
}

/// Each element's board: its link and its rig file's compensation.
fn board_elements(args: &Args) -> anyhow::Result<Vec<SiteElement>> {
    if args.qemu.is_none() && args.port.is_empty() {
        anyhow::bail!("--link needs the boards: --qemu ELF, or --port TTY once per element");
    }
    if !args.port.is_empty() && args.port.len() != args.elements {
        anyhow::bail!(
            "--port given {}× for {} elements: each element drives its own actuator, on its \
             own board (--port TTY once per element)",
            args.port.len(),
            args.elements
        );
    }
    for (i, p) in args.port.iter().enumerate() {
        if args.port.get(..i).is_some_and(|before| before.contains(p)) {
            anyhow::bail!(
                "--port {} given twice: each element drives its own board",
                p.display()
            );
        }
    }
    (0..args.elements).map(|i| board_element(args, i)).collect()
}

/// Element `i`'s board: its link and its rig file's compensation.
fn board_element(args: &Args, i: usize) -> anyhow::Result<SiteElement> {
    let path = rig_of(args, i)?
        .cloned()
        .unwrap_or_else(|| PathBuf::from(DEFAULT_BOARD_RIG));
    let file = RigFile::load(&path).with_context(|| {
        format!(
            "rig file {} (the board's identification: `rths link ... identify --out {}`, or \
             --rig RIG.json)",
            path.display(),
            path.display()
        )
    })?;
    if file.specimen != "linear" {
        anyhow::bail!(
            "rig file {}: the {} specimen (the site returns the force corrected with a linear \
             specimen's stiffness)",
            path.display(),
            file.specimen
        );
    }
    let lead = file
        .lead_params()
        .with_context(|| format!("rig file {}: its lead", path.display()))?;
    let k = file.specimen_fit.stiffness_kn_per_mm;
    let mut header = Vec::new();
    let conn = match (&args.qemu, args.port.get(i)) {
        (Some(elf), None) => {
            let dir = std::env::temp_dir().join(format!(
                "rths-site-qemu-{}-{}",
                std::process::id(),
                i + 1
            ));
            std::fs::create_dir_all(&dir)?;
            header.push(("link".into(), "qemu".into()));
            BoardLink::Qemu(Box::new(Qemu::start(elf, &dir).with_context(|| {
                format!("element {}'s board {}", i + 1, elf.display())
            })?))
        }
        (None, Some(port)) => {
            let p = port.display().to_string();
            let mut l = Link::serial(&p, args.baud)?;
            l.wait_ready(std::time::Duration::from_secs(10))
                .with_context(|| format!("element {}'s board on {p}", i + 1))?;
            header.push(("link".into(), format!("serial {p}")));
            BoardLink::Port(Box::new(l))
        }
        _ => anyhow::bail!("--link needs the boards: --qemu ELF, or --port TTY once per element"),
    };
    header.push(("rig".into(), path.display().to_string()));
    header.push(("preset".into(), file.preset.clone()));
    Ok(SiteElement {
        setup: ElementSetup {
            specimen_k_kn_per_mm: k,
            rate_factor: args.rate_factor,
        },
        experiment: Box::new(BoardExperiment::new(conn, lead)),
        header,
    })
}

/// Element `i`'s virtual rig: its rig file's (`--rig`), or the preset's identified at start.
fn virtual_element(args: &Args, i: usize) -> anyhow::Result<SiteElement> {
    let seed = args.seed + i as u64;
    let (rig, lead, k, source) = match rig_of(args, i)? {
        Some(path) => {
            let file =
                RigFile::load(path).with_context(|| format!("rig file {}", path.display()))?;
            let preset = match file.preset.as_str() {
                "benchmark" => rths_hal_sim::Preset::Benchmark,
                "unr-compact" => rths_hal_sim::Preset::UnrCompact,
                other => anyhow::bail!("rig file {}: unknown preset `{other}`", path.display()),
            };
            file.check(preset.name(), VIRTUAL_BOARD)
                .with_context(|| format!("rig file {} refused", path.display()))?;
            if file.specimen != "linear" {
                anyhow::bail!(
                    "rig file {}: the {} specimen (rths site's virtual rig has the linear one)",
                    path.display(),
                    file.specimen
                );
            }
            let mut rig = crate::machinery::reference::rig_config(
                preset,
                Specimen::Linear,
                file.specimen_stiffness_factor,
                file.seed,
            );
            rig.uncertainty = file.uncertainty;
            (
                rig,
                file.lead_params()?,
                file.specimen_fit.stiffness_kn_per_mm,
                path.display().to_string(),
            )
        }
        None => {
            let preset = match args.preset.unwrap_or(PresetArg::UnrCompact) {
                PresetArg::Benchmark => rths_hal_sim::Preset::Benchmark,
                PresetArg::UnrCompact => rths_hal_sim::Preset::UnrCompact,
            };
            let rig = crate::machinery::reference::rig_config(preset, Specimen::Linear, 1.0, seed);
            eprintln!(
                "site: element {}: identifying the {} rig",
                i + 1,
                preset.name()
            );
            let o = identify_virtual(&rig, FaultPlan::none(), &IdentifyConfig::default())
                .with_context(|| format!("identifying element {}'s rig", i + 1))?;
            let id = &o.identification;
            let lead = LeadParams::new(id.lead_weights, id.lead_stride)
                .map_err(|e| anyhow::anyhow!("the identified lead: {e:?}"))?;
            eprintln!(
                "site: element {}: delay {:.2} ms, specimen k {:.4} kN/mm",
                i + 1,
                id.delay_s * 1e3,
                id.specimen.stiffness_kn_per_mm
            );
            (
                rig,
                lead,
                id.specimen.stiffness_kn_per_mm,
                "identified".to_string(),
            )
        }
    };
    Ok(SiteElement {
        setup: ElementSetup {
            specimen_k_kn_per_mm: k,
            rate_factor: args.rate_factor,
        },
        header: vec![
            ("preset".into(), rig.preset.name().into()),
            ("rig".into(), source),
        ],
        experiment: Box::new(VirtualExperiment::new(&rig, lead, args.real_time)?),
    })
}

/// Run `rths site`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if !args.link && (args.qemu.is_some() || !args.port.is_empty()) {
        anyhow::bail!("--qemu and --port are the board's: add --link");
    }
    if !(args.rate_factor.is_finite() && args.rate_factor >= 1.0) {
        anyhow::bail!("--rate-factor {} must be ≥ 1", args.rate_factor);
    }
    if args.elements == 0 || args.elements > 64 {
        anyhow::bail!("--elements {} must be in 1..=64", args.elements);
    }
    let header = vec![
        ("rate_factor".to_string(), args.rate_factor.to_string()),
        (
            "pacing".to_string(),
            if args.link {
                "board"
            } else if args.real_time {
                "wall-clock"
            } else {
                "simulated"
            }
            .to_string(),
        ),
    ];
    let elements = if args.link {
        board_elements(&args)?
    } else {
        (0..args.elements)
            .map(|i| virtual_element(&args, i))
            .collect::<anyhow::Result<Vec<_>>>()?
    };
    let cfg = SiteConfig {
        listen: args.listen,
        udp: args.udp,
        elements,
        out: args.out,
        header,
    };
    let outcomes = site::run(cfg)?;
    let mut failed = false;
    for (i, o) in outcomes.iter().enumerate() {
        let (med, max) = median_max(&o.step_latency_s);
        crate::outln!(
            "element {}: {} steps of {} ticks, latency per step median {:.3} ms max {:.3} ms, \
             supervisor {}{}",
            i + 1,
            o.steps,
            o.ticks_per_step,
            med * 1e3,
            max * 1e3,
            crate::link_host::state_name(o.state),
            o.stop_reason
                .as_ref()
                .map(|r| format!(", stopped: {r}"))
                .unwrap_or_default()
        );
        if let Some(p) = &o.pacing {
            crate::outln!(
                "element {}: wall clock: {} ticks at {:.2} Hz (goal 2048), each tick's start \
                 after its deadline RMS {:.1} µs, max {:.1} µs",
                i + 1,
                p.ticks,
                p.rate_hz,
                p.jitter_rms_s * 1e6,
                p.late_max_s * 1e6
            );
        }
        failed |= o.stop_reason.is_some();
    }
    if failed {
        return Err(crate::cmd::RunStopped(
            "a test was stopped (see above); the recording is kept".into(),
        )
        .into());
    }
    Ok(())
}
