use super::*;
use rths_core::integrator::{Chang, ExplicitIntegrator};
use rths_core::structure::{LinearStructure, Vector};

fn trained() -> LrxTraining {
    train(&LrxConfig::new().unwrap()).unwrap()
}

/// The frame model run on its own brace force (no actuator), vs the pure FE response, %.
fn pure_at(params: LrxParams, ag: &[f64], factor: f64) -> f64 {
    let proto = crate::machinery::reference::specimen_prototype(factor).unwrap();
    let reference = super::super::data::pure_response(&proto, ag, DT_S)
        .unwrap()
        .brace_disp_mm;
    let lrx = Analytical::Lrx(Lrx::new(params));
    super::super::pure::nrmse("lrx-pure", lrx, proto, 0, ag, &reference).unwrap()
}

/// The identified ARX is the frame: fed the brace force of any specimen stiffness it reproduces the
/// pure FE response of the structure with that specimen, on a record it was not trained on.
#[test]
fn frame_model_follows_any_specimen_on_an_unseen_record() {
    let t = trained();
    println!("coefficients {:?}", t.coeffs);
    println!(
        "frame fit {:.2e}% (cond {:.2e}); lead fit {:.3}% (cond {:.2e}) {:?}",
        t.frame_fit_nrmse_pct,
        t.frame_condition,
        t.lead_fit_nrmse_pct,
        t.lead_condition,
        t.lead_weights
    );
    let (p, _) = crate::machinery::models::lrx_params(&t.file).unwrap();
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    for f in [0.6, 0.8, 1.0, 1.2, 1.4] {
        let e = pure_at(p, &ag, f);
        println!("lrx-pure el-centro F = {f}: {e:.2e}%");
        assert!(e < 5e-3, "F = {f}: {e}%");
    }
    for (m, e) in &t.pure_nrmse_pct {
        assert!(*e < 5e-3, "{m}: {e}%");
    }
}

/// Without force perturbations and with one specimen, F = k·d: the force columns are collinear with
/// the displacement columns and the fit cannot tell their effects apart (the paper LR's problem).
#[test]
fn force_perturbations_make_the_force_identifiable() {
    let mut cfg = LrxConfig::new().unwrap();
    let with = train(&cfg).unwrap().frame_condition;
    cfg.perturbation = 0.0;
    cfg.frame_factors = vec![1.0];
    let without = train(&cfg).unwrap().frame_condition;
    println!("condition number: with perturbations {with:.3e}, without {without:.3e}");
    assert!(without > 1e3 * with, "{without:e} vs {with:e}");
}

/// The lead filter is a plant inverse: DC gain ≈ 1/plant gain (1.0261 nominal, CSI included), and
/// it fits the commands well.
#[test]
fn lead_filter_inverts_the_plant() {
    let t = trained();
    let dc: f64 = t.lead_weights.iter().sum();
    println!("lead DC gain {dc:.4}, fit {:.3}%", t.lead_fit_nrmse_pct);
    assert!((0.9..1.05).contains(&dc), "{dc}");
    assert!(t.lead_fit_nrmse_pct < 1.0, "{}", t.lead_fit_nrmse_pct);
}

/// The hybrid split (frame by Chang with its initial stiffness, brace force fed in) equals the pure FE
/// response of [`crate::machinery::reference::specimen_prototype`] (frame damping coefficient unchanged), not the
/// one that keeps the damping *ratio* at 2% for every specimen (1% to 3% away at F = 0.6..1.4).
#[test]
fn the_hybrid_split_keeps_the_frame_damping_coefficient() {
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    for f in [0.6, 1.4] {
        let (d, _) = frame_run(&ag, f, &[]).unwrap();
        let same_c = crate::machinery::reference::specimen_prototype(f).unwrap();
        let same_zeta = Prototype::paper().with_brace_factor(f).unwrap();
        let r_c = super::super::data::pure_response(&same_c, &ag, DT_S)
            .unwrap()
            .brace_disp_mm;
        let r_z = super::super::data::pure_response(&same_zeta, &ag, DT_S)
            .unwrap()
            .brace_disp_mm;
        let (e_c, e_z) = (
            metrics::nrmse_pct(&d, &r_c).unwrap(),
            metrics::nrmse_pct(&d, &r_z).unwrap(),
        );
        println!("F = {f}: hybrid split vs same c {e_c:.4}%, vs same ζ {e_z:.3}%");
        assert!(e_c < 0.01 && e_z > 1.0, "{e_c} {e_z}");
    }
}

