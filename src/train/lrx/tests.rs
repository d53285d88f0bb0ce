use super::*;
use crate::scenario::{self, ScenarioId, ScenarioSetup};
use crate::study;

#[test]
#[ignore]
fn experiment() {
    let mut cfg = LrxConfig::new().unwrap();
    if let Ok(v) = std::env::var("STRIDE") {
        cfg.lead_stride = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("KT") {
        cfg.k_adapt_ticks = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("RCOND") {
        cfg.rcond = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("LF") {
        cfg.lead_factors = v.split(',').map(|x| x.parse().unwrap()).collect();
    }
    let t0 = std::time::Instant::now();
    let tr = train(&cfg).unwrap();
    eprintln!(
        "train {:?} frame fit {:.3e}% cond {:.3e} lead fit {:.3}% cond {:.3e} pure {:?}",
        t0.elapsed(),
        tr.frame_fit_nrmse_pct,
        tr.frame_condition,
        tr.lead_fit_nrmse_pct,
        tr.lead_condition,
        tr.pure_nrmse_pct
    );
    eprintln!(
        "coeffs {:?}\nlead {:?} sum {}",
        tr.coeffs,
        tr.lead_weights,
        tr.lead_weights.iter().sum::<f64>()
    );
    let (fp, mut lp) = crate::models::lrx_params(&tr.file).unwrap();
    if std::env::var("NOLEAD").is_ok() {
        lp = rths_core::compensator::LeadParams::new([1.0, 0., 0., 0., 0., 0., 0., 0.], 1).unwrap();
    }
    let scale: f64 = std::env::var("SCALE")
        .map(|v| v.parse().unwrap())
        .unwrap_or(1.0);
    let ag = GroundMotion::embedded(&std::env::var("REC").unwrap_or("el-centro".into()))
        .unwrap()
        .scaled(scale)
        .resample_mm_s2(DT_S);
    for (spec, f) in [
        (Specimen::Linear, 0.6),
        (Specimen::Linear, 0.8),
        (Specimen::Linear, 1.0),
        (Specimen::Linear, 1.2),
        (Specimen::Linear, 1.4),
        (Specimen::BoucWen(Default::default()), 1.0),
    ] {
        let reference = study::reference_for(&ag, spec, f).unwrap();
        for id in [ScenarioId::LrxOnline] {
            let run = scenario::run(&ScenarioSetup {
                id,
                ground_accel_mm_s2: &ag,
                reference_mm: &reference,
                rig: scenario::rig_config(Preset::UnrCompact, spec, f, 1),
                stiffness_factor: f,
                lr: None,
                rnn: None,
                delay_steps: 28,
                lrx: Some((fp, lp)),
            })
            .unwrap();
            let r = run.report;
            eprintln!(
                "{} {} F={f}: stop {:?} stable {} nrmse {:?} meas {:?} j2t {:?} j1t {:?}",
                id,
                spec.name(),
                r.stop_reason,
                r.stable,
                r.nrmse_pct,
                r.nrmse_measured_pct,
                r.j2_target_pct,
                r.j1_target_ms
            );
        }
    }
}

#[test]
#[ignore]
fn scales() {
    for name in GroundMotion::embedded_names() {
        let ag = GroundMotion::embedded(name).unwrap().resample_mm_s2(DT_S);
        for (spec, f) in crate::sweep::cases() {
            let r = study::reference_for(&ag, spec, f).unwrap();
            let v = r
                .windows(2)
                .map(|w| ((w[1] - w[0]) / DT_S).abs())
                .fold(0.0, f64::max);
            eprintln!(
                "{name} {} {f}: peak {:.2} mm, {:.1} mm/s",
                spec.name(),
                rths_core::metrics::peak_abs(&r),
                v
            );
        }
    }
}
