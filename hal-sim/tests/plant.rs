//! The virtual plant against closed forms: frequency response, control-structure interaction,
//! saturations, reproducibility, faults.

use nalgebra::SMatrix;
use num_complex::Complex64 as C;
use rths_core::hal::{Actuator, Daq, Error, ErrorKind, Sample};
use rths_hal_sim::*;

const DT: f64 = 1.0 / 2048.0;
const TAU: f64 = std::f64::consts::TAU;

fn ideal(preset: Preset) -> RigConfig {
    let mut c = RigConfig::new(preset);
    c.sensors = Sensors::ideal();
    c
}

/// Gain and phase of the simulated plant at `f_hz`: a 1 mm sine command held by the DAC, the true
/// displacement sampled at the ticks, fitted by a sine and a cosine over whole periods.
fn simulated_response(params: PlantParams, f_hz: f64) -> Response {
    let mut rig = VirtualRig::new(params);
    let w = TAU * f_hz;
    let settle = 8192;
    let window = if f_hz < 1.0 { 4096 } else { 2048 };
    let (mut s, mut c) = (0.0, 0.0);
    for k in 0..settle + window {
        rig.command((w * k as f64 * DT).sin()).unwrap();
        rig.advance_tick();
        if k >= settle {
            // The sample after the tick is at t = (k + 1)·dt.
            let t = (k + 1) as f64 * DT;
            s += rig.true_disp_mm() * (w * t).sin();
            c += rig.true_disp_mm() * (w * t).cos();
        }
    }
    let (a, b) = (2.0 * s / window as f64, 2.0 * c / window as f64);
    let p = b.atan2(a).to_degrees();
    Response {
        gain: a.hypot(b),
        phase_deg: if p > 0.0 { p - 360.0 } else { p },
    }
}

fn close(sim: Response, tf: Response, what: &str) {
    let dg = (sim.gain / tf.gain - 1.0).abs();
    let dp = (sim.phase_deg - tf.phase_deg).abs();
    assert!(
        dg < 0.01 && dp < 1.0,
        "{what}: simulated {sim:?} vs transfer function {tf:?} (gain error {:.3}%, phase error {dp:.3}°)",
        100.0 * dg
    );
}

#[test]
fn discrete_plant_matches_continuous_transfer_function() {
    for preset in [Preset::Benchmark, Preset::UnrCompact] {
        let params = ideal(preset).build().unwrap();
        for f in [0.5, 1.0, 2.0, 5.0, 10.0, 20.0] {
            let sim = simulated_response(params, f);
            // The controller sees the continuous plant behind the DAC's zero-order hold.
            close(
                sim,
                params.sampled_frequency_response(f),
                &format!("{preset:?} at {f} Hz"),
            );
            // The ZOH itself is half a tick of delay: below 1° up to 5 Hz.
            if f <= 5.0 {
                close(
                    sim,
                    params.frequency_response(f),
                    &format!("{preset:?} at {f} Hz without ZOH"),
                );
            }
        }
    }
}

#[test]
fn published_benchmark_figures() {
    let p = RigConfig::new(Preset::Benchmark).build().unwrap();
    // docs/design.md §4: gain ≈ 0.85 at 5 Hz, delay about 25 ms.
    let r5 = p.frequency_response(5.0);
    assert!((r5.gain - 0.85).abs() < 0.05, "{r5:?}");
    let delay_ms = 1e3 * p.phase_delay_s(1.0);
    assert!((20.0..30.0).contains(&delay_ms), "{delay_ms} ms");
    // Time scaling s → s/r: the unr-compact response at r·f is the benchmark's at f.
    let u = RigConfig::new(Preset::UnrCompact).build().unwrap();
    let r = u.time_scale();
    let a = p.frequency_response(3.0);
    let b = u.frequency_response(3.0 * r);
    assert!((a.gain - b.gain).abs() < 1e-9 && (a.phase_deg - b.phase_deg).abs() < 1e-6);
}

