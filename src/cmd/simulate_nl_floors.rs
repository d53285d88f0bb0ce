//! `rths simulate --structure S.json --scenario nl-pure|nl-online --model M.json` for a structure
//! whose yielding rths does not model: an imported one (a lab's nonlinear OpenSees model, exported
//! elastic) or an elastic story file (no `hysteresis` section), its model trained on the lab's
//! runs. The learned model (either form) runs in core's controller, alone with the numerical
//! stand-in specimen (`nl-pure`), or in the hybrid loop on the virtual rig with the rig's
//! identified lead and force correction (`nl-online`). Writes `DIR/history.csv` (`time_s`,
//! `interface_mm`, one `out_<NODE>_<DOF>_mm` per floor of the model). rths has no yielding FE of
//! these structures, so these runs have no reference here: they are scored against the lab's own
//! runs by `rths train nonlinear --evaluate --histories H... [--hybrid]`
//! (docs/opensees-nonlinear.md).

use std::ops::ControlFlow;
use std::path::Path;

use anyhow::Context;
use rths_core::compensator::Compensator;
use rths_core::control::{Analytical, ControlConfig, Controller, FeedbackSource};
use rths_core::params::{Prototype, SpecimenScale, DT_S};
use rths_core::supervisor::Limits;
use rths_files::hysteron_model_file::AnyNlModel;
use rths_hal_sim::{Preset, VirtualRig};

use crate::cmd::plant::PresetArg;
use crate::cmd::simulate_args::Args;
use crate::machinery::drive;
use crate::machinery::imported::fe::FeHistory;
use crate::machinery::train::nonlinear::floors::FloorModel;
use crate::machinery::train::nonlinear::score::Learned;
use crate::studies::nonlinear::held_out::{run_hybrid, HybridRig};
use crate::studies::nonlinear::scenario::SimScenario;

/// Run `nl-pure` or `nl-online` of the structure `text` (at `path`: imported, or an elastic story
/// file) under `ag`.
pub fn run(
    args: &Args,
    path: &Path,
    text: &str,
    ag_mm_s2: &[f64],
    motion_label: &str,
) -> anyhow::Result<()> {
    let sc = args.scenario;
    let Some(mp) = &args.model else {
        anyhow::bail!(
            "{sc} needs the structure's learned model: --model M.json from `rths train nonlinear \
             --structure {} --histories H... --out M.json`",
            path.display()
        );
    };
    let any = AnyNlModel::load(mp).with_context(|| format!("model {}", mp.display()))?;
    any.check_structure(text)
        .with_context(|| format!("model {} refused", mp.display()))?;
    rths_files::rate::check_dt(
        "the nonlinear model",
        any.dt_s(),
        DT_S,
        "rths train nonlinear --structure S.json --histories ... --out FILE",
    )
    .with_context(|| format!("model {}", mp.display()))?;
    // The structure's floors, once: the model's elastic floors must be them.
    let fm = FloorModel::from_json(text)?;
    if let AnyNlModel::Hysteron(h) = &any {
        fm.check_elastic(h)
            .with_context(|| format!("model {} refused", mp.display()))?;
    }
    let model = Learned::of(&any, DT_S).with_context(|| format!("model {}", mp.display()))?;
    let k_e = fm.specimen_k_kn_per_mm;
    let sf = fm.specimen_floor;
    let floors = fm.floors();
    let mut hist = FeHistory {
        dt_s: DT_S,
        output_columns: fm.columns.clone(),
        interface_mm: Vec::with_capacity(ag_mm_s2.len()),
        outputs_mm: Vec::with_capacity(ag_mm_s2.len()),
    };
    let read = |a: &Analytical, h: &mut FeHistory| {
        let floor: &dyn Fn(usize) -> f64 = match a {
            Analytical::StructureHysteron(m) => &|i| m.model().floor_disp_mm(i),
            Analytical::StructureModal(m) => &|i| m.model().floor_disp_mm(i),
            _ => return,
        };
        h.interface_mm.push(floor(sf));
        h.outputs_mm.push((0..floors).map(floor).collect());
    };
    let stopped = match sc {
        SimScenario::NlPure => {
            let config = ControlConfig::new(
                Prototype::paper(),
                SpecimenScale::new(1.0, 1.0)?,
                FeedbackSource::OwnLinearSpecimen {
                    stiffness_kn_per_mm: k_e,
                },
                Limits::unbounded(),
            )?;
            let mut ctl = Controller::new(config, model.analytical(), Compensator::None);
            drive::run::<VirtualRig>(&mut ctl, None, ag_mm_s2, None, DT_S, |st, ctl, _| {
                read(ctl.analytical(), &mut hist);
                if st.out.target_mm.is_finite() {
                    ControlFlow::Continue(())
                } else {
                    ControlFlow::Break(())
                }
            })
            .map(|(why, t)| format!("{why} at {t:.2} s"))
        }
        SimScenario::NlOnline => {
            let preset = match args.preset {
                PresetArg::Benchmark => Preset::Benchmark,
                PresetArg::UnrCompact => Preset::UnrCompact,
            };
            let rig = HybridRig::identified(&fm.name, preset, args.seed)?;
            let (online, stop, _) = run_hybrid(&model, k_e, ag_mm_s2, &rig)?;
            hist = FeHistory {
                output_columns: fm.columns.clone(),
                ..online
            };
            stop
        }
        _ => anyhow::bail!("{sc} is not a learned-model scenario"),
    };
    if let Some(dir) = &args.out {
        std::fs::create_dir_all(dir).with_context(|| format!("creating {}", dir.display()))?;
        let csv = dir.join("history.csv");
        hist.write_csv(&csv)
            .with_context(|| format!("writing {}", csv.display()))?;
    }
    let peak = |v: &[f64]| v.iter().fold(0.0_f64, |m, x| m.max(x.abs()));
    let size = match &model {
        Learned::Hysteron(p) => format!("{} hysterons", p.hysterons().len()),
        Learned::Modal(p) => format!("{} springs", p.springs()),
    };
    crate::outln!(
        "scenario            {sc} ({motion_label}, {} structure {}, {} model {}: {floors} floors, \
         {size})",
        if fm.stories { "story" } else { "imported" },
        fm.name,
        model.form(),
        mp.display(),
    );
    match &stopped {
        Some(why) => crate::outln!("stable              no: stopped ({why})"),
        None => crate::outln!("stable              yes"),
    }
    crate::outln!("peak interface      {:.4} mm", peak(&hist.interface_mm));
    if let Some(dir) = &args.out {
        crate::outln!("wrote {}", dir.join("history.csv").display());
    }
    Ok(())
}
