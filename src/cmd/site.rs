//! `rths site`: be the experimental site of an OpenSees analysis (its `genericClient` elements),
//! on the virtual rig (docs/site.md).

use std::net::SocketAddr;
use std::path::PathBuf;

use anyhow::Context;
use rths_core::compensator::LeadParams;
use rths_hal_sim::{FaultPlan, Specimen};

use crate::cmd::plant::PresetArg;
use crate::identify::{identify_virtual, IdentifyConfig, RigFile};
use crate::site::element::{median_max, ElementSetup};
use crate::site::{self, SiteConfig};

/// The board of a virtual-rig site.
const BOARD: &str = "virtual";

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
    /// Rig file (`rths identify`) of the virtual rig: its identified lead and specimen stiffness.
    #[arg(long, value_name = "RIG.json")]
    pub rig: Option<PathBuf>,
    /// The board through the command link (not yet supported by `rths site`).
    #[arg(long, conflicts_with_all = ["preset", "rig"])]
    pub link: bool,
    /// With --link: the emulated board's ELF.
    #[arg(long, value_name = "ELF", requires = "link")]
    pub qemu: Option<PathBuf>,
    /// With --link: the board's serial port.
    #[arg(long, value_name = "TTY", requires = "link")]
    pub port: Option<PathBuf>,
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

/// Run `rths site`.
pub fn run(args: Args) -> anyhow::Result<()> {
    if args.link || args.qemu.is_some() || args.port.is_some() {
        anyhow::bail!(
            "rths site --link (--qemu ELF | --port TTY): the board's site mode is not yet \
             supported; use the virtual rig (--preset P or --rig RIG.json)"
        );
    }
    if !(args.rate_factor.is_finite() && args.rate_factor >= 1.0) {
        anyhow::bail!("--rate-factor {} must be ≥ 1", args.rate_factor);
    }
    if args.elements == 0 || args.elements > 64 {
        anyhow::bail!("--elements {} must be in 1..=64", args.elements);
    }
    let mut header = vec![("rate_factor".to_string(), args.rate_factor.to_string())];
    let mut elements = Vec::with_capacity(args.elements);
    for i in 0..args.elements {
        let seed = args.seed + i as u64;
        let (rig, lead, k, source) = match &args.rig {
            Some(path) => {
                let file =
                    RigFile::load(path).with_context(|| format!("rig file {}", path.display()))?;
                let preset = match file.preset.as_str() {
                    "benchmark" => rths_hal_sim::Preset::Benchmark,
                    "unr-compact" => rths_hal_sim::Preset::UnrCompact,
                    other => anyhow::bail!("rig file {}: unknown preset `{other}`", path.display()),
                };
                file.check(preset.name(), BOARD)
                    .with_context(|| format!("rig file {} refused", path.display()))?;
                if file.specimen != "linear" {
                    anyhow::bail!(
                        "rig file {}: the {} specimen (rths site's virtual rig has the linear one)",
                        path.display(),
                        file.specimen
                    );
                }
                let mut rig = crate::scenario::rig_config(
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
                let rig = crate::scenario::rig_config(preset, Specimen::Linear, 1.0, seed);
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
        if i == 0 {
            header.push(("preset".into(), rig.preset.name().into()));
            header.push(("rig".into(), source));
        }
        elements.push(ElementSetup {
            rig,
            lead,
            specimen_k_kn_per_mm: k,
            rate_factor: args.rate_factor,
        });
    }
    let cfg = SiteConfig {
        listen: args.listen,
        udp: args.udp,
        elements,
        out: args.out,
        header,
    };
    let outcomes = site::run(&cfg)?;
    let mut failed = false;
    for (i, o) in outcomes.iter().enumerate() {
        let (med, max) = median_max(&o.step_latency_s);
        println!(
            "element {}: {} steps of {} ticks, latency per step median {:.3} ms max {:.3} ms, \
             supervisor {:?}{}",
            i + 1,
            o.steps,
            o.ticks_per_step,
            med * 1e3,
            max * 1e3,
            o.state,
            o.stop_reason
                .as_ref()
                .map(|r| format!(", stopped: {r}"))
                .unwrap_or_default()
        );
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
