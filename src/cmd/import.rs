//! `rths import opensees`: a lab's openseespy model becomes a structure file (docs/opensees.md).

use std::io::IsTerminal as _;
use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use rths_files::structure_file::Units;

use crate::machinery::imported::export::{self, ImportRequest};
use crate::machinery::imported::DofLabel;

/// Arguments of `rths import`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// What to import from.
    #[command(subcommand)]
    pub source: ImportSource,
}

/// The programs `rths import` reads.
#[derive(Debug, clap::Subcommand)]
pub enum ImportSource {
    /// An openseespy model script (run with python3 and openseespy: `RTHS_PYTHON` overrides).
    Opensees(OpenseesArgs),
}

/// The model's units.
#[derive(Debug, Clone, Copy, clap::ValueEnum)]
pub enum UnitsArg {
    /// N, m, kg, s.
    Si,
    /// kN, mm, s (mass kN·s²/mm).
    MmKn,
}

/// Arguments of `rths import opensees`.
#[derive(Debug, clap::Args)]
pub struct OpenseesArgs {
    /// The openseespy script that builds the model (the whole test structure, specimen included).
    #[arg(value_name = "MODEL.py")]
    pub model: PathBuf,
    /// The DOF the specimen acts at, in that DOF's direction (OpenSees node tag : DOF, 1-based).
    #[arg(long, value_name = "NODE:DOF")]
    pub specimen: DofLabel,
    /// The specimen's stiffness, kN/mm: taken off the model at its DOF to leave the numerical
    /// substructure, and the numerical stand-in specimen of the pure loop.
    #[arg(long, value_name = "K_KN_MM")]
    pub specimen_stiffness: f64,
    /// A DOF whose displacement runs write (`out_<NODE>_<DOF>_mm`); repeat for more.
    #[arg(long = "output", value_name = "NODE:DOF")]
    pub outputs: Vec<DofLabel>,
    /// The model's units (default: the script's `RTHS_UNITS = "si" | "mm-kn"`).
    #[arg(long, value_enum)]
    pub units: Option<UnitsArg>,
    /// The structure file to write.
    #[arg(long, value_name = "S.json")]
    pub out: PathBuf,
}

/// A spinner on stderr while a step runs (hidden when stderr is not a terminal).
fn spinner() -> indicatif::ProgressBar {
    if !std::io::stderr().is_terminal() {
        return indicatif::ProgressBar::hidden();
    }
    let bar = indicatif::ProgressBar::new_spinner();
    if let Ok(style) = indicatif::ProgressStyle::with_template("{spinner} {msg} [{elapsed}]") {
        bar.set_style(style);
    }
    bar.enable_steady_tick(Duration::from_millis(100));
    bar
}

/// Run `rths import`.
pub fn run(args: Args) -> anyhow::Result<()> {
    match args.source {
        ImportSource::Opensees(a) => opensees(a),
    }
}

fn opensees(a: OpenseesArgs) -> anyhow::Result<()> {
    let start = Instant::now();
    let model = &a.model;
    if !model.is_file() {
        anyhow::bail!("{}: no such model script", model.display());
    }
    let req = ImportRequest {
        model: model.clone(),
        specimen: a.specimen,
        specimen_stiffness_kn_per_mm: a.specimen_stiffness,
        outputs: a.outputs.clone(),
        units: a.units.map(|u| match u {
            UnitsArg::Si => Units::Si,
            UnitsArg::MmKn => Units::MmKn,
        }),
    };
    let dir = tempfile::tempdir().context("creating a temporary directory for the export")?;
    let bar = spinner();
    bar.set_message(format!("building {} in OpenSees", model.display()));
    export::export(&req, dir.path())
        .with_context(|| format!("exporting the OpenSees model {}", model.display()))?;
    let exported_s = start.elapsed().as_secs_f64();
    bar.set_message("reading the Matrix Market files");
    let file = export::read_export(&req, dir.path())
        .with_context(|| format!("reading the export of {}", model.display()))?;
    bar.set_message("checking and condensing the model");
    let structure = file
        .validate()
        .with_context(|| format!("the OpenSees model {} is refused", model.display()))?;
    let json = file.to_json()?;
    std::fs::write(&a.out, json).with_context(|| format!("writing {}", a.out.display()))?;
    bar.finish_and_clear();
    crate::outln!(
        "model               {} ({} free DOFs, {} with mass: the condensed model's size)",
        model.display(),
        structure.equations().len(),
        structure.mass_dofs()
    );
    crate::outln!(
        "specimen            {} kN/mm at {} (condensed DOF {})",
        structure.specimen_stiffness_kn_per_mm(),
        structure.specimen(),
        structure.interface_index()
    );
    let outs: Vec<String> = structure.outputs().iter().map(|o| o.to_string()).collect();
    crate::outln!("outputs             {}", outs.join(", "));
    crate::outln!(
        "time                {:.2} s ({exported_s:.2} s in OpenSees)",
        start.elapsed().as_secs_f64()
    );
    crate::outln!("wrote {}", a.out.display());
    Ok(())
}
