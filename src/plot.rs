//! Shared plotting setup: plotters renders text with an embedded font (DejaVu Sans, see
//! `assets/DejaVuSans.LICENSE`) so figures render the same on any machine, with no system fonts.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::{BitMapBackend, DrawingArea, IntoDrawingArea};
use plotters::style::FontStyle;

static FONT: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// Register the embedded font with plotters (idempotent). Call before drawing any text.
pub fn init_fonts() -> anyhow::Result<()> {
    static DONE: OnceLock<Result<(), String>> = OnceLock::new();
    DONE.get_or_init(|| {
        for style in [
            FontStyle::Normal,
            FontStyle::Bold,
            FontStyle::Italic,
            FontStyle::Oblique,
        ] {
            plotters::style::register_font("sans-serif", style, FONT)
                .map_err(|_| "embedded font is not a valid TrueType font".to_string())?;
        }
        Ok(())
    })
    .clone()
    .map_err(anyhow::Error::msg)
}

/// The drawing area of a `size`-pixel PNG at `path`, once [`crate::output::writable_file`] says
/// the file can be written (plotters finds out only when the figure is done).
pub fn bitmap(
    path: &Path,
    size: (u32, u32),
) -> anyhow::Result<DrawingArea<BitMapBackend<'_>, Shift>> {
    crate::output::writable_file(path)?;
    Ok(BitMapBackend::new(path, size).into_drawing_area())
}

/// One curve of a [`Panel`]: `values[k]` at `time_s[k]` (the shorter length wins; non-finite
/// points are skipped).
#[derive(Debug, Clone)]
pub struct Series<'a> {
    /// Legend text; an empty label keeps the curve out of the legend.
    pub label: String,
    /// Time, s.
    pub time_s: &'a [f64],
    /// Values, in the unit of the panel's y label.
    pub values: &'a [f64],
}

/// One stacked panel of [`stacked_time_series`]: a y-axis label (with its unit) and one or more
/// curves sharing it (e.g. reference and measured), drawn in the order given.
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// Y-axis label with unit, e.g. `"Brace disp. (mm)"`.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series<'a>>,
}

impl<'a> Panel<'a> {
    /// A panel with a single unlabelled curve.
    pub fn single(y_label: impl Into<String>, time_s: &'a [f64], values: &'a [f64]) -> Self {
        Self {
            y_label: y_label.into(),
            series: vec![Series {
                label: String::new(),
                time_s,
                values,
            }],
        }
    }

    /// Add a labelled curve (builder style).
    pub fn with(mut self, label: impl Into<String>, time_s: &'a [f64], values: &'a [f64]) -> Self {
        self.series.push(Series {
            label: label.into(),
            time_s,
            values,
        });
        self
    }
}

/// Curve colours, in series order (colour-blind-safe Okabe–Ito set, then black).
const PALETTE: [plotters::style::RGBColor; 5] = [
    plotters::style::RGBColor(0, 114, 178),
    plotters::style::RGBColor(213, 94, 0),
    plotters::style::RGBColor(0, 158, 115),
    plotters::style::RGBColor(204, 121, 167),
    plotters::style::RGBColor(0, 0, 0),
];

/// Points worth drawing: finite ones, and for long series only the min and max of each of ~2000
/// buckets (in time order), which keeps the envelope a bitmap can show at a fraction of the cost.
fn drawable(time_s: &[f64], values: &[f64]) -> Vec<(f64, f64)> {
    let pts: Vec<(f64, f64)> = time_s
        .iter()
        .zip(values)
        .map(|(t, v)| (*t, *v))
        .filter(|(t, v)| t.is_finite() && v.is_finite())
        .collect();
    const BUCKETS: usize = 2000;
    if pts.len() <= 2 * BUCKETS {
        return pts;
    }
    let size = pts.len().div_ceil(BUCKETS);
    let mut out = Vec::with_capacity(2 * BUCKETS + 2);
    for chunk in pts.chunks(size) {
        let lo = chunk
            .iter()
            .enumerate()
            .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1));
        let hi = chunk
            .iter()
            .enumerate()
            .max_by(|a, b| a.1 .1.total_cmp(&b.1 .1));
        if let (Some((il, l)), Some((ih, h))) = (lo, hi) {
            if il <= ih {
                out.extend([*l, *h]);
            } else {
                out.extend([*h, *l]);
            }
        }
    }
    out
}

/// A range that contains every value, padded 5%, never empty.
fn padded_range(lo: f64, hi: f64) -> std::ops::Range<f64> {
    if !(lo.is_finite() && hi.is_finite()) {
        return -1.0..1.0;
    }
    let span = hi - lo;
    let pad = if span > 0.0 {
        0.05 * span
    } else {
        lo.abs().max(1.0) * 0.05
    };
    (lo - pad)..(hi + pad)
}

/// Tick label with as many decimals as a span of `span` needs, and no "-0".
fn tick_label(v: f64, span: f64) -> String {
    let decimals = if span >= 50.0 {
        0
    } else if span >= 5.0 {
        1
    } else if span >= 0.5 {
        2
    } else {
        3
    };
    let s = format!("{v:.decimals$}");
    if s.trim_start_matches('-')
        .chars()
        .all(|c| c == '0' || c == '.')
    {
        s.trim_start_matches('-').to_string()
    } else {
        s
    }
}

