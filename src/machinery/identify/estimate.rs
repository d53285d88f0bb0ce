//! The estimators: actuator frequency response (H1 with coherence), its gain-and-delay model, the
//! lead filter (plant inverse) and the specimen's stiffness. They take only arrays of measured
//! signals ([`Signals`]) and the excitation's design ([`Design`]): nothing here can see a
//! simulator.
//!
//! Conventions: `command_mm[k]` is the command sent at tick k (held from k to k+1),
//! `measured_mm[k]` and `force_kn[k]` are read at tick k before it. The frequency response is `H =
//! X/U` between these two sequences: the plant behind the DAC's hold, as the controller sees it.

use nalgebra::{DMatrix, DVector};
use rths_core::compensator::{LEAD_MAX_STRIDE, LEAD_TAPS};
use rths_core::filter::{Butterworth, ButterworthParams};
use rths_core::metrics;

use super::error::IdentifyError;

/// Lines at least this coherent count as well measured.
pub const COHERENCE_GOOD: f64 = 0.9;
/// Fraction of the lines that must be well measured, else the excitation was too small for the
/// noise (or the rig is not linear/time-invariant enough to characterize).
pub const MIN_GOOD_LINE_FRACTION: f64 = 0.95;
/// Smallest R² of the force model `F = k·x + c·ẋ + m·ẍ + F0`.
pub const MIN_STIFFNESS_R2: f64 = 0.9;
/// Largest NRMSE of the lead fit, %.
pub const MAX_LEAD_NRMSE_PCT: f64 = 20.0;
/// Plausible actuator gain (x/u at low frequency).
pub const GAIN_RANGE: (f64, f64) = (0.5, 2.0);
/// Plausible actuator delay, ms.
pub const DELAY_RANGE_MS: (f64, f64) = (0.0, 100.0);

/// Measured signals of an identification run, one entry per tick.
#[derive(Debug, Clone, Copy)]
pub struct Signals<'a> {
    /// Controller tick, s.
    pub dt_s: f64,
    /// Command sent at tick k, mm.
    pub command_mm: &'a [f64],
    /// Displacement read at tick k, mm.
    pub measured_mm: &'a [f64],
    /// Force read at tick k, kN.
    pub force_kn: &'a [f64],
}

/// What the estimators need to know of the excitation.
#[derive(Debug, Clone)]
pub struct Design {
    /// First tick of the analysed periods.
    pub window_start: usize,
    /// Ticks per period.
    pub period_ticks: usize,
    /// Number of analysed periods.
    pub periods: usize,
    /// Excited DFT bins (cycles per period).
    pub lines: Vec<usize>,
    /// Tap spacing of the lead filter, ticks.
    pub lead_stride: usize,
    /// Cutoff of the low-pass applied to force and displacement for the stiffness fit, Hz.
    pub stiffness_cutoff_hz: f64,
}

/// One line of the measured frequency response.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct FrfLine {
    /// Frequency, Hz.
    pub freq_hz: f64,
    /// |H|.
    pub gain: f64,
    /// arg H, degrees, unwrapped from 0 at low frequency.
    pub phase_deg: f64,
    /// Magnitude-squared coherence over the periods, 0..1.
    pub coherence: f64,
}

/// The specimen's force model `F = k·x + c·ẋ + m·ẍ + F0` fitted on the measured signals.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize, serde::Deserialize)]
pub struct SpecimenFit {
    /// Stiffness k, kN/mm.
    pub stiffness_kn_per_mm: f64,
    /// Damping c, kN·s/mm.
    pub damping_kn_s_per_mm: f64,
    /// Moving mass m, kN·s²/mm (= 1e6 kg).
    pub mass_kn_s2_per_mm: f64,
    /// R² of the fit.
    pub r2: f64,
}

