//! The exact zero-order-hold tick of the linear plant against RK4 with many sub-steps, its RK4
//! fallback at the saturations, and reproducibility with faults.

use rths_core::hal::{Actuator, Daq};
use rths_core::integrator::{Chang, ExplicitIntegrator};
use rths_core::params::{Prototype, G_MM_S2};
use rths_core::structure::{LinearStructure, Vector};
use rths_hal_sim::*;

const DT: f64 = 1.0 / 2048.0;

/// The El Centro brace deformation (mm) at 2048 Hz: `IELC180.AT2` resampled linearly, the paper's
/// pure prototype integrated by Chang's method (as `rths plant` does).
fn el_centro_brace_mm() -> Vec<f64> {
    let text = include_str!(concat!(
        env!("CARGO_MANIFEST_DIR"),
        "/../data/ground_motions/IELC180.AT2"
    ));
    let accel_g: Vec<f64> = text
        .lines()
        .skip(4)
        .flat_map(|l| l.split_whitespace())
        .map(|v| v.parse::<f64>().unwrap())
        .collect();
    assert_eq!(accel_g.len(), 4000);
    let rec_dt = 0.01;
    let n = ((accel_g.len() - 1) as f64 * rec_dt / DT) as usize + 1;
    let ag: Vec<f64> = (0..n)
        .map(|k| {
            let pos = k as f64 * DT / rec_dt;
            let i = pos.floor() as usize;
            let a1 = accel_g.get(i + 1).copied().unwrap_or(accel_g[i]);
            (accel_g[i] + (pos - i as f64) * (a1 - accel_g[i])) * G_MM_S2
        })
        .collect();
    let proto = Prototype::paper();
    let mut ch = Chang::new(LinearStructure::prototype_pure(&proto).unwrap(), DT).unwrap();
    ch.reset(ag[0]);
    let zero = Vector::<1>::zeros();
    let mut out = vec![0.0];
    for &a in &ag[1..] {
        ch.advance(a, &zero);
        out.push(proto.brace_disp_mm(ch.state().disp[0]));
    }
    let peak = out.iter().fold(0.0f64, |m, x| m.max(x.abs()));
    assert!((peak - 12.67).abs() < 0.1, "El Centro brace peak {peak} mm");
    out
}

fn config(preset: Preset, integration: Integration, substeps: u32) -> RigConfig {
    let mut c = RigConfig::new(preset);
    c.sensors = Sensors::ideal();
    c.integration = integration;
    c.substeps = substeps;
    c
}

/// True displacement per tick (mm) following `command`, and the ticks taken exactly.
fn follow(c: RigConfig, faults: FaultPlan, command: &[f64]) -> (Vec<f64>, u64) {
    let mut rig = VirtualRig::with_faults(c.build().unwrap(), faults);
    let x = command
        .iter()
        .map(|&u| {
            let _ = rig.command(u);
            rig.advance_tick();
            rig.true_disp_mm()
        })
        .collect();
    (x, rig.exact_ticks())
}

fn max_diff(a: &[f64], b: &[f64]) -> f64 {
    a.iter()
        .zip(b)
        .map(|(x, y)| (x - y).abs())
        .fold(0.0, f64::max)
}

#[test]
fn exact_tick_matches_rk4_with_64_substeps_on_el_centro() {
    let target = el_centro_brace_mm();
    for preset in [Preset::Benchmark, Preset::UnrCompact] {
        let (exact, n_exact) = follow(
            config(preset, Integration::ExactLinear, 4),
            FaultPlan::none(),
            &target,
        );
        let (rk64, n64) = follow(
            config(preset, Integration::Rk4, 64),
            FaultPlan::none(),
            &target,
        );
        let (rk4, _) = follow(
            config(preset, Integration::Rk4, 4),
            FaultPlan::none(),
            &target,
        );
        let (e64, e4) = (max_diff(&exact, &rk64), max_diff(&rk4, &rk64));
        println!(
            "{preset:?}: {n_exact}/{} ticks exact; max |Δx| exact vs RK4×64 {e64:.3e} mm, \
             RK4×4 vs RK4×64 {e4:.3e} mm",
            target.len()
        );
        assert_eq!(n64, 0);
        // El Centro stays clear of every limit (valve ≤ 0.8 of its rated flow): all ticks exact.
        assert_eq!(n_exact, target.len() as u64);
        // RK4×64 is itself ~1e-12 mm from the exact solution; the exact tick is far closer to it
        // than the 4-sub-step RK4 it replaces.
        assert!(e64 < 1e-9, "exact vs RK4×64: {e64} mm");
        assert!(e4 > 10.0 * e64, "RK4×4 {e4} vs exact {e64}");
    }
}

/// A square wave of ±`amp_mm` with half-period `half` ticks.
fn square(amp_mm: f64, half: usize, n: usize) -> Vec<f64> {
    (0..n)
        .map(|k| if (k / half) % 2 == 0 { amp_mm } else { -amp_mm })
        .collect()
}

