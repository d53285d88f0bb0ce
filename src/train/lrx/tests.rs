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
                rig: {
                    let mut c = scenario::rig_config(Preset::UnrCompact, spec, f, 1);
                    if std::env::var("IDEAL").is_ok() {
                        c.sensors = rths_hal_sim::Sensors::ideal();
                    }
                    c
                },
                stiffness_factor: f,
                lr: None,
                rnn: None,
                delay_steps: 28,
                lrx: Some((fp, lp)),
            })
            .unwrap();
            let r = run.report;
            if let Specimen::Linear = spec {
                let hr = hybrid_ref(&ag, f);
                let h = &run.history;
                let (mut sxx, mut sfx) = (0.0, 0.0);
                for (x, fo) in h.measured_mm.iter().zip(&h.measured_force_kn) {
                    if x.is_finite() {
                        sxx += x * x;
                        sfx += x * fo * 1000.0;
                    }
                }
                eprintln!("   LS k/k_b = {:.4} (F = {f})", sfx / sxx / 1224.1);
                eprintln!(
                    "   target vs hybrid ref {:.3}%  measured vs hybrid ref {:.3}%",
                    rths_core::metrics::nrmse_pct(&run.history.target_mm, &hr).unwrap(),
                    rths_core::metrics::nrmse_pct(&run.history.measured_mm, &hr).unwrap()
                );
            }
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

#[test]
#[ignore]
fn hybrid_reference() {
    let f: f64 = std::env::var("F")
        .map(|v| v.parse().unwrap())
        .unwrap_or(1.0);
    let ag = GroundMotion::el_centro().scaled(0.85).resample_mm_s2(DT_S);
    let p = scenario::rig_config(Preset::UnrCompact, Specimen::Linear, f, 1)
        .build()
        .unwrap();
    let (me, ce) = (p.specimen_mass_kg(), p.specimen_damping_n_s_per_m());
    eprintln!("m_e {me} kg, c_e {ce} N s/m");
    let proto = crate::scenario::specimen_prototype(f).unwrap();
    let c2 = proto.cos_theta().powi(2);
    let m = proto.mass_kn_s2_per_mm();
    let sim = |ms: f64, cs: f64| {
        let mt = m + ms * c2;
        let ct = proto.damping_kn_s_per_mm() + cs * c2;
        let kt = proto.total_stiffness_kn_per_mm();
        let dt = DT_S;
        let (mut x, mut v) = (0.0f64, 0.0f64);
        let mut a = -m * ag[0] / mt;
        let keff = kt + 2.0 * ct / dt + 4.0 * mt / (dt * dt);
        let mut out = vec![0.0];
        for &g in &ag[1..] {
            let rhs =
                -m * g + mt * (4.0 * x / (dt * dt) + 4.0 * v / dt + a) + ct * (2.0 * x / dt + v);
            let xn = rhs / keff;
            let vn = 2.0 * (xn - x) / dt - v;
            let an = 4.0 * (xn - x) / (dt * dt) - 4.0 * v / dt - a;
            x = xn;
            v = vn;
            a = an;
            out.push(proto.brace_disp_mm(x));
        }
        out
    };
    let r0 = sim(0.0, 0.0);
    let r1 = sim(me * 1e-3, ce * 1e-3);
    let r2 = sim(0.0, ce * 1e-3);
    eprintln!(
        "F={f}: with specimen m,c vs pure: {:.3}%  (c only {:.3}%)",
        rths_core::metrics::nrmse_pct(&r1, &r0).unwrap(),
        rths_core::metrics::nrmse_pct(&r2, &r0).unwrap()
    );
}

fn hybrid_ref(ag: &[f64], f: f64) -> Vec<f64> {
    let p = scenario::rig_config(Preset::UnrCompact, Specimen::Linear, f, 1)
        .build()
        .unwrap();
    let (me, ce) = (
        p.specimen_mass_kg() * 1e-3,
        p.specimen_damping_n_s_per_m() * 1e-3,
    );
    let proto = crate::scenario::specimen_prototype(f).unwrap();
    let c2 = proto.cos_theta().powi(2);
    let m = proto.mass_kn_s2_per_mm();
    let mt = m + me * c2;
    let ct = proto.damping_kn_s_per_mm() + ce * c2;
    let kt = proto.total_stiffness_kn_per_mm();
    let dt = DT_S;
    let (mut x, mut v) = (0.0f64, 0.0f64);
    let mut a = -m * ag[0] / mt;
    let keff = kt + 2.0 * ct / dt + 4.0 * mt / (dt * dt);
    let mut out = vec![0.0];
    for &g in &ag[1..] {
        let rhs = -m * g + mt * (4.0 * x / (dt * dt) + 4.0 * v / dt + a) + ct * (2.0 * x / dt + v);
        let xn = rhs / keff;
        let vn = 2.0 * (xn - x) / dt - v;
        let an = 4.0 * (xn - x) / (dt * dt) - 4.0 * v / dt - a;
        x = xn;
        v = vn;
        a = an;
        out.push(proto.brace_disp_mm(x));
    }
    out
}