/// Linearized state matrix of the plant (states q, q̇, f, x, ẋ) with the loop closed.
fn state_matrix(p: &PlantParams) -> SMatrix<f64, 5, 5> {
    let m = p.specimen_mass_kg();
    let k = p.specimen_stiffness_kn_per_mm() * 1e6;
    let c = p.specimen_damping_n_s_per_m();
    #[rustfmt::skip]
    let a = SMatrix::<f64, 5, 5>::from_row_slice(&[
        0.0, 1.0, 0.0, 0.0, 0.0,
        -p.beta2(), -p.beta1(), 0.0, -p.a1_beta0(), 0.0,
        1.0, 0.0, -p.a3(), 0.0, -p.a2(),
        0.0, 0.0, 0.0, 0.0, 1.0,
        0.0, 0.0, 1.0 / m, -k / m, -c / m,
    ]);
    a
}

#[test]
fn poles_are_stable_and_substeps_resolve_them() {
    for preset in [Preset::Benchmark, Preset::UnrCompact] {
        let p = RigConfig::new(preset).build().unwrap();
        let eig = state_matrix(&p).complex_eigenvalues();
        let h = p.dt_s() / f64::from(p.substeps());
        let fastest = eig.iter().map(|l| l.norm()).fold(0.0, f64::max);
        println!("{preset:?}: poles {eig}");
        println!(
            "{preset:?}: |λ|max = {fastest:.0} rad/s, |λh| = {:.3}",
            fastest * h
        );
        assert!(eig.iter().all(|l| l.re < 0.0), "{preset:?}: {eig}");
        // RK4 local error (λh)⁵/120 stays below 2e-5 with |λh| ≤ 0.3.
        assert!(fastest * h < 0.3, "{preset:?}: |λ|max = {fastest}, h = {h}");
    }
}

#[test]
fn substeps_converge() {
    let run = |n: u32| {
        let mut c = ideal(Preset::UnrCompact);
        // RK4 on every tick (the linear plant would otherwise take the exact step).
        c.integration = Integration::Rk4;
        c.substeps = n;
        let mut rig = VirtualRig::new(c.build().unwrap());
        let mut out = vec![];
        for k in 0..4096 {
            rig.command(5.0 * (TAU * 4.0 * k as f64 * DT).sin())
                .unwrap();
            rig.advance_tick();
            out.push(rig.true_disp_mm());
        }
        out
    };
    let (a, b) = (run(4), run(64));
    let e = a
        .iter()
        .zip(&b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max);
    assert!(e < 1e-4, "4 vs 64 sub-steps differ by {e} mm");
}

/// The benchmark loop without the interaction term `a2·s` (G0 = Ga·Ge).
fn no_csi(p: &PlantParams, f_hz: f64) -> C {
    let s = C::new(0.0, TAU * f_hz);
    let gs = p.a1_beta0() / (s * s + s * p.beta1() + p.beta2());
    let ge = 1.0
        / (s * s * p.specimen_mass_kg()
            + s * p.specimen_damping_n_s_per_m()
            + p.specimen_stiffness_kn_per_mm() * 1e6);
    let g0 = ge / (s + p.a3());
    gs * g0 / (1.0 + gs * g0) * p.gain()
}

#[test]
fn control_structure_interaction_depends_on_specimen_stiffness() {
    let with_k = |factor: f64| {
        let mut c = ideal(Preset::Benchmark);
        c.specimen_stiffness_kn_per_mm *= factor;
        c.build().unwrap()
    };
    let (soft, stiff) = (with_k(0.25), with_k(4.0));
    let f = 5.0;
    let (rs, rk) = (simulated_response(soft, f), simulated_response(stiff, f));
    println!("5 Hz: soft {rs:?}, stiff {rk:?}");
    // The simulated plant follows the CSI transfer function at both stiffnesses...
    close(rs, soft.sampled_frequency_response(f), "soft");
    close(rk, stiff.sampled_frequency_response(f), "stiff");
    // ...which moves visibly with the specimen.
    assert!(
        (rs.phase_deg - rk.phase_deg).abs() > 5.0 || (rs.gain / rk.gain - 1.0).abs() > 0.05,
        "soft {rs:?} vs stiff {rk:?}"
    );
    // Without the interaction term the model would be far from the simulation.
    for (p, sim) in [(soft, rs), (stiff, rk)] {
        let g = no_csi(&p, f);
        let rel = (g.norm() / sim.gain - 1.0).abs();
        let dp = (g.arg().to_degrees() - sim.phase_deg).abs();
        println!("no-CSI model: gain error {rel:.3}, phase error {dp:.1}°");
        assert!(rel > 0.05 || dp > 5.0, "no-CSI model matches: {rel} {dp}");
    }
}