#[test]
fn model_file_round_trip_and_validation() {
    let t = trained();
    let json = t.file.to_json().unwrap();
    let back = ModelFile::from_json(&json).unwrap();
    assert_eq!(back, t.file);
    let (p, lead) = crate::machinery::models::lrx_params(&back).unwrap();
    assert_eq!(p.coeffs(), &t.coeffs);
    assert_eq!(lead.weights(), &t.lead_weights);
    let mut bad = back.clone();
    if let Some(w) = bad.lrx.as_mut() {
        w.coeffs.pop();
    }
    assert!(matches!(
        bad.validate(),
        Err(crate::machinery::model_file::ModelFileError::WrongShape { .. })
    ));
    let mut bad = back.clone();
    if let Some(w) = bad.lrx.as_mut() {
        w.lead_stride = 9;
    }
    assert!(bad.validate().is_err());
    let mut bad = back;
    bad.features.swap(0, 1);
    assert!(matches!(
        bad.validate(),
        Err(crate::machinery::model_file::ModelFileError::FeatureMismatch { .. })
    ));
    assert!(crate::machinery::models::lr_params(&t.file).is_err());
}

/// An N-story shear building (every floor 1.75 kN·s²/mm, every story frame 176.75 kN/mm, the paper's
/// brace in story 1, Rayleigh 2%): hybrid split (frame analytical, brace force fed in at floor 1).
fn mdof<const N: usize>() -> (LinearStructure<N>, LinearStructure<N>) {
    use rths_core::structure::ShearBuilding;
    let p = Prototype::paper();
    let mut b =
        ShearBuilding::<N>::uniform(p.mass_kn_s2_per_mm(), p.frame_stiffness_kn_per_mm(), 0.02);
    b.story_stiffness_kn_per_mm[0] += p.brace_lateral_stiffness_kn_per_mm();
    let pure = b.model().unwrap();
    let mut k_frame = *pure.stiffness();
    k_frame[(0, 0)] -= p.brace_lateral_stiffness_kn_per_mm();
    let hybrid =
        LinearStructure::new(*pure.mass(), *pure.damping(), k_frame, *pure.stiffness()).unwrap();
    (pure, hybrid)
}

/// Brace deformation of the N-story hybrid split driven by a brace force `factor·k_b·d + p`.
fn mdof_run<const N: usize>(
    h: LinearStructure<N>,
    ag: &[f64],
    factor: f64,
    p: &[f64],
) -> (Vec<f64>, Vec<f64>) {
    let proto = Prototype::paper();
    let k = factor * proto.brace_axial_stiffness_kn_per_mm();
    let mut ch = Chang::new(h, DT_S).unwrap();
    let (mut d, mut f) = (vec![0.0], vec![0.0]);
    ch.reset(ag[0]);
    for (i, &g) in ag.iter().enumerate().skip(1) {
        let di = proto.brace_disp_mm(ch.next_displacement()[0]);
        let fi = k * di + p.get(i).copied().unwrap_or(0.0);
        let mut r = Vector::<N>::zeros();
        r[0] = proto.story_force_kn(fi);
        ch.advance(g, &r);
        d.push(di);
        f.push(fi);
    }
    (d, f)
}

