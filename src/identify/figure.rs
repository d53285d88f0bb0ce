//! The rig file's figure: measured and identified frequency response (gain, phase) and coherence
//! against log frequency, in the project's plotting style (`crate::plot`).

use std::path::Path;

use plotters::prelude::*;

use super::estimate::{Fopdt, FrfLine};

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
    crate::plot::init_fonts()?;
    if frf.is_empty() {
        anyhow::bail!("nothing to plot");
    }
    let f_lo = frf.iter().map(|l| l.freq_hz).fold(f64::INFINITY, f64::min);
    let f_hi = frf.iter().map(|l| l.freq_hz).fold(0.0, f64::max);
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plotting {}: {e}", path.display());
    let root = BitMapBackend::new(path, (1000, 900)).into_drawing_area();
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| err(&e))?;
    let areas = root.split_evenly((3, 1));
    let blue = RGBColor(0, 114, 178);
    let orange = RGBColor(213, 94, 0);
    let green = RGBColor(0, 158, 115);
    let model_gain = |f: f64| model.response(f).0;
    let model_phase = |f: f64| model.response(f).1;
    let gain = model.gain;
    let x_range = (f_lo * 0.9..f_hi * 1.1).log_scale();

    // Gain.
    let g_max = frf
        .iter()
        .map(|l| l.gain)
        .chain(compensated.iter().map(|c| c.0))
        .fold(gain, f64::max)
        .max(1.0);
    let g_min = frf
        .iter()
        .map(|l| l.gain)
        .chain(compensated.iter().map(|c| c.0))
        .fold(gain, f64::min);
    let mut ch = ChartBuilder::on(&areas[0])
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range.clone(), (g_min - 0.05)..(g_max + 0.05))
        .map_err(|e| err(&e))?;
    ch.configure_mesh()
        .y_desc("gain |x/u|")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    ch.draw_series(
        frf.iter()
            .map(|l| Circle::new((l.freq_hz, l.gain), 2, blue.filled())),
    )
    .map_err(|e| err(&e))?
    .label("measured (H1)")
    .legend(move |(x, y)| Circle::new((x + 10, y), 3, blue.filled()));
    ch.draw_series(LineSeries::new(
        frf.iter().map(|l| (l.freq_hz, model_gain(l.freq_hz))),
        orange.stroke_width(2),
    ))
    .map_err(|e| err(&e))?
    .label(format!(
        "identified g = {gain:.4}, T = {:.2} ms",
        model.lag_s * 1e3
    ))
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], orange.stroke_width(2)));
    ch.draw_series(LineSeries::new(
        frf.iter().zip(compensated).map(|(l, c)| (l.freq_hz, c.0)),
        green.stroke_width(2),
    ))
    .map_err(|e| err(&e))?
    .label("with identified lead")
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], green.stroke_width(2)));
    ch.configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| err(&e))?;

    // Phase.
    let p_min = frf
        .iter()
        .map(|l| l.phase_deg.min(model_phase(l.freq_hz)))
        .fold(0.0, f64::min);
    let mut ch = ChartBuilder::on(&areas[1])
        .margin(10)
        .x_label_area_size(30)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range.clone(), (p_min - 10.0)..20.0)
        .map_err(|e| err(&e))?;
    ch.configure_mesh()
        .y_desc("phase (deg)")
        .label_style(("sans-serif", 14))
        .draw()
        .map_err(|e| err(&e))?;
    ch.draw_series(
        frf.iter()
            .map(|l| Circle::new((l.freq_hz, l.phase_deg), 2, blue.filled())),
    )
    .map_err(|e| err(&e))?
    .label("measured (H1)")
    .legend(move |(x, y)| Circle::new((x + 10, y), 3, blue.filled()));
    ch.draw_series(LineSeries::new(
        frf.iter().map(|l| (l.freq_hz, model_phase(l.freq_hz))),
        orange.stroke_width(2),
    ))
    .map_err(|e| err(&e))?
    .label(format!(
        "identified: delay {:.2} ms (≤ 1 Hz); model dead time {:.2} ms",
        delay_s * 1e3,
        model.dead_time_s * 1e3
    ))
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], orange.stroke_width(2)));
    ch.draw_series(LineSeries::new(
        frf.iter().zip(compensated).map(|(l, c)| (l.freq_hz, c.1)),
        green.stroke_width(2),
    ))
    .map_err(|e| err(&e))?
    .label("with identified lead")
    .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 20, y)], green.stroke_width(2)));
    ch.configure_series_labels()
        .position(SeriesLabelPosition::LowerLeft)
        .label_font(("sans-serif", 14))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()
        .map_err(|e| err(&e))?;

    // Coherence.
    let c_min = frf.iter().map(|l| l.coherence).fold(1.0, f64::min);
    let mut ch = ChartBuilder::on(&areas[2])
        .margin(10)
        .x_label_area_size(40)
        .y_label_area_size(70)
        .build_cartesian_2d(x_range, (c_min.min(0.9) - 0.02)..1.01)
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