/// Everything identified.
#[derive(Debug, Clone, PartialEq)]
pub struct Characterization {
    /// Measured frequency response at the excited lines.
    pub frf: Vec<FrfLine>,
    /// The actuator's delay: phase delay at low frequency ([`phase_delay_s`]), s.
    pub delay_s: f64,
    /// The actuator's first-order-plus-dead-time model.
    pub model: Fopdt,
    /// Lead weights, newest tap first.
    pub lead_weights: [f64; LEAD_TAPS],
    /// Lead tap spacing, ticks.
    pub lead_stride: usize,
    /// NRMSE of the lead fit (command predicted from the measured displacement), %.
    pub lead_fit_nrmse_pct: f64,
    /// RMS of `|W·H·e^{jωΔt} − 1|` over the band: how far the compensated actuator is from
    /// following its target exactly, %.
    pub lead_residual_pct: f64,
    /// ATS initial [a0, a1 (s), a2 (s²)] from g and τ.
    pub ats_initial: [f64; 3],
    /// The specimen.
    pub specimen: SpecimenFit,
    /// Smallest coherence over the lines.
    pub min_coherence: f64,
    /// Mean coherence over the lines.
    pub mean_coherence: f64,
    /// Fraction of the lines with coherence ≥ [`COHERENCE_GOOD`].
    pub good_line_fraction: f64,
}

fn refuse(msg: String) -> IdentifyError {
    IdentifyError::Refused(msg)
}

/// H1 and coherence at the excited lines: per period p the DFTs `U_p`, `X_p` at each line;
/// `H = Σ X_p·U_p* / Σ |U_p|²`, `γ² = |Σ X_p·U_p*|² / (Σ|U_p|²·Σ|X_p|²)`. The windows are whole
/// periods of a periodic excitation in steady state, so no window function is needed.
pub fn frf(
    dt_s: f64,
    u: &[f64],
    x: &[f64],
    design: &Design,
) -> Result<Vec<FrfLine>, IdentifyError> {
    let n = design.period_ticks;
    let end = design.window_start + design.periods * n;
    if n == 0 || u.len() < end || x.len() < end {
        return Err(refuse(format!(
            "the record has {} ticks, the analysis needs {end}",
            u.len().min(x.len())
        )));
    }
    let table: Vec<(f64, f64)> = (0..n)
        .map(|t| {
            let a = 2.0 * std::f64::consts::PI * t as f64 / n as f64;
            (a.cos(), a.sin())
        })
        .collect();
    let mut out = Vec::with_capacity(design.lines.len());
    let mut prev_phase = 0.0f64;
    for &k in &design.lines {
        let (mut sxu_re, mut sxu_im, mut suu, mut sxx) = (0.0, 0.0, 0.0, 0.0);
        for p in 0..design.periods {
            let s = design.window_start + p * n;
            let (mut ur, mut ui, mut xr, mut xi) = (0.0, 0.0, 0.0, 0.0);
            for t in 0..n {
                let (c, sn) = table[(k * t) % n];
                ur += u[s + t] * c;
                ui -= u[s + t] * sn;
                xr += x[s + t] * c;
                xi -= x[s + t] * sn;
            }
            // X·U*
            sxu_re += xr * ur + xi * ui;
            sxu_im += xi * ur - xr * ui;
            suu += ur * ur + ui * ui;
            sxx += xr * xr + xi * xi;
        }
        if !(suu > 0.0 && sxx > 0.0) {
            return Err(refuse(format!(
                "no signal at line {k} (command or displacement is flat)"
            )));
        }
        let (hr, hi) = (sxu_re / suu, sxu_im / suu);
        let coherence = (sxu_re * sxu_re + sxu_im * sxu_im) / (suu * sxx);
        // Unwrap: the nearest branch to the previous line's phase (lines are 0.1 Hz apart, far
        // closer than the 1/τ a phase wrap needs).
        let raw = hi.atan2(hr).to_degrees();
        let phase_deg = raw + 360.0 * ((prev_phase - raw) / 360.0).round();
        prev_phase = phase_deg;
        out.push(FrfLine {
            freq_hz: k as f64 / (n as f64 * dt_s),
            gain: (hr * hr + hi * hi).sqrt(),
            phase_deg,
            coherence,
        });
    }
    Ok(out)
}

/// The first-order-plus-dead-time model `H(jω) ≈ g·e^{−jωτ}/(1 + jωT)` of the actuator.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Fopdt {
    /// Low-frequency gain g.
    pub gain: f64,
    /// Dead time τ, s.
    pub dead_time_s: f64,
    /// Lag time constant T, s.
    pub lag_s: f64,
    /// RMS of `|H − model|/|H|` over the lines, %.
    pub fit_error_pct: f64,
}

