//! The hysteresis plot: each story's force against its drift (plotters, the embedded font of
//! [`crate::machinery::plot`]).

use std::path::Path;

use plotters::prelude::*;

use super::NlResponse;

/// Draw one panel per story (force–drift) into the PNG `path`, under `title`.
pub fn hysteresis(path: &Path, title: &str, r: &NlResponse) -> anyhow::Result<()> {
    crate::machinery::plot::init_fonts()?;
    let n = r.story_drift_mm.len();
    if n == 0 {
        anyhow::bail!("nothing to plot");
    }
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plotting {}: {e}", path.display());
    let width = 520 * n as u32;
    let root = crate::machinery::plot::bitmap(path, (width.max(600), 560))?;
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(title, ("sans-serif", 22))
        .map_err(|e| err(&e))?;
    let areas = root.split_evenly((1, n));
    for (j, ((d, f), area)) in r
        .story_drift_mm
        .iter()
        .zip(&r.story_force_kn)
        .zip(&areas)
        .enumerate()
    {
        let span = |v: &[f64]| {
            let m = v.iter().fold(0.0_f64, |m, x| m.max(x.abs())).max(1e-9) * 1.1;
            -m..m
        };
        let mut chart = ChartBuilder::on(area)
            .margin(12)
            .caption(format!("story {}", j + 1), ("sans-serif", 18))
            .x_label_area_size(40)
            .y_label_area_size(70)
            .build_cartesian_2d(span(d), span(f))
            .map_err(|e| err(&e))?;
        chart
            .configure_mesh()
            .x_desc("Story drift (mm)")
            .y_desc("Story force (kN)")
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 16))
            .light_line_style(WHITE.mix(0.0))
            .draw()
            .map_err(|e| err(&e))?;
        chart
            .draw_series(LineSeries::new(
                d.iter().zip(f).map(|(x, y)| (*x, *y)),
                BLUE.stroke_width(1),
            ))
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