#[test]
fn fallback_engages_at_the_velocity_limit_and_matches_rk4() {
    // A soft specimen and ±20 mm steps: the piston runs at its velocity limit (338.84 mm/s).
    let mut exact_cfg = config(Preset::UnrCompact, Integration::ExactLinear, 4);
    exact_cfg.specimen_stiffness_kn_per_mm = 0.01;
    let mut rk_cfg = exact_cfg;
    rk_cfg.integration = Integration::Rk4;
    let cmd = square(20.0, 1024, 8192);
    let mut a = VirtualRig::new(exact_cfg.build().unwrap());
    let mut b = VirtualRig::new(rk_cfg.build().unwrap());
    let (mut dx, mut peak_v, mut at_limit) = (0.0f64, 0.0f64, 0);
    for &u in &cmd {
        a.command(u).unwrap();
        b.command(u).unwrap();
        let before = a.exact_ticks();
        a.advance_tick();
        b.advance_tick();
        let v = a.true_vel_mm_s().abs();
        peak_v = peak_v.max(v);
        if v > 0.999 * 338.84 {
            at_limit += 1;
            // A tick ending at the limit was never taken by the exact step.
            assert_eq!(a.exact_ticks(), before, "exact tick at {v} mm/s");
        }
        dx = dx.max((a.true_disp_mm() - b.true_disp_mm()).abs());
    }
    let n = cmd.len() as u64;
    println!(
        "velocity limit: {}/{n} ticks exact, {at_limit} at the limit, peak {peak_v} mm/s, \
         max |Δx| vs RK4 {dx:.3e} mm",
        a.exact_ticks()
    );
    assert!(
        peak_v <= 338.84 + 1e-9 && peak_v > 0.999 * 338.84,
        "{peak_v}"
    );
    assert!(at_limit > 100, "{at_limit}");
    assert!(a.exact_ticks() < n - at_limit && a.exact_ticks() > n / 2);
    assert_eq!(b.exact_ticks(), 0);
    // The same trajectory as the all-RK4 plant, to RK4's own 4-vs-64 sub-step agreement.
    assert!(dx < 1e-4, "max |Δx| {dx} mm");
}

#[test]
fn fallback_at_the_stroke_force_and_valve_limits_matches_rk4() {
    // Stroke end stop (40 mm command), relief valves (4× stiffer specimen at 15 mm), and a valve
    // delivering 30% of its flow (fault), each against the all-RK4 plant.
    let stroke = config(Preset::UnrCompact, Integration::ExactLinear, 4);
    let mut force = config(Preset::Benchmark, Integration::ExactLinear, 4);
    force.specimen_stiffness_kn_per_mm *= 4.0;
    let valve = FaultPlan::none()
        .with(Fault::new(FaultKind::ValveSaturation(0.3), 1000, 3000).unwrap())
        .unwrap();
    let cases = [
        (
            "stroke",
            stroke,
            FaultPlan::none(),
            square(40.0, 2048, 6144),
        ),
        ("force", force, FaultPlan::none(), square(15.0, 2048, 6144)),
        ("valve", stroke, valve, square(8.0, 512, 6144)),
    ];
    for (what, c, faults, cmd) in cases {
        let mut rk = c;
        rk.integration = Integration::Rk4;
        let (x, n_exact) = follow(c, faults, &cmd);
        let (y, _) = follow(rk, faults, &cmd);
        let dx = max_diff(&x, &y);
        println!(
            "{what}: {n_exact}/{} ticks exact, max |Δx| vs RK4 {dx:.3e} mm",
            cmd.len()
        );
        assert!(
            n_exact < cmd.len() as u64 && n_exact > 0,
            "{what}: {n_exact}"
        );
        assert!(dx < 1e-4, "{what}: max |Δx| {dx} mm");
    }
}

#[test]
fn stiffness_fault_keeps_the_exact_tick_at_the_new_stiffness() {
    let target = el_centro_brace_mm();
    let faults = FaultPlan::none()
        .with(Fault::new(FaultKind::StiffnessChange(0.5), 40_000, 30_000).unwrap())
        .unwrap();
    let (x, n_exact) = follow(
        config(Preset::UnrCompact, Integration::ExactLinear, 4),
        faults,
        &target,
    );
    let (y, _) = follow(
        config(Preset::UnrCompact, Integration::Rk4, 64),
        faults,
        &target,
    );
    let dx = max_diff(&x, &y);
    println!(
        "stiffness ×0.5: {n_exact}/{} ticks exact, max |Δx| vs RK4×64 {dx:.3e} mm",
        target.len()
    );
    assert_eq!(n_exact, target.len() as u64);
    assert!(dx < 1e-9, "max |Δx| {dx} mm");
}

#[test]
fn seeds_reproduce_bit_for_bit_with_faults_and_reset() {
    let faults = FaultPlan::none()
        .with(Fault::new(FaultKind::StiffnessChange(0.7), 500, 1000).unwrap())
        .unwrap()
        .with(Fault::new(FaultKind::ValveSaturation(0.2), 2000, 300).unwrap())
        .unwrap();
    let mut c = RigConfig::new(Preset::UnrCompact);
    c.seed = 9;
    c.uncertainty = true;
    let cmd = square(6.0, 400, 3000);
    let run = |rig: &mut VirtualRig| -> Vec<(u64, u64)> {
        cmd.iter()
            .map(|&u| {
                let s = rig.read().unwrap();
                rig.command(u).unwrap();
                rig.advance_tick();
                (s.disp_mm.to_bits(), s.force_kn.to_bits())
            })
            .collect()
    };
    let mut a = VirtualRig::with_faults(c.build().unwrap(), faults);
    let mut b = VirtualRig::with_faults(c.build().unwrap(), faults);
    let first = run(&mut a);
    assert_eq!(first, run(&mut b));
    let exact = a.exact_ticks();
    assert!(exact > 0 && exact < cmd.len() as u64, "{exact}");
    // After reset (the faulted-stiffness map is cached by then) the run repeats exactly.
    a.reset();
    assert_eq!(first, run(&mut a));
    assert_eq!(a.exact_ticks(), exact);
}
