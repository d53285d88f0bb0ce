//! The rig file's figure: measured and identified frequency response (gain, phase) and coherence
//! against log frequency, in the project's plotting style (`crate::machinery::plot`).

use std::path::Path;

use plotters::prelude::*;

use plotters::coord::Shift;

use super::estimate::{Fopdt, FrfLine};

const MEASURED: RGBColor = RGBColor(0, 114, 178);
const IDENTIFIED: RGBColor = RGBColor(213, 94, 0);
const WITH_LEAD: RGBColor = RGBColor(0, 158, 115);

/// One frequency-response panel: the measured lines, the identified model and the actuator with its
/// identified lead.
struct Panel {
    /// Frequency, Hz (drawn on a log scale).
    x_range: std::ops::Range<f64>,
    y_range: std::ops::Range<f64>,
    y_desc: &'static str,
    measured: Vec<(f64, f64)>,
    model: Vec<(f64, f64)>,
    model_label: String,
    compensated: Vec<(f64, f64)>,
}

fn response_panel(
    area: &DrawingArea<BitMapBackend<'_>, Shift>,
    p: Panel,
    err: &dyn Fn(&dyn std::fmt::Display) -> anyhow::Error,
) -> anyhow::Result<()> {
    let mut ch = ChartBuilder::on(area)
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(p.x_range.log_scale(), p.y_range)
        .map_err(|e| err(&e))?;
    ch.configure_mesh()
        .y_desc(p.y_desc)
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    ch.draw_series(
        p.measured
            .iter()
            .map(|&xy| Circle::new(xy, 2, MEASURED.filled())),
    )
    .map_err(|e| err(&e))?
    .label("measured (H1)")
    .legend(move |(x, y)| Circle::new((x + 10, y), 3, MEASURED.filled()));
    ch.draw_series(LineSeries::new(p.model, IDENTIFIED.stroke_width(2)))
        .map_err(|e| err(&e))?
        .label(p.model_label)
        .legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], IDENTIFIED.stroke_width(2))
        });
    ch.draw_series(LineSeries::new(p.compensated, WITH_LEAD.stroke_width(2)))
        .map_err(|e| err(&e))?
        .label("with identified lead")
        .legend(move |(x, y)| {
            PathElement::new(vec![(x, y), (x + 20, y)], WITH_LEAD.stroke_width(2))
        });
    ch.configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| err(&e))?;
    Ok(())
}

/// Gain, phase and coherence of the measured lines, the identified delay and model `g·e^{−jωτ}/(1 +
/// jωT)`, and the actuator with its identified lead (`W·H·e^{jωΔt}`, ideally 1 and 0°).
pub fn draw(
    path: &Path,
    title: &str,
    frf: &[FrfLine],
    delay_s: f64,
    model: &Fopdt,
    compensated: &[(f64, f64)],
) -> anyhow::Result<()> {
    crate::machinery::plot::init_fonts()?;
    if frf.is_empty() {
        anyhow::bail!("nothing to plot");
    }
    let f_lo = frf.iter().map(|l| l.freq_hz).fold(f64::INFINITY, f64::min);
    let f_hi = frf.iter().map(|l| l.freq_hz).fold(0.0, f64::max);
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plotting {}: {e}", path.display());
    let root = crate::machinery::plot::bitmap(path, (1000, 900))?;
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| err(&e))?;
    let areas = root.split_evenly((3, 1));
    let blue = MEASURED;
    let model_gain = |f: f64| model.response(f).0;
    let model_phase = |f: f64| model.response(f).1;
    let gain = model.gain;
    let x_range = f_lo * 0.9..f_hi * 1.1;

    let measured_gain: Vec<_> = frf.iter().map(|l| (l.freq_hz, l.gain)).collect();
    let g_max = measured_gain
        .iter()
        .map(|p| p.1)
        .chain(compensated.iter().map(|c| c.0))
        .fold(gain, f64::max)
        .max(1.0);
    let g_min = measured_gain
        .iter()
        .map(|p| p.1)
        .chain(compensated.iter().map(|c| c.0))
        .fold(gain, f64::min);
    response_panel(
        &areas[0],
        Panel {
            x_range: x_range.clone(),
            y_range: (g_min - 0.05)..(g_max + 0.05),
            y_desc: "gain |x/u|",
            measured: measured_gain,
            model: frf
                .iter()
                .map(|l| (l.freq_hz, model_gain(l.freq_hz)))
                .collect(),
            model_label: format!("identified g = {gain:.4}, T = {:.2} ms", model.lag_s * 1e3),
            compensated: frf
                .iter()
                .zip(compensated)
                .map(|(l, c)| (l.freq_hz, c.0))
                .collect(),
        },
        &err,
    )?;
    let p_min = frf
        .iter()
        .map(|l| l.phase_deg.min(model_phase(l.freq_hz)))
        .fold(0.0, f64::min);
    response_panel(
        &areas[1],
        Panel {
            x_range: x_range.clone(),
            y_range: (p_min - 10.0)..20.0,
            y_desc: "phase (deg)",
            measured: frf.iter().map(|l| (l.freq_hz, l.phase_deg)).collect(),
            model: frf
                .iter()
                .map(|l| (l.freq_hz, model_phase(l.freq_hz)))
                .collect(),
            model_label: format!(
                "identified: delay {:.2} ms (≤ 1 Hz); model dead time {:.2} ms",
                delay_s * 1e3,
                model.dead_time_s * 1e3
            ),
            compensated: frf
                .iter()
                .zip(compensated)
                .map(|(l, c)| (l.freq_hz, c.1))
                .collect(),
        },
        &err,
    )?;

    // Coherence.
    let c_min = frf.iter().map(|l| l.coherence).fold(1.0, f64::min);
    let mut ch = ChartBuilder::on(&areas[2])
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range.log_scale(), (c_min.min(0.9) - 0.02)..1.01)
        .map_err(|e| err(&e))?;
    ch.configure_mesh()
        .x_desc("frequency (Hz)")
        .y_desc("coherence")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    ch.draw_series(
        frf.iter()
            .map(|l| Circle::new((l.freq_hz, l.coherence), 2, blue.filled())),
    )
    .map_err(|e| err(&e))?;
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