#[test]
#[ignore]
fn pure_at_factors() {
    let mut cfg = LrxConfig::new().unwrap();
    if let Ok(v) = std::env::var("RCOND") {
        cfg.rcond = v.parse().unwrap();
    }
    if let Ok(v) = std::env::var("PERT") {
        cfg.perturbation = v.parse().unwrap();
    }
    if std::env::var("CHANG").is_ok() {
        cfg.exact_frame = false;
    }
    if let Ok(v) = std::env::var("FF") {
        cfg.frame_factors = v.split(',').map(|x| x.parse().unwrap()).collect();
    }
    let tr = train(&cfg).unwrap();
    eprintln!("cond {:.3e} coeffs {:?}", tr.frame_condition, tr.coeffs);
    let (fp, _) = crate::models::lrx_params(&tr.file).unwrap();
    let ag = GroundMotion::el_centro().scaled(0.85).resample_mm_s2(DT_S);
    for f in [0.6, 0.8, 1.0, 1.2, 1.4] {
        let proto = crate::scenario::specimen_prototype(f).unwrap();
        let reference = crate::train::data::pure_response(&proto, &ag, DT_S)
            .unwrap()
            .brace_disp_mm;
        for delay in [0usize, 28] {
            let mut m = Lrx::new(fp);
            let mut out = vec![];
            let mut d = 0.0;
            for (i, &g) in ag.iter().enumerate() {
                out.push(d);
                let xd = if i >= delay { out[i - delay] } else { 0.0 };
                d = m
                    .predict(LrxInputs {
                        ground_accel_mm_s2: g,
                        brace_disp_fb_mm: xd,
                        brace_force_fb_kn: proto.brace_force_kn(xd),
                    })
                    .unwrap();
            }
            eprintln!(
                "F={f} delay {delay}: {:.4}%  k_est/k_b {:.4}",
                metrics::nrmse_pct(&out, &reference).unwrap(),
                m.state().k_est_kn_per_mm / 1224.1
            );
        }
    }
}

#[test]
#[ignore]
fn hybrid_chang_vs_pure() {
    let ag = GroundMotion::el_centro().scaled(0.85).resample_mm_s2(DT_S);
    for f in [0.6, 0.8, 1.0, 1.2, 1.4] {
        let proto = crate::scenario::specimen_prototype(f).unwrap();
        let reference = crate::train::data::pure_response(&proto, &ag, DT_S)
            .unwrap()
            .brace_disp_mm;
        let nm =
            crate::analysis::pure_response(&proto, &ag, DT_S, crate::analysis::Method::Newmark)
                .unwrap()
                .brace_disp_mm;
        let (d, _) = frame_run(&ag, f, &[]).unwrap();
        eprintln!("F={f}: hybrid Chang vs pure Chang {:.4}%, pure Chang vs Newmark {:.4}%, hybrid vs Newmark {:.4}%", metrics::nrmse_pct(&d, &reference).unwrap(), metrics::nrmse_pct(&reference, &nm).unwrap(), metrics::nrmse_pct(&d, &nm).unwrap());
    }
}

#[test]
#[ignore]
fn order_study() {
    let cfg = LrxConfig::new().unwrap();
    let mut rng = StdRng::seed_from_u64(1);
    let ags: Vec<Vec<f64>> = cfg
        .motions
        .iter()
        .map(|(m, s)| m.scaled(*s).resample_mm_s2(DT_S))
        .collect();
    let ffs: Vec<f64> = std::env::var("FF")
        .map(|v| v.split(',').map(|x| x.parse().unwrap()).collect())
        .unwrap_or(vec![0.5, 1.0, 1.5]);
    for n in [3usize, 4, 5] {
        let mut rows: Vec<Vec<f64>> = vec![];
        let mut ys = vec![];
        for ag in &ags {
            for &f in &ffs {
                let (_, f0) = frame_run_exact(ag, f, &[]).unwrap();
                let p = band_limited_noise(ag.len(), 0.3 * rms_of(&f0), &mut rng).unwrap();
                let (d, fo) = frame_run_exact(ag, f, &p).unwrap();
                for i in 0..d.len() - 1 {
                    let mut r = vec![];
                    for j in 0..n {
                        r.push(lag(&d, i, j));
                    }
                    for j in 0..n {
                        r.push(lag(ag, i, j));
                    }
                    for j in 0..n {
                        r.push(lag(&fo, i, j));
                    }
                    rows.push(r);
                    ys.push(d[i + 1]);
                }
            }
        }
        let x = DMatrix::from_fn(rows.len(), 3 * n, |i, j| rows[i][j]);
        let (th, cond) = lstsq(&x, &DVector::from_vec(ys), 1e-15).unwrap();
        let ag = GroundMotion::el_centro().scaled(0.85).resample_mm_s2(DT_S);
        let mut line = format!("order {n} cond {cond:.2e}:");
        for f in [0.6, 0.8, 1.0, 1.2, 1.4] {
            let proto = crate::scenario::specimen_prototype(f).unwrap();
            let reference = crate::train::data::pure_response(&proto, &ag, DT_S)
                .unwrap()
                .brace_disp_mm;
            let (mut d, mut fo) = (vec![0.0; ag.len()], vec![0.0; ag.len()]);
            for i in 0..ag.len() - 1 {
                fo[i] = proto.brace_force_kn(d[i]);
                let mut y = 0.0;
                for j in 0..n {
                    y += th[j] * lag(&d, i, j)
                        + th[n + j] * lag(&ag, i, j)
                        + th[2 * n + j] * lag(&fo, i, j);
                }
                d[i + 1] = y;
            }
            line += &format!(
                " F={f}: {:.4}%",
                metrics::nrmse_pct(&d, &reference).unwrap()
            );
        }
        eprintln!("{line}");
    }
}