impl Fopdt {
    /// The model's equivalent delay τ + T, s (its phase slope at zero frequency).
    pub fn delay_s(&self) -> f64 {
        self.dead_time_s + self.lag_s
    }

    /// The model at `f_hz`: (gain, phase deg).
    pub fn response(&self, f_hz: f64) -> (f64, f64) {
        let wt = 2.0 * std::f64::consts::PI * f_hz;
        (
            self.gain / (1.0 + (wt * self.lag_s).powi(2)).sqrt(),
            -(wt * self.dead_time_s + (wt * self.lag_s).atan()).to_degrees(),
        )
    }
}

/// Weight of a line in the model fit: its coherence over its frequency, so that each octave counts
/// alike (the lines are evenly spaced in frequency: unweighted, 20 Hz would outvote 1 Hz 10 to 1,
/// while the controller's signals live mostly at low frequency).
fn weight(l: &FrfLine) -> f64 {
    l.coherence / l.freq_hz.max(1e-9)
}

/// Lines up to this frequency give the low-frequency phase delay, Hz.
pub const DELAY_BAND_HZ: f64 = 1.0;

/// The actuator's delay as a phase delay at low frequency (what `rths plant` reports, from the
/// phase at 0.5 Hz): the least-squares slope through the origin of the measured phase against ω
/// over the lines up to [`DELAY_BAND_HZ`], weighted by coherence, `τ = −Σ w·φ·ω / Σ w·ω²`, s.
pub fn phase_delay_s(frf: &[FrfLine]) -> Result<f64, IdentifyError> {
    let (mut num, mut den) = (0.0, 0.0);
    for l in frf.iter().filter(|l| l.freq_hz <= DELAY_BAND_HZ) {
        let omega = 2.0 * std::f64::consts::PI * l.freq_hz;
        num += l.coherence * l.phase_deg.to_radians() * omega;
        den += l.coherence * omega * omega;
    }
    if den.is_nan() || den <= 0.0 {
        return Err(refuse(format!(
            "no coherent line up to {DELAY_BAND_HZ} Hz to measure the delay"
        )));
    }
    Ok(-num / den)
}

/// Fit [`Fopdt`] to the measured lines, both steps linear least squares, each line weighted by γ²/f
/// (every octave counts alike): the gain from `1/|H|² = (1 + ω²T²)/g² = α + β·ω²` (g = 1/√α, T =
/// √(β/α), T = 0 if β ≤ 0), then the dead time from the phase less the lag's, `φ + atan(ωT) = −ωτ`,
/// a slope through the origin.
pub fn fopdt(frf: &[FrfLine]) -> Result<Fopdt, IdentifyError> {
    let (mut s_w, mut s_x, mut s_xx, mut s_y, mut s_xy) = (0.0, 0.0, 0.0, 0.0, 0.0);
    for l in frf {
        let w = weight(l);
        let x = (2.0 * std::f64::consts::PI * l.freq_hz).powi(2);
        let y = 1.0 / (l.gain * l.gain).max(1e-300);
        s_w += w;
        s_x += w * x;
        s_xx += w * x * x;
        s_y += w * y;
        s_xy += w * x * y;
    }
    let det = s_w * s_xx - s_x * s_x;
    if !(det > 0.0 && s_w > 0.0) {
        return Err(refuse("too few coherent lines to fit the actuator".into()));
    }
    let alpha = (s_xx * s_y - s_x * s_xy) / det;
    let beta = (s_w * s_xy - s_x * s_y) / det;
    if alpha.is_nan() || alpha <= 0.0 {
        return Err(refuse(format!(
            "the measured gain does not fit a first-order lag (1/g² = {alpha:.3e})"
        )));
    }
    let gain = 1.0 / alpha.sqrt();
    let lag_s = if beta > 0.0 {
        (beta / alpha).sqrt()
    } else {
        0.0
    };
    let (mut num, mut den) = (0.0, 0.0);
    for l in frf {
        let omega = 2.0 * std::f64::consts::PI * l.freq_hz;
        let rest = l.phase_deg.to_radians() + (omega * lag_s).atan();
        num += weight(l) * rest * omega;
        den += weight(l) * omega * omega;
    }
    let mut m = Fopdt {
        gain,
        dead_time_s: -num / den,
        lag_s,
        fit_error_pct: 0.0,
    };
    let mut e2 = 0.0;
    for l in frf {
        let (mg, mp) = m.response(l.freq_hz);
        let (hp, mp) = (l.phase_deg.to_radians(), mp.to_radians());
        let (dr, di) = (
            l.gain * hp.cos() - mg * mp.cos(),
            l.gain * hp.sin() - mg * mp.sin(),
        );
        e2 += (dr * dr + di * di) / (l.gain * l.gain).max(1e-300);
    }
    m.fit_error_pct = 100.0 * (e2 / frf.len().max(1) as f64).sqrt();
    Ok(m)
}

