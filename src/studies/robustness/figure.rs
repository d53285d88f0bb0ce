//! `robustness.png`: the measured NRMSE of every run, per preset (one panel each), specimen case
//! and controller (log scale), with each row's median and the goal lines at 1 % and 2.5 %.

use std::path::Path;

use plotters::prelude::*;

use rths_core::metrics::median;

use super::{case_label, cases, goals, Robustness, CONTROLLERS};

/// Y range of the panels, % (log scale); the bottom goes a decade lower when a run needs it (an
/// adaptive metamodel reaches 0.05 %); runs outside are drawn at the edge.
const Y_MIN_PCT: f64 = 0.05;
const Y_FLOOR_PCT: f64 = 0.001;
const Y_MAX_PCT: f64 = 100.0;
/// Where an unstable run is drawn (a cross near the top).
const UNSTABLE_AT_PCT: f64 = 70.0;

/// Horizontal offset of each controller within its case, and the spread of its points.
const OFFSET: f64 = 0.27;
const JITTER: f64 = 0.09;

/// Draw the figure.
pub fn draw(r: &Robustness, path: &Path) -> anyhow::Result<()> {
    crate::machinery::plot::init_fonts()?;
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plotting {}: {e}", path.display());
    let labels: Vec<String> = cases().into_iter().map(|(s, f)| case_label(s, f)).collect();
    let n = labels.len();
    let panels = r.presets.len().max(1);
    let smallest = r
        .jobs
        .iter()
        .flat_map(|j| j.runs.iter())
        .filter_map(|x| x.nrmse_measured_pct)
        .filter(|y| *y > 0.0)
        .fold(Y_MIN_PCT, f64::min);
    let y_min = if smallest < Y_MIN_PCT {
        10f64.powf(smallest.log10().floor()).max(Y_FLOOR_PCT)
    } else {
        Y_MIN_PCT
    };
    let root = crate::machinery::plot::bitmap(path, (1200, 120 + 420 * panels as u32))?;
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(
            &format!(
                "Robustness: measured NRMSE vs the fair reference, {} draws × {} records per row \
                 (bar: median; ×: unstable; red: {} % / {} % goals)",
                r.draws,
                r.records.len(),
                goals::NRMSE_MEDIAN_PCT,
                goals::NRMSE_MAX_PCT
            ),
            ("sans-serif", 18),
        )
        .map_err(|e| err(&e))?;
    let colours = [
        RGBColor(213, 94, 0),
        RGBColor(0, 114, 178),
        RGBColor(0, 158, 115),
    ];
    for (preset, area) in r.presets.iter().zip(root.split_evenly((panels, 1))) {
        let mut chart = ChartBuilder::on(&area)
            .caption(format!("preset {preset}"), ("sans-serif", 17))
            .margin(15)
            .x_label_area_size(35)
            .y_label_area_size(70)
            .build_cartesian_2d(-0.5..(n as f64 - 0.5), (y_min..Y_MAX_PCT).log_scale())
            .map_err(|e| err(&e))?;
        let fmt_x = |v: &f64| {
            let i = v.round();
            if (v - i).abs() < 1e-6 && i >= 0.0 {
                labels.get(i as usize).cloned().unwrap_or_default()
            } else {
                String::new()
            }
        };
        chart
            .configure_mesh()
            .x_labels(n)
            .x_label_formatter(&fmt_x)
            .y_desc("NRMSE measured (%)")
            .label_style(("sans-serif", 14))
            .axis_desc_style(("sans-serif", 15))
            .draw()
            .map_err(|e| err(&e))?;
        for goal in [goals::NRMSE_MEDIAN_PCT, goals::NRMSE_MAX_PCT] {
            chart
                .draw_series(LineSeries::new(
                    [(-0.5, goal), (n as f64 - 0.5, goal)],
                    RGBColor(200, 0, 0).mix(0.5).stroke_width(2),
                ))
                .map_err(|e| err(&e))?;
        }
        for (k, id) in CONTROLLERS.iter().enumerate() {
            let colour = colours[k % colours.len()];
            let name = id.to_string();
            let mut stable_pts = Vec::new();
            let mut unstable_pts = Vec::new();
            let mut medians = Vec::new();
            for (ci, label) in labels.iter().enumerate() {
                let x0 = ci as f64 + (k as f64 - 1.0) * OFFSET;
                let mut ys = Vec::new();
                let runs = r
                    .jobs
                    .iter()
                    .filter(|j| &j.preset == preset && &j.case == label)
                    .flat_map(|j| j.runs.iter())
                    .filter(|x| x.controller == name);
                for (i, run) in runs.enumerate() {
                    // A deterministic spread (golden-ratio sequence) so equal values stay visible.
                    let x = x0 + JITTER * (2.0 * ((i as f64 * 0.618_034) % 1.0) - 1.0);
                    match (run.stable, run.nrmse_measured_pct) {
                        (true, Some(y)) => {
                            ys.push(y);
                            stable_pts.push((x, y.clamp(y_min, Y_MAX_PCT)));
                        }
                        _ => unstable_pts.push((x, UNSTABLE_AT_PCT)),
                    }
                }
                if let Some(m) = median(&mut ys) {
                    medians.push((x0, m.clamp(y_min, Y_MAX_PCT)));
                }
            }
            chart
                .draw_series(
                    stable_pts
                        .iter()
                        .map(|p| Circle::new(*p, 2, colour.mix(0.55).filled())),
                )
                .map_err(|e| err(&e))?
                .label(if k == 2 {
                    format!("{name} (identified)")
                } else {
                    name.clone()
                })
                .legend(move |(x, y)| Circle::new((x + 10, y), 4, colour.filled()));
            chart
                .draw_series(
                    unstable_pts
                        .iter()
                        .map(|p| Cross::new(*p, 5, colour.stroke_width(2))),
                )
                .map_err(|e| err(&e))?;
            for (x, m) in medians {
                chart
                    .draw_series(LineSeries::new(
                        [(x - 1.2 * JITTER, m), (x + 1.2 * JITTER, m)],
                        BLACK.stroke_width(3),
                    ))
                    .map_err(|e| err(&e))?;
            }
        }
        chart
            .configure_series_labels()
            .position(SeriesLabelPosition::UpperRight)
            .label_font(("sans-serif", 14))
            .background_style(WHITE.mix(0.85))
            .border_style(BLACK)
            .draw()
            .map_err(|e| err(&e))?;
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}