/// Draw `panels` stacked vertically over a shared time axis (s) into the PNG `path`, under `title`.
/// Every panel gets its own y range; a legend appears in panels with labelled curves.
pub fn stacked_time_series(path: &Path, title: &str, panels: &[Panel<'_>]) -> anyhow::Result<()> {
    use plotters::prelude::*;
    init_fonts()?;
    if panels.is_empty() {
        anyhow::bail!("nothing to plot");
    }
    let data: Vec<Vec<Vec<(f64, f64)>>> = panels
        .iter()
        .map(|p| {
            p.series
                .iter()
                .map(|s| drawable(s.time_s, s.values))
                .collect()
        })
        .collect();
    let all = || data.iter().flatten().flatten();
    let (t0, t1) = all().fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (t, _)| {
        (a.min(*t), b.max(*t))
    });
    if !t0.is_finite() {
        anyhow::bail!("no finite points to plot");
    }
    let t_range = if t1 > t0 { t0..t1 } else { t0..t0 + 1.0 };

    const PANEL_H: u32 = 260;
    const TITLE_H: u32 = 50;
    let height = TITLE_H + PANEL_H * panels.len() as u32;
    let err = |e: &dyn std::fmt::Display| anyhow::anyhow!("plotting {}: {e}", path.display());
    let root = bitmap(path, (1200, height))?;
    root.fill(&WHITE).map_err(|e| err(&e))?;
    let root = root
        .titled(title, ("sans-serif", 24))
        .map_err(|e| err(&e))?;
    let areas = root.split_evenly((panels.len(), 1));
    let last = panels.len() - 1;
    for (i, ((panel, series), area)) in panels.iter().zip(&data).zip(&areas).enumerate() {
        let (lo, hi) = series
            .iter()
            .flatten()
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (_, v)| {
                (a.min(*v), b.max(*v))
            });
        let y_range = padded_range(lo, hi);
        let y_span = y_range.end - y_range.start;
        let t_span = t_range.end - t_range.start;
        let y_fmt = move |v: &f64| tick_label(*v, y_span);
        let t_fmt = move |v: &f64| tick_label(*v, t_span);
        let mut chart = ChartBuilder::on(area)
            .margin_left(10)
            .margin_right(25)
            .margin_top(8)
            .x_label_area_size(if i == last { 45 } else { 22 })
            .y_label_area_size(85)
            .build_cartesian_2d(t_range.clone(), y_range)
            .map_err(|e| err(&e))?;
        let mut mesh = chart.configure_mesh();
        mesh.y_desc(panel.y_label.as_str())
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .y_label_formatter(&y_fmt)
            .x_label_formatter(&t_fmt)
            .light_line_style(WHITE.mix(0.0));
        if i == last {
            mesh.x_desc("Time (s)");
        }
        mesh.draw().map_err(|e| err(&e))?;
        let mut labelled = false;
        for (j, (s, pts)) in panel.series.iter().zip(series).enumerate() {
            let color = PALETTE[j % PALETTE.len()];
            let drawn = chart
                .draw_series(LineSeries::new(pts.iter().copied(), color.stroke_width(1)))
                .map_err(|e| err(&e))?;
            if !s.label.is_empty() {
                labelled = true;
                drawn.label(s.label.as_str()).legend(move |(x, y)| {
                    PathElement::new(vec![(x, y), (x + 20, y)], color.stroke_width(2))
                });
            }
        }
        if labelled {
            chart
                .configure_series_labels()
                .position(SeriesLabelPosition::UpperRight)
                .label_font(("sans-serif", 15))
                .background_style(WHITE.mix(0.85))
                .border_style(BLACK)
                .draw()
                .map_err(|e| err(&e))?;
        }
    }
    root.present().map_err(|e| err(&e))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn decimation_keeps_the_envelope() {
        let t: Vec<f64> = (0..100_000).map(|k| k as f64 * 1e-3).collect();
        let v: Vec<f64> = t.iter().map(|t| (t * 7.0).sin() * t).collect();
        let d = drawable(&t, &v);
        assert!(d.len() <= 4002);
        let max = |x: &mut dyn Iterator<Item = f64>| x.fold(f64::MIN, f64::max);
        assert_eq!(max(&mut d.iter().map(|p| p.1)), max(&mut v.iter().copied()));
        assert!(d.windows(2).all(|w| w[0].0 <= w[1].0));
        assert_eq!(drawable(&[0.0, 1.0, 2.0], &[1.0, f64::NAN, 3.0]).len(), 2);
    }

    #[test]
    fn draws_a_png() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.png");
        let t = [0.0, 1.0, 2.0];
        let (a, b) = ([0.0, 1.0, 0.5], [0.1, 0.9, 0.4]);
        stacked_time_series(
            &p,
            "test",
            &[
                Panel::single("A (mm)", &t, &a),
                Panel::single("B (kN)", &t, &b).with("b2", &t, &a),
            ],
        )
        .unwrap();
        assert!(std::fs::metadata(&p).unwrap().len() > 1000);
        assert!(stacked_time_series(&p, "empty", &[]).is_err());
    }

    #[test]
    fn tick_labels() {
        assert_eq!(tick_label(-0.0001, 0.6), "0.00");
        assert_eq!(tick_label(15000.0, 30000.0), "15000");
        assert_eq!(tick_label(-12.5, 25.0), "-12.5");
        assert_eq!(tick_label(0.25, 0.3), "0.250");
    }
}