#[test]
fn stroke_saturation_holds() {
    let mut rig = VirtualRig::new(RigConfig::new(Preset::UnrCompact).build().unwrap());
    let mut peak: f64 = 0.0;
    for _ in 0..4096 {
        let e = rig.command(40.0).unwrap_err();
        assert_eq!(e.kind(), ErrorKind::OutOfRange);
        rig.advance_tick();
        peak = peak.max(rig.true_disp_mm().abs());
        assert!(rig.read().unwrap().disp_mm <= 25.4);
    }
    assert!(peak <= 25.4 && peak > 25.0, "peak {peak}");
    assert_eq!(
        rig.command(f64::NAN).unwrap_err().kind(),
        ErrorKind::NotFinite
    );
}

#[test]
fn velocity_saturation_holds() {
    // A soft specimen, so that the whole rated flow goes into piston velocity.
    let mut c = ideal(Preset::UnrCompact);
    c.specimen_stiffness_kn_per_mm = 0.01;
    let mut rig = VirtualRig::new(c.build().unwrap());
    let mut peak: f64 = 0.0;
    for k in 0..8192 {
        let u = if (k / 1024) % 2 == 0 { 20.0 } else { -20.0 };
        rig.command(u).unwrap();
        rig.advance_tick();
        peak = peak.max(rig.true_vel_mm_s().abs());
    }
    assert!(peak <= 338.84 + 1e-9, "{peak}");
    assert!(peak > 0.95 * 338.84, "the limit is not reached: {peak}");
}

#[test]
fn force_saturation_holds() {
    // Four times the brace stiffness at 15 mm would need 73 kN.
    let mut c = ideal(Preset::Benchmark);
    c.specimen_stiffness_kn_per_mm *= 4.0;
    let mut rig = VirtualRig::new(c.build().unwrap());
    let mut peak: f64 = 0.0;
    for _ in 0..8192 {
        rig.command(15.0).unwrap();
        rig.advance_tick();
        peak = peak.max(rig.true_force_kn().abs());
    }
    assert!(peak <= 31.14 + 1e-9 && peak > 31.0, "{peak}");
    // The actuator stalls short of the command.
    assert!(rig.true_disp_mm() < 31.14 / c.specimen_stiffness_kn_per_mm + 0.1);
}

type Rec = Vec<Result<Sample, SimError>>;

fn record(c: RigConfig, faults: FaultPlan, n: usize) -> Rec {
    let mut rig = VirtualRig::with_faults(c.build().unwrap(), faults);
    (0..n)
        .map(|k| {
            let s = rig.read();
            let _ = rig.command(5.0 * (TAU * 2.0 * k as f64 * DT).sin());
            rig.advance_tick();
            s
        })
        .collect()
}

fn bits(v: &Rec) -> Vec<(u64, u64)> {
    v.iter()
        .map(|s| {
            let s = s.unwrap();
            (s.disp_mm.to_bits(), s.force_kn.to_bits())
        })
        .collect()
}

#[test]
fn seeds_reproduce_bit_for_bit() {
    for specimen in [Specimen::Linear, Specimen::BoucWen(BoucWen::default())] {
        let mut c = RigConfig::new(Preset::UnrCompact);
        c.seed = 42;
        c.uncertainty = true;
        c.specimen = specimen;
        let a = bits(&record(c, FaultPlan::none(), 4096));
        let b = bits(&record(c, FaultPlan::none(), 4096));
        assert_eq!(a, b);
        c.seed = 43;
        assert_ne!(a, bits(&record(c, FaultPlan::none(), 4096)));
        // Reset re-seeds.
        let mut rig = VirtualRig::new(c.build().unwrap());
        let mut run = || -> Vec<u64> {
            (0..100)
                .map(|_| {
                    rig.command(1.0).unwrap();
                    rig.advance_tick();
                    rig.read().unwrap().disp_mm.to_bits()
                })
                .collect()
        };
        let first = run();
        rig.reset();
        let mut run = || -> Vec<u64> {
            (0..100)
                .map(|_| {
                    rig.command(1.0).unwrap();
                    rig.advance_tick();
                    rig.read().unwrap().disp_mm.to_bits()
                })
                .collect()
        };
        assert_eq!(first, run());
    }
}

