//! The nonlinear (modal-hysteretic) metamodel: with every mode and the true laws it is the FE;
//! a small training run (seconds) beats the linear path on a held-out yielding record; the same
//! seed writes the same bytes; a model for another structure, a scoring record as training data
//! and bad model files are refused with the reason; the shipped models are for their structures.

use std::path::Path;

use rths::machinery::motion::GroundMotion;
use rths::machinery::structure::{drift_nrmse_pct, elastic_drifts, fe_reference};
use rths::machinery::train::nonlinear::runs::{fe_run, pure_loop};
use rths::machinery::train::nonlinear::{eval, modal, train, NlTrainConfig, SpringLaw};
use rths_core::metamodel::ModalHyst;
use rths_core::params::DT_S;
use rths_files::nl_model_file::{
    structure_checksum, ModeSpec, NlModelFile, NlModelFileError, NlStructureId, NlTraining,
    SpringSpec, NL_FORMAT, NL_KIND, NL_VERSION,
};
use rths_files::structure_file::{StoredStoryLaw, Structure, StructureFile};

fn root(p: &str) -> std::path::PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join(p)
}

fn text(p: &str) -> String {
    std::fs::read_to_string(root(p)).unwrap()
}

/// The model with every elastic mode and the structure's own laws (what training should find).
fn exact_model(path: &str) -> NlModelFile {
    let t = text(path);
    let s = Structure::from_json(&t).unwrap();
    let f = StructureFile::parse(&t).unwrap();
    let modes = modal::elastic_modes(&s, s.dofs()).unwrap();
    let laws = f.stories.unwrap().hysteresis.unwrap();
    let springs = laws
        .iter()
        .enumerate()
        .map(|(k, l)| {
            let k0 = modes.story_k0_kn_per_mm[k];
            let mut sp = SpringSpec {
                law: "bilinear".into(),
                k0_kn_per_mm: k0,
                yield_force_kn: 0.0,
                post_yield_ratio: 0.0,
                exponent: 0.0,
                beta: 0.0,
                gamma: 0.0,
                drift: modes.drift[k].clone(),
            };
            match l {
                StoredStoryLaw::Bilinear {
                    yield_force,
                    post_yield_ratio,
                } => {
                    sp.yield_force_kn = *yield_force;
                    sp.post_yield_ratio = *post_yield_ratio;
                }
                StoredStoryLaw::BoucWen {
                    yield_force,
                    post_yield_ratio,
                    exponent,
                    beta,
                    gamma,
                } => {
                    sp.law = "bouc-wen".into();
                    sp.yield_force_kn = *yield_force;
                    sp.post_yield_ratio = *post_yield_ratio;
                    sp.exponent = *exponent;
                    sp.beta = *beta;
                    sp.gamma = *gamma;
                }
            }
            sp
        })
        .collect();
    NlModelFile {
        format: NL_FORMAT.into(),
        version: NL_VERSION,
        kind: NL_KIND.into(),
        structure: NlStructureId {
            name: s.name().into(),
            checksum: structure_checksum(&t).unwrap(),
        },
        dt_s: DT_S,
        specimen_dof: 0,
        specimen_stiffness_kn_per_mm: s.specimen().1,
        modes: (0..s.dofs())
            .map(|j| ModeSpec {
                omega_rad_s: modes.omega_rad_s[j],
                damping_ratio: modes.damping_ratio[j],
                ground_participation: modes.ground_participation[j],
            })
            .collect(),
        shape: modes.shape.clone(),
        springs,
        training: NlTraining::default(),
    }
}

#[test]
fn with_every_mode_and_the_true_laws_the_model_is_the_fe() {
    for path in [
        "data/structures/shear3-yielding.json",
        "data/structures/paper-frame-yielding.json",
    ] {
        let s = Structure::load(&root(path)).unwrap();
        let m = exact_model(path);
        let run = fe_run(
            &s,
            &GroundMotion::try_embedded("northridge").unwrap(),
            1.0,
            DT_S,
        )
        .unwrap();
        let mut model = ModalHyst::new(m.params(DT_S).unwrap());
        let x = pure_loop(
            &mut model,
            m.specimen_stiffness_kn_per_mm,
            &run.ground_accel_mm_s2,
        )
        .unwrap();
        assert!(run.ductility > 1.5, "{path}: it yields ({})", run.ductility);
        for (xm, xr) in x.iter().zip(&run.floor_disp_mm) {
            let peak = xr.iter().fold(0.0_f64, |a, v| a.max(v.abs()));
            let worst = xm
                .iter()
                .zip(xr)
                .fold(0.0_f64, |a, (p, q)| a.max((p - q).abs()));
            assert!(worst < 1e-6 * peak, "{path}: {worst} mm of {peak} mm");
        }
    }
}