/// The Bouc–Wen reference of `study::reference_for` at step dt/`sub` (decimated back).
fn bw_reference_fine(m: &GroundMotion, sub: usize) -> Vec<f64> {
    let bw = rths_hal_sim::BoucWen::default();
    let dt = DT_S / sub as f64;
    let ag = m.resample_mm_s2(dt);
    let proto = Prototype::paper();
    let scale = SpecimenScale::default();
    let k_spec = scale.specimen_stiffness_kn_per_mm(proto.brace_axial_stiffness_kn_per_mm());
    let mut ch = Chang::new(LinearStructure::prototype_hybrid(&proto).unwrap(), dt).unwrap();
    ch.reset(ag[0]);
    let dz_dx = |z: f64, dx: f64| {
        let sgn = if dx * z > 0.0 {
            1.0
        } else if dx * z < 0.0 {
            -1.0
        } else {
            0.0
        };
        (bw.a - z.abs().powf(bw.n) * (bw.beta * sgn + bw.gamma)) / bw.yield_disp_mm
    };
    let (mut z, mut d_prev) = (0.0_f64, 0.0_f64);
    let mut out = vec![0.0];
    for &g in &ag[1..] {
        let d = proto.brace_disp_mm(ch.next_displacement()[0]);
        let h = (d - d_prev) / 8.0;
        for _ in 0..8 {
            let k1 = dz_dx(z, h);
            let k2 = dz_dx(z + 0.5 * h * k1, h);
            let k3 = dz_dx(z + 0.5 * h * k2, h);
            let k4 = dz_dx(z + h * k3, h);
            z += h / 6.0 * (k1 + 2.0 * k2 + 2.0 * k3 + k4);
        }
        d_prev = d;
        let r = bw.post_yield_ratio * k_spec * d
            + (1.0 - bw.post_yield_ratio) * k_spec * bw.yield_disp_mm * z;
        ch.advance(
            g,
            &Vector::<1>::new(proto.story_force_kn(scale.prototype_force_kn(r))),
        );
        out.push(d);
    }
    out.into_iter().step_by(sub).collect()
}

#[test]
#[ignore]
fn bw_reference_convergence() {
    let m = GroundMotion::el_centro().scaled(0.85);
    let ag = m.resample_mm_s2(DT_S);
    let r1 = study::reference_for(&ag, Specimen::BoucWen(Default::default()), 1.0).unwrap();
    let r1b = bw_reference_fine(&m, 1);
    let r16 = bw_reference_fine(&m, 16);
    let n = r1.len().min(r16.len());
    eprintln!(
        "check {:.2e}%; 2048 Hz vs 32768 Hz: {:.4}%",
        metrics::nrmse_pct(&r1b[..n], &r1[..n]).unwrap(),
        metrics::nrmse_pct(&r1[..n], &r16[..n]).unwrap()
    );
    // linear: hybrid Chang at fine steps vs pure at 2048
    for f in [0.6, 1.4] {
        let proto = crate::scenario::specimen_prototype(f).unwrap();
        let nm = crate::train::data::pure_response(&proto, &ag, DT_S)
            .unwrap()
            .brace_disp_mm;
        let agf = m.resample_mm_s2(DT_S / 16.0);
        let mut ch = Chang::new(
            LinearStructure::prototype_hybrid(&Prototype::paper()).unwrap(),
            DT_S / 16.0,
        )
        .unwrap();
        ch.reset(agf[0]);
        let mut out = vec![0.0];
        for &g in &agf[1..] {
            let d = proto.brace_disp_mm(ch.next_displacement()[0]);
            ch.advance(
                g,
                &Vector::<1>::new(proto.story_force_kn(proto.brace_force_kn(d))),
            );
            out.push(d);
        }
        let out: Vec<f64> = out.into_iter().step_by(16).collect();
        let n = out.len().min(nm.len());
        eprintln!(
            "F={f}: hybrid Chang at 32768 Hz vs pure at 2048 Hz: {:.4}%",
            metrics::nrmse_pct(&out[..n], &nm[..n]).unwrap()
        );
    }
}