/// The lead filter `u(k−1) ≈ Σ_i w_i·x_m(k − i·s)`: least squares (as `rths train lrx` fits it on
/// the simulator, here on the measured displacement) over the ticks `from..to`. The target at row k
/// is the command sent at k−1, the one the displacement at k answers. Returns (weights, NRMSE %).
pub fn lead(
    u: &[f64],
    x: &[f64],
    stride: usize,
    from: usize,
    to: usize,
) -> Result<([f64; LEAD_TAPS], f64), IdentifyError> {
    if !(1..=LEAD_MAX_STRIDE).contains(&stride) {
        return Err(IdentifyError::Setting(format!(
            "lead stride {stride} not in 1..={LEAD_MAX_STRIDE}"
        )));
    }
    let first = from.max((LEAD_TAPS - 1) * stride + 1);
    let to = to.min(u.len()).min(x.len());
    if to <= first + LEAD_TAPS {
        return Err(refuse("too short a record for the lead fit".into()));
    }
    let rows = to - first;
    let xm = DMatrix::from_fn(rows, LEAD_TAPS, |r, i| x[first + r - i * stride]);
    let y = DVector::from_fn(rows, |r, _| u[first + r - 1]);
    let w = crate::machinery::train::lstsq::solve(&xm, &y, 1e-9)
        .map_err(|e| refuse(format!("lead fit: {e}")))?
        .coeffs;
    let fitted = &xm * DVector::from_column_slice(&w);
    let nrmse = metrics::nrmse_pct(fitted.as_slice(), y.as_slice())
        .map_err(|e| refuse(format!("lead fit: {e:?}")))?;
    let mut weights = [0.0; LEAD_TAPS];
    weights.iter_mut().zip(&w).for_each(|(d, s)| *d = *s);
    Ok((weights, nrmse))
}

/// The actuator with the lead in front, `W(ω)·H(ω)·e^{jωΔt}` at every line as (gain, phase deg):
/// `W` the lead's response, and `e^{jωΔt}` because the lead's target is one tick ahead of the
/// command it produces. Ideally 1 and 0°.
pub fn compensated(
    frf: &[FrfLine],
    weights: &[f64; LEAD_TAPS],
    stride: usize,
    dt_s: f64,
) -> Vec<(f64, f64)> {
    frf.iter()
        .map(|l| {
            let (cr, ci) = compensated_at(l, weights, stride, dt_s);
            ((cr * cr + ci * ci).sqrt(), ci.atan2(cr).to_degrees())
        })
        .collect()
}

fn compensated_at(l: &FrfLine, weights: &[f64; LEAD_TAPS], stride: usize, dt_s: f64) -> (f64, f64) {
    let omega = 2.0 * std::f64::consts::PI * l.freq_hz;
    let (mut wr, mut wi) = (0.0, 0.0);
    for (i, w) in weights.iter().enumerate() {
        let a = -omega * (i * stride) as f64 * dt_s;
        wr += w * a.cos();
        wi += w * a.sin();
    }
    let ph = l.phase_deg.to_radians() + omega * dt_s;
    let (hr, hi) = (l.gain * ph.cos(), l.gain * ph.sin());
    (wr * hr - wi * hi, wr * hi + wi * hr)
}