fn quick_config(seed: u64, generations: usize) -> NlTrainConfig {
    let mut cfg = NlTrainConfig::new(seed).unwrap();
    cfg.laws = vec![SpringLaw::Bilinear];
    cfg.ductilities = vec![0.7, 3.0, 6.0];
    cfg.record_s = Some(10.0);
    cfg.stage1_generations = 15;
    cfg.generations = generations;
    cfg
}

/// El Centro × 2 takes the paper's frame to ductility 3.6, where the elastic path misses by 17.8 %
/// (docs/nonlinear.md): a few seconds of training on other records must do far better.
#[test]
fn a_small_training_run_beats_the_linear_path_on_a_held_out_yielding_record() {
    let path = "data/structures/paper-frame-yielding.json";
    let t = train(&text(path), &quick_config(1, 12), |_, _, _| {}).unwrap();
    let tr = &t.file.training;
    eprintln!(
        "loss {:.3}% -> {:.3}%, {} generations",
        tr.initial_loss_pct, tr.final_loss_pct, tr.generations
    );
    // Seed 1 draws a poor start (a yield force far off): the search must have learned.
    assert!(tr.final_loss_pct < 0.5 * tr.initial_loss_pct);
    let s = Structure::load(&root(path)).unwrap();
    let el_centro = GroundMotion::try_el_centro().unwrap();
    let row = eval::evaluate(&t.file, &s, &el_centro, 2.0, DT_S).unwrap();
    let ag = el_centro.scaled(2.0).resample_mm_s2(DT_S);
    let fe = fe_reference(&s, &ag, DT_S).unwrap();
    let linear = drift_nrmse_pct(&elastic_drifts(&s, &fe, DT_S).unwrap(), &fe).unwrap()[0];
    eprintln!(
        "El Centro x2: trained {:.3}%, linear {linear:.3}%",
        row.nrmse_pct
    );
    assert!(row.ductility_ref > 3.0);
    assert!(
        row.nrmse_pct < 0.5 * linear,
        "trained {:.2}% vs linear {linear:.2}%",
        row.nrmse_pct
    );
}

/// With the lab's force noise on (the default), the loss is still a function of θ alone: the same
/// seed writes the same bytes; another seed, or the exact force, another model.
#[test]
fn the_same_seed_writes_the_same_bytes_with_the_force_noise_on() {
    let t = text("data/structures/paper-frame-yielding.json");
    let cfg = quick_config(5, 3);
    assert!(cfg.force_noise, "the lab's force is the default");
    let a = train(&t, &cfg, |_, _, _| {}).unwrap();
    let b = train(&t, &cfg, |_, _, _| {}).unwrap();
    assert_eq!(a.file.to_json().unwrap(), b.file.to_json().unwrap());
    let c = train(&t, &quick_config(6, 3), |_, _, _| {}).unwrap();
    assert_ne!(a.file.to_json().unwrap(), c.file.to_json().unwrap());
    let mut exact = quick_config(5, 3);
    exact.force_noise = false;
    let d = train(&t, &exact, |_, _, _| {}).unwrap();
    assert_ne!(
        a.file.training.final_loss_pct,
        d.file.training.final_loss_pct
    );
}

/// Stage 1 alone (one stage-2 generation) puts every spring of the 3-story frame near its
/// story's law: the pure loop on the training runs is already within a few per cent.
#[test]
fn stage_1_puts_the_springs_near_their_stories_laws() {
    let mut cfg = quick_config(3, 1);
    cfg.laws = vec![SpringLaw::BoucWen];
    cfg.stage1_generations = 150;
    let t = train(
        &text("data/structures/shear3-yielding.json"),
        &cfg,
        |_, _, _| {},
    )
    .unwrap();
    eprintln!(
        "loss {:.3}% -> stage 1 {:.3}% -> {:.3}%",
        t.file.training.initial_loss_pct, t.stage1_loss_pct, t.file.training.final_loss_pct
    );
    assert!(t.stage1_loss_pct < 0.5 * t.file.training.initial_loss_pct);
    assert!(t.stage1_loss_pct < 3.0, "{}", t.stage1_loss_pct);
}