/// How far the fixed-order (3) LRX gets on an N-story frame: it is exact for N = 1 and becomes a
/// reduced-order model for N > 1 (its cost stays 9 multiply-adds, the FE's grows as N²). Trained on
/// the default motions, `lrx-pure` on El Centro (not trained on) vs the pure FE of the building.
fn mdof_lrx_pure_nrmse<const N: usize>() -> f64 {
    let cfg = LrxConfig::new().unwrap();
    let (pure, hybrid) = mdof::<N>();
    let mut rng = StdRng::seed_from_u64(1);
    let (mut rows, mut ys) = (Vec::new(), Vec::new());
    for (m, s) in &cfg.motions {
        let ag = m.scaled(*s).resample_mm_s2(DT_S);
        for &f in &cfg.frame_factors {
            let (_, f0) = mdof_run(hybrid, &ag, f, &[]);
            let p = band_limited_noise(ag.len(), 0.3 * rms_of(&f0), &mut rng).unwrap();
            let (d, fo) = mdof_run(hybrid, &ag, f, &p);
            frame_rows(&ag, &d, &fo, &mut rows, &mut ys);
        }
    }
    let x = DMatrix::from_fn(rows.len(), LRX_COEFFS, |i, j| rows[i][j]);
    let theta = lstsq::solve(&x, &DVector::from_vec(ys), 1e-12)
        .unwrap()
        .coeffs;
    let mut c = [0.0; LRX_COEFFS];
    c.iter_mut().zip(&theta).for_each(|(d, s)| *d = *s);
    let params = LrxParams::new(c, 1224.1, 0.0).unwrap();
    let ag = GroundMotion::el_centro().resample_mm_s2(DT_S);
    let proto = Prototype::paper();
    let mut ch = Chang::new(pure, DT_S).unwrap();
    ch.reset(ag[0]);
    let mut reference = vec![0.0];
    for &g in &ag[1..] {
        reference.push(proto.brace_disp_mm(ch.next_displacement()[0]));
        ch.advance(g, &Vector::<N>::zeros());
    }
    // A model that diverges trips the controller's supervisor: infinitely far from the reference.
    let lrx = Analytical::Lrx(Lrx::new(params));
    match super::super::pure::prediction("lrx-pure", lrx, proto, 0, &ag) {
        Ok(out) if out.iter().all(|d| d.abs() <= 1e6) => {
            metrics::nrmse_pct(&out, &reference).unwrap()
        }
        _ => f64::INFINITY,
    }
}

#[test]
fn mdof_frames_need_more_than_a_third_order_model() {
    let e1 = mdof_lrx_pure_nrmse::<1>();
    let e2 = mdof_lrx_pure_nrmse::<2>();
    let e3 = mdof_lrx_pure_nrmse::<3>();
    let e5 = mdof_lrx_pure_nrmse::<5>();
    println!("lrx-pure (order 3) on an N-story frame, El Centro: N=1 {e1:.4}%, N=2 {e2:.3}%, N=3 {e3:.3}%, N=5 {e5:.3}%");
    assert!(e1 < 0.01, "{e1}");
    // The documented limitation (docs/lrx.md): a third-order model is not a reduced model of a
    // multi-story frame. If this fails, the model got better: update the notes.
    assert!(e2 > 5.0 && e5 > 5.0, "{e2} {e5}");
}

/// The shipped `data/models/lrx.json` is what the default training produces (as `rths reproduce`
/// and `rths train lrx` do).
#[test]
fn shipped_model_is_the_default_training() {
    let shipped = ModelFile::load(
        &std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("data/models/lrx.json"),
    )
    .unwrap();
    let t = trained();
    let (s, w) = (shipped.lrx.unwrap(), t.file.lrx.unwrap());
    let close = |a: &[f64], b: &[f64]| {
        a.len() == b.len()
            && a.iter()
                .zip(b)
                .all(|(x, y)| (x - y).abs() <= 1e-12 * x.abs().max(y.abs()).max(1e-300))
    };
    assert!(
        close(&s.coeffs, &w.coeffs),
        "{:?} vs {:?}",
        s.coeffs,
        w.coeffs
    );
    assert!(close(&s.lead_weights, &w.lead_weights));
    assert_eq!(
        (s.lead_stride, s.k_corr_kn_per_mm, s.k_adapt_ticks),
        (w.lead_stride, w.k_corr_kn_per_mm, w.k_adapt_ticks)
    );
}