/// RMS of `|W·H·e^{jωΔt} − 1|` over the lines ([`compensated`]), %.
pub fn lead_residual_pct(
    frf: &[FrfLine],
    weights: &[f64; LEAD_TAPS],
    stride: usize,
    dt_s: f64,
) -> f64 {
    let e2: f64 = frf
        .iter()
        .map(|l| {
            let (cr, ci) = compensated_at(l, weights, stride, dt_s);
            (cr - 1.0).powi(2) + ci * ci
        })
        .sum();
    100.0 * (e2 / frf.len().max(1) as f64).sqrt()
}

/// The specimen: `F = k·x + c·ẋ + m·ẍ + F0` by least squares on force and displacement through the
/// same low-pass (the same linear filter on both sides keeps the relation; it removes the sensor
/// noise the derivatives would amplify), derivatives by central differences, over `from..to`.
pub fn specimen(
    x: &[f64],
    f: &[f64],
    dt_s: f64,
    cutoff_hz: f64,
    from: usize,
    to: usize,
) -> Result<SpecimenFit, IdentifyError> {
    let to = to.min(x.len()).min(f.len());
    let p = ButterworthParams::new(4, cutoff_hz, 1.0 / dt_s)
        .map_err(|e| IdentifyError::Setting(format!("stiffness filter: {e:?}")))?;
    let (mut bx, mut bf) = (Butterworth::new(p), Butterworth::new(p));
    let mut xf = Vec::with_capacity(to);
    let mut ff = Vec::with_capacity(to);
    for k in 0..to {
        xf.push(
            bx.step(x[k])
                .map_err(|_| refuse(format!("displacement not finite at tick {k}")))?,
        );
        ff.push(
            bf.step(f[k])
                .map_err(|_| refuse(format!("force not finite at tick {k}")))?,
        );
    }
    // Skip the filter's transient: start at least a second into the record.
    let first = from.max((1.0 / dt_s) as usize).max(1);
    if to < first + 8 {
        return Err(refuse("too short a record for the stiffness fit".into()));
    }
    let rows = to - 1 - first;
    let a = DMatrix::from_fn(rows, 4, |r, j| {
        let k = first + r;
        match j {
            0 => xf[k],
            1 => (xf[k + 1] - xf[k - 1]) / (2.0 * dt_s),
            2 => (xf[k + 1] - 2.0 * xf[k] + xf[k - 1]) / (dt_s * dt_s),
            _ => 1.0,
        }
    });
    let y = DVector::from_fn(rows, |r, _| ff[first + r]);
    let mean = y.mean();
    let ss_tot: f64 = y.iter().map(|v| (v - mean).powi(2)).sum();
    if ss_tot.is_nan() || ss_tot <= 0.0 {
        return Err(refuse(
            "the force reading does not vary: dead or stuck load cell".into(),
        ));
    }
    let th = crate::machinery::train::lstsq::solve(&a, &y, 1e-12)
        .map_err(|e| refuse(format!("stiffness fit: {e}")))?
        .coeffs;
    let fitted = &a * DVector::from_column_slice(&th);
    let ss_res: f64 = fitted
        .iter()
        .zip(y.iter())
        .map(|(a, b)| (a - b).powi(2))
        .sum();
    Ok(SpecimenFit {
        stiffness_kn_per_mm: th[0],
        damping_kn_s_per_mm: th[1],
        mass_kn_s2_per_mm: th[2],
        r2: 1.0 - ss_res / ss_tot,
    })
}