#[test]
fn a_scoring_record_is_refused_as_training_data() {
    for name in ["el-centro", "kobe", "data/vrths_benchmark/morgan.csv"] {
        let mut cfg = quick_config(1, 1);
        cfg.records = vec![
            rths::cmd::analyze::load_motion(Some(&root(name).to_string_lossy()))
                .or_else(|_| rths::cmd::analyze::load_motion(Some(name)))
                .unwrap(),
        ];
        let e = train(
            &text("data/structures/paper-frame-yielding.json"),
            &cfg,
            |_, _, _| {},
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("scoring record"), "{name}: {e}");
    }
}

#[test]
fn a_model_for_another_structure_is_refused_with_the_reason() {
    let m = exact_model("data/structures/paper-frame-yielding.json");
    let own = text("data/structures/paper-frame-yielding.json");
    m.check_structure(&own).unwrap();
    let other = text("data/structures/shear3-yielding.json");
    let e = m.check_structure(&other).unwrap_err();
    assert!(matches!(e, NlModelFileError::WrongStructure { .. }));
    let msg = e.to_string();
    assert!(
        msg.contains("paper-frame-yielding") && msg.contains("shear3-yielding"),
        "{msg}"
    );
    // Same name, one number changed: refused; the description or the layout changed: accepted.
    let mut v: serde_json::Value = serde_json::from_str(&own).unwrap();
    v["stories"]["hysteresis"][0]["yield_force"] = serde_json::json!(1600.0);
    assert!(m
        .check_structure(&serde_json::to_string(&v).unwrap())
        .is_err());
    let mut v: serde_json::Value = serde_json::from_str(&own).unwrap();
    v["description"] = serde_json::json!("reworded");
    m.check_structure(&serde_json::to_string_pretty(&v).unwrap())
        .unwrap();
}

#[test]
fn bad_model_files_are_refused_with_the_reason() {
    let good = exact_model("data/structures/shear3-yielding.json")
        .to_json()
        .unwrap();
    NlModelFile::from_json(&good).unwrap();
    let bad = |edit: &dyn Fn(&mut serde_json::Value), want: &str| {
        let mut v: serde_json::Value = serde_json::from_str(&good).unwrap();
        edit(&mut v);
        let e = NlModelFile::from_json(&serde_json::to_string(&v).unwrap())
            .unwrap_err()
            .to_string();
        assert!(e.contains(want), "want {want:?} in {e:?}");
    };
    bad(&|v| v["format"] = "rths-model".into(), "format");
    bad(&|v| v["version"] = 2.into(), "version");
    bad(&|v| v["kind"] = "gru".into(), "kind");
    bad(&|v| v["springs"][0]["law"] = "elastic".into(), "spring law");
    bad(
        &|v| v["springs"][1]["yield_force_kn"] = (-1.0).into(),
        "yield force",
    );
    bad(
        &|v| v["springs"][0]["drift"] = serde_json::json!([1.0]),
        "one per mode",
    );
    bad(
        &|v| v["shape"][2] = serde_json::json!([1.0, 2.0]),
        "one per mode",
    );
    bad(
        &|v| v["modes"][0]["omega_rad_s"] = 0.0.into(),
        "modal frequency",
    );
    bad(
        &|v| v["modes"][1]["damping_ratio"] = 1.5.into(),
        "damping ratio",
    );
    bad(&|v| v["specimen_dof"] = 3.into(), "specimen DOF");
    bad(&|v| v["modes"] = serde_json::json!([]), "modes");
}

#[test]
fn the_shipped_models_are_for_their_structures() {
    for (model, structure) in [
        (
            "data/models/nl-paper-frame-yielding.json",
            "data/structures/paper-frame-yielding.json",
        ),
        (
            "data/models/nl-shear3-yielding.json",
            "data/structures/shear3-yielding.json",
        ),
        (
            "data/models/nl-shear8-yielding.json",
            "data/structures/shear8-yielding.json",
        ),
    ] {
        let m = NlModelFile::load_for(&root(model), &root(structure)).unwrap();
        assert!(m.training.runs.iter().all(|r| !r.starts_with("el-centro")
            && !r.starts_with("kobe")
            && !r.starts_with("morgan")));
        let other = if structure.contains("shear") {
            "data/structures/paper-frame-yielding.json"
        } else {
            "data/structures/shear3-yielding.json"
        };
        assert!(NlModelFile::load_for(&root(model), &root(other)).is_err());
    }
}