#[test]
fn uncertainty_has_the_published_spread() {
    let n = 2000;
    let mut draws = vec![];
    for seed in 0..n {
        let mut c = RigConfig::new(Preset::Benchmark);
        c.seed = seed;
        c.uncertainty = true;
        let p = c.build().unwrap();
        draws.push([
            p.beta1(),
            p.beta2(),
            p.a3(),
            p.specimen_stiffness_kn_per_mm() * 1e6,
        ]);
    }
    let nominal = [425.0, 9.9976e4, 3.3, 1.2241e6];
    // A normal truncated at 2.5σ has a standard deviation of 0.946σ.
    let sigma = [3.3, 3.3e3, 1.3, 5e4].map(|s| 0.946 * s);
    for i in 0..4 {
        let mean = draws.iter().map(|d| d[i]).sum::<f64>() / n as f64;
        let sd = (draws.iter().map(|d| (d[i] - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        assert!(
            (mean - nominal[i]).abs() < 4.0 * sigma[i] / (n as f64).sqrt(),
            "{i}: mean {mean}"
        );
        assert!(
            (sd / sigma[i] - 1.0).abs() < 0.08,
            "{i}: σ {sd} vs {}",
            sigma[i]
        );
    }
}

#[test]
fn sensors_are_quantized_and_noisy() {
    let c = RigConfig::new(Preset::UnrCompact);
    let mut rig = VirtualRig::new(c.build().unwrap());
    let lsb_mm = 50.8 / 65536.0;
    let lsb_kn = 62.28 / 65536.0;
    let mut err = vec![];
    for _ in 0..4096 {
        rig.command(3.0).unwrap();
        rig.advance_tick();
        let s = rig.read().unwrap();
        assert!(((s.disp_mm / lsb_mm) - (s.disp_mm / lsb_mm).round()).abs() < 1e-6);
        assert!(((s.force_kn / lsb_kn) - (s.force_kn / lsb_kn).round()).abs() < 1e-6);
        err.push(s.disp_mm - rig.true_disp_mm());
    }
    let sd = (err.iter().map(|e| e * e).sum::<f64>() / err.len() as f64).sqrt();
    // Noise σ = 0.002 mm plus quantization LSB/√12 = 0.00022 mm.
    assert!((sd - 0.002).abs() < 0.0003, "σ = {sd}");
}

#[test]
fn every_fault_is_observed_at_the_daq() {
    let c = RigConfig::new(Preset::UnrCompact);
    let (start, dur) = (1000usize, 50usize);
    let end = start + dur;
    let healthy = record(c, FaultPlan::none(), 2000);
    let with = |kind| {
        let f = Fault::new(kind, start as u64, dur as u64).unwrap();
        record(c, FaultPlan::none().with(f).unwrap(), 2000)
    };
    let in_window = |k: usize| (start..end).contains(&k);

    let r = with(FaultKind::Dropout);
    for (k, s) in r.iter().enumerate() {
        assert_eq!(s.is_err(), in_window(k), "tick {k}");
        if let Err(e) = s {
            assert_eq!(e.kind(), ErrorKind::Timeout);
        }
    }

    let r = with(FaultKind::NaN(Channel::Force));
    for (k, s) in r.iter().enumerate() {
        let s = s.unwrap();
        assert_eq!(s.force_kn.is_nan(), in_window(k));
        assert!(s.disp_mm.is_finite());
    }

    let r = with(FaultKind::Stuck(Channel::Disp));
    let stuck = r[start - 1].unwrap().disp_mm;
    for k in start..end {
        assert_eq!(r[k].unwrap().disp_mm, stuck);
        assert_eq!(r[k].unwrap().force_kn, healthy[k].unwrap().force_kn);
    }
    assert_ne!(r[end].unwrap().disp_mm, stuck);

    let r = with(FaultKind::Spike(Channel::Disp, 2.0));
    for k in 0..2000 {
        let d = r[k].unwrap().disp_mm - healthy[k].unwrap().disp_mm;
        let want = if in_window(k) { 2.0 } else { 0.0 };
        assert!((d - want).abs() < 1e-3, "tick {k}: {d}");
    }

    // Lost ticks: stale samples, and the commands sent meanwhile never arrive.
    let r = with(FaultKind::LostTicks);
    let stale = r[start - 1].unwrap();
    for s in &r[start..end] {
        assert_eq!(s.unwrap(), stale);
    }
    assert!((r[end + 5].unwrap().disp_mm - healthy[end + 5].unwrap().disp_mm).abs() > 0.05);

    // Valve saturation: the actuator falls behind while the valve is starved.
    let r = with(FaultKind::ValveSaturation(0.05));
    assert_eq!(r[..start], healthy[..start]);
    let lag = (r[end].unwrap().disp_mm - healthy[end].unwrap().disp_mm).abs();
    assert!(lag > 0.5, "{lag}");

    // Stiffness change: the load cell sees a softer specimen at the same displacement.
    let r = with(FaultKind::StiffnessChange(0.5));
    let ratio = |s: Sample| s.force_kn / s.disp_mm;
    let (a, b) = (ratio(r[end].unwrap()), ratio(healthy[end].unwrap()));
    assert!(a / b < 0.7, "force/disp {a} vs {b}");
}

#[test]
fn bad_configs_are_rejected() {
    let mut c = RigConfig::new(Preset::Benchmark);
    c.substeps = 2;
    assert!(c.build().is_err());
    let mut c = RigConfig::new(Preset::Benchmark);
    c.specimen_stiffness_kn_per_mm = f64::NAN;
    assert_eq!(
        c.build().unwrap_err(),
        ConfigError::NotFinite("specimen stiffness")
    );
    assert!(Fault::new(FaultKind::ValveSaturation(1.5), 0, 1).is_err());
    assert!(Fault::new(FaultKind::StiffnessChange(0.0), 0, 1).is_err());
    let f = Fault::new(FaultKind::Dropout, 0, 1).unwrap();
    let mut plan = FaultPlan::none();
    for _ in 0..fault::MAX_FAULTS {
        plan = plan.with(f).unwrap();
    }
    assert_eq!(plan.with(f).unwrap_err(), ConfigError::TooManyFaults);
}

#[test]
fn bouc_wen_is_hysteretic() {
    let mut c = ideal(Preset::UnrCompact);
    c.specimen = Specimen::BoucWen(BoucWen::default());
    let mut rig = VirtualRig::new(c.build().unwrap());
    // One cycle to 15 mm (yield at 6 mm), ending back at zero displacement.
    let mut peak: f64 = 0.0;
    for k in 0..4096 {
        let u = 15.0 * (TAU * 0.5 * k as f64 * DT).sin();
        rig.command(u).unwrap();
        rig.advance_tick();
        peak = peak.max(rig.true_restoring_force_kn().abs());
    }
    for _ in 0..400 {
        rig.command(0.0).unwrap();
        rig.advance_tick();
    }
    let k = 1.2241;
    // Yield force k·x_y = 7.3 kN with 10% hardening: far below the elastic 18.4 kN.
    assert!(peak < 0.7 * k * 15.0 && peak > k * 6.0, "peak {peak}");
    // Back near zero displacement (the proportional servo leaves a small error against the
    // residual force), a residual force far above k·x remains: the loop has area.
    assert!(rig.true_disp_mm().abs() < 0.2, "{}", rig.true_disp_mm());
    assert!(
        rig.true_restoring_force_kn().abs() > 1.0,
        "{}",
        rig.true_restoring_force_kn()
    );
}