/// Identify everything from the measured signals, then check it; a failed check is a refusal
/// ([`IdentifyError::Refused`]) with the reason.
pub fn identify(sig: Signals<'_>, design: &Design) -> Result<Characterization, IdentifyError> {
    let (from, to) = (
        design.window_start,
        design.window_start + design.periods * design.period_ticks,
    );
    for (name, v) in [
        ("command", sig.command_mm),
        ("displacement", sig.measured_mm),
        ("force", sig.force_kn),
    ] {
        let w = v.get(from..to).ok_or_else(|| {
            refuse(format!(
                "the record has {} ticks, the analysis needs {to}",
                v.len()
            ))
        })?;
        let bad = w.iter().filter(|x| !x.is_finite()).count();
        if bad > 0 {
            return Err(refuse(format!(
                "{bad} {name} samples missing or not finite in the analysed periods (sensor dropout?)"
            )));
        }
    }
    let frf = frf(sig.dt_s, sig.command_mm, sig.measured_mm, design)?;
    let good = frf.iter().filter(|l| l.coherence >= COHERENCE_GOOD).count();
    let good_line_fraction = good as f64 / frf.len().max(1) as f64;
    let min_coherence = frf.iter().map(|l| l.coherence).fold(1.0, f64::min);
    let mean_coherence = frf.iter().map(|l| l.coherence).sum::<f64>() / frf.len().max(1) as f64;
    if good_line_fraction < MIN_GOOD_LINE_FRACTION {
        return Err(refuse(format!(
            "too little excitation for the noise: only {:.0}% of the lines have coherence ≥ \
             {COHERENCE_GOOD} (need {:.0}%; mean {mean_coherence:.3}): raise --amplitude-mm",
            100.0 * good_line_fraction,
            100.0 * MIN_GOOD_LINE_FRACTION
        )));
    }
    let model = fopdt(&frf)?;
    let (gain, delay_s) = (model.gain, phase_delay_s(&frf)?);
    if !(GAIN_RANGE.0..=GAIN_RANGE.1).contains(&gain) {
        return Err(refuse(format!(
            "actuator gain {gain:.3} outside the plausible {GAIN_RANGE:?}"
        )));
    }
    let delay_ms = delay_s * 1e3;
    if !(delay_ms > DELAY_RANGE_MS.0 && delay_ms < DELAY_RANGE_MS.1) {
        return Err(refuse(format!(
            "actuator delay {delay_ms:.2} ms outside the plausible {DELAY_RANGE_MS:?} ms"
        )));
    }
    let (lead_weights, lead_fit_nrmse_pct) = lead(
        sig.command_mm,
        sig.measured_mm,
        design.lead_stride,
        from,
        to,
    )?;
    if lead_fit_nrmse_pct.is_nan() || lead_fit_nrmse_pct > MAX_LEAD_NRMSE_PCT {
        return Err(refuse(format!(
            "lead fit NRMSE {lead_fit_nrmse_pct:.2}% above {MAX_LEAD_NRMSE_PCT}%"
        )));
    }
    let lead_residual_pct = lead_residual_pct(&frf, &lead_weights, design.lead_stride, sig.dt_s);
    let specimen = specimen(
        sig.measured_mm,
        sig.force_kn,
        sig.dt_s,
        design.stiffness_cutoff_hz,
        from,
        to,
    )?;
    if !(specimen.r2 >= MIN_STIFFNESS_R2 && specimen.stiffness_kn_per_mm > 0.0) {
        return Err(refuse(format!(
            "the force does not follow the displacement (R² {:.3} < {MIN_STIFFNESS_R2}, k {:.4} \
             kN/mm): load cell or specimen fault",
            specimen.r2, specimen.stiffness_kn_per_mm
        )));
    }
    // The inverse of g·e^{−sτ}/(1 + sT) is (1/g)(1 + s(τ+T) + s²(τ²/2 + τT) + …) (the ATS
    // law's form); the compensator's target is one tick ahead of the command it produces, so it
    // must supply the dead time less one tick.
    let (tau, lag) = ((model.dead_time_s - sig.dt_s).max(0.0), model.lag_s);
    let ats_initial = [
        1.0 / gain,
        (tau + lag) / gain,
        (tau * tau / 2.0 + tau * lag) / gain,
    ];
    Ok(Characterization {
        frf,
        delay_s,
        model,
        lead_weights,
        lead_stride: design.lead_stride,
        lead_fit_nrmse_pct,
        lead_residual_pct,
        ats_initial,
        specimen,
        min_coherence,
        mean_coherence,
        good_line_fraction,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::machinery::identify::excitation::{generate, ExcitationConfig};
    use rths_core::params::DT_S;

    /// A pure delay of `d` ticks and gain `g` on the default excitation: x(k) = g·u(k − d).
    fn delayed(g: f64, d: usize) -> (Vec<f64>, Vec<f64>, Design) {
        let e = generate(&ExcitationConfig::new(DT_S)).unwrap();
        let u = e.command_mm.clone();
        let x: Vec<f64> = (0..u.len())
            .map(|k| if k >= d { g * u[k - d] } else { 0.0 })
            .collect();
        let design = Design {
            window_start: e.window_start,
            period_ticks: e.period_ticks,
            periods: e.config.periods,
            lines: e.lines.clone(),
            lead_stride: 8,
            stiffness_cutoff_hz: 30.0,
        };
        (u, x, design)
    }

    #[test]
    fn h1_of_a_pure_delay_is_exact() {
        let (u, x, design) = delayed(0.9, 30);
        let frf = frf(DT_S, &u, &x, &design).unwrap();
        for l in &frf {
            assert!((l.gain - 0.9).abs() < 1e-9, "{l:?}");
            let want = -360.0 * l.freq_hz * 30.0 * DT_S;
            assert!((l.phase_deg - want).abs() < 1e-6, "{l:?} {want}");
            assert!((l.coherence - 1.0).abs() < 1e-9);
        }
        assert!((phase_delay_s(&frf).unwrap() - 30.0 * DT_S).abs() < 1e-12);
        let m = fopdt(&frf).unwrap();
        assert!((m.gain - 0.9).abs() < 1e-9 && m.lag_s.abs() < 1e-6, "{m:?}");
        assert!((m.dead_time_s - 30.0 * DT_S).abs() < 1e-9 && m.fit_error_pct < 1e-6);
    }

    #[test]
    fn fopdt_recovers_its_own_response() {
        let truth = Fopdt {
            gain: 1.02,
            dead_time_s: 0.004,
            lag_s: 0.011,
            fit_error_pct: 0.0,
        };
        let frf: Vec<FrfLine> = (1..=200)
            .map(|k| {
                let f = 0.1 * k as f64;
                let (gain, phase_deg) = truth.response(f);
                FrfLine {
                    freq_hz: f,
                    gain,
                    phase_deg,
                    coherence: 1.0,
                }
            })
            .collect();
        let m = fopdt(&frf).unwrap();
        assert!((m.gain - 1.02).abs() < 1e-9, "{m:?}");
        assert!((m.lag_s - 0.011).abs() < 1e-9 && (m.dead_time_s - 0.004).abs() < 1e-9);
    }

    #[test]
    fn the_lead_inverts_a_one_tick_delay() {
        // One tick of delay, the least a sampled actuator has: u(k−1) = x(k)/g exactly.
        let (u, x, design) = delayed(0.8, 1);
        let (w, nrmse) = lead(&u, &x, 8, design.window_start, u.len()).unwrap();
        assert!(
            (w[0] - 1.25).abs() < 1e-9 && w[1..].iter().all(|v| v.abs() < 1e-9),
            "{w:?}"
        );
        assert!(nrmse < 1e-9);
        let frf = frf(DT_S, &u, &x, &design).unwrap();
        assert!(lead_residual_pct(&frf, &w, 8, DT_S) < 1e-6);
    }

    #[test]
    fn the_specimen_fit_recovers_stiffness_damping_and_mass() {
        let (u, _, design) = delayed(1.0, 0);
        let (k, c, m) = (1.2, 1e-4, 3e-5);
        let x = u.clone();
        let f: Vec<f64> = (0..x.len())
            .map(|i| {
                let xm = if i > 0 { x[i - 1] } else { 0.0 };
                let xp = x.get(i + 1).copied().unwrap_or(x[i]);
                k * x[i] + c * (xp - xm) / (2.0 * DT_S) + m * (xp - 2.0 * x[i] + xm) / (DT_S * DT_S)
            })
            .collect();
        let end = design.window_start + design.periods * design.period_ticks;
        let s = specimen(&x, &f, DT_S, 30.0, design.window_start, end).unwrap();
        assert!((s.stiffness_kn_per_mm / k - 1.0).abs() < 1e-3, "{s:?}");
        assert!(s.r2 > 0.9999, "{s:?}");
    }
}
