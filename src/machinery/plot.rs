//! Shared plotting setup: plotters renders text with an embedded font (DejaVu Sans, see
//! `assets/DejaVuSans.LICENSE`) so figures render the same on any machine, with no system fonts.

use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::Shift;
use plotters::prelude::{BitMapBackend, DrawingArea, IntoDrawingArea};
use plotters::style::FontStyle;

static FONT: &[u8] = include_bytes!("../../assets/DejaVuSans.ttf");

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

/// The drawing area of a `size`-pixel PNG at `path`, once [`crate::machinery::output::writable_file`] says
/// the file can be written (plotters finds out only when the figure is done).
pub fn bitmap(
    path: &Path,
    size: (u32, u32),
) -> anyhow::Result<DrawingArea<BitMapBackend<'_>, Shift>> {
    crate::machinery::output::writable_file(path)?;
    Ok(BitMapBackend::new(path, size).into_drawing_area())
}

/// How a curve is drawn, so that curves on top of each other stay apart.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum LineStyle {
    /// A thin solid line in the series' palette colour.
    #[default]
    Solid,
    /// A dashed line in the series' palette colour (e.g. a command drawn over a measurement).
    Dashed,
    /// A wide grey band drawn first, under the others: the reference, which the curves judged
    /// against it must not hide (where they agree it shows as a grey edge on both sides).
    Reference,
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
    /// How it is drawn.
    pub line: LineStyle,
}

/// One stacked panel of [`stacked_time_series`]: a y-axis label (with its unit) and one or more
/// curves sharing it (e.g. reference and measured), drawn in the order given.
#[derive(Debug, Clone)]
pub struct Panel<'a> {
    /// Y-axis label with unit, e.g. `"Brace disp. (mm)"`.
    pub y_label: String,
    /// The curves.
    pub series: Vec<Series<'a>>,
    /// A zoom panel: only this time window (start, end), s, on its own time axis; `None`: the
    /// figure's whole time axis.
    pub zoom_s: Option<(f64, f64)>,
}

impl<'a> Panel<'a> {
    /// A panel with no curves yet.
    pub fn new(y_label: impl Into<String>) -> Self {
        Self {
            y_label: y_label.into(),
            series: Vec::new(),
            zoom_s: None,
        }
    }

    /// A panel with a single unlabelled curve.
    pub fn single(y_label: impl Into<String>, time_s: &'a [f64], values: &'a [f64]) -> Self {
        Self::new(y_label).with("", time_s, values)
    }

    /// Add a labelled solid curve (builder style).
    pub fn with(self, label: impl Into<String>, time_s: &'a [f64], values: &'a [f64]) -> Self {
        self.with_line(label, time_s, values, LineStyle::Solid)
    }

    /// Add a labelled curve drawn as `line` (builder style).
    pub fn with_line(
        mut self,
        label: impl Into<String>,
        time_s: &'a [f64],
        values: &'a [f64],
        line: LineStyle,
    ) -> Self {
        self.series.push(Series {
            label: label.into(),
            time_s,
            values,
            line,
        });
        self
    }

    /// The same curves, on the time window `window_s` (start, end), s, only (builder style).
    pub fn zoomed(mut self, y_label: impl Into<String>, window_s: (f64, f64)) -> Self {
        self.y_label = y_label.into();
        self.zoom_s = Some(window_s);
        self
    }
}

/// A vertical line across every panel at `time_s`, labelled (e.g. where the supervisor tripped).
#[derive(Debug, Clone, PartialEq)]
pub struct Marker {
    /// Time, s.
    pub time_s: f64,
    /// Its text, e.g. `"trip: CommandVelocity at 2.353 s"`.
    pub label: String,
}

/// A figure of stacked time-series panels ([`draw`]).
#[derive(Debug, Clone)]
pub struct Figure<'a> {
    /// The title.
    pub title: String,
    /// The panels, top to bottom.
    pub panels: Vec<Panel<'a>>,
    /// A labelled vertical line in every panel, if any.
    pub marker: Option<Marker>,
    /// The shared time axis (start, end), s; `None`: the span of the data. A stopped run keeps
    /// the record's whole span, so the figure shows how early it ended.
    pub time_span_s: Option<(f64, f64)>,
}

/// Half the width of the zoom window of [`peak_window_s`], s.
pub const ZOOM_HALF_WIDTH_S: f64 = 1.5;

/// `a[k] − b[k]` (the shorter length wins): the error of a curve against its reference, in their
/// unit.
pub fn difference(a: &[f64], b: &[f64]) -> Vec<f64> {
    a.iter().zip(b).map(|(x, y)| x - y).collect()
}

/// The window `half_width_s` either side of the largest |value| (the strongest motion), kept
/// inside the series' time span; `None` if no point is finite.
pub fn peak_window_s(time_s: &[f64], values: &[f64], half_width_s: f64) -> Option<(f64, f64)> {
    let (t_peak, _) = time_s
        .iter()
        .zip(values)
        .filter(|(t, v)| t.is_finite() && v.is_finite())
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))?;
    let (first, last) = (time_s.first()?, time_s.last()?);
    let (mut lo, mut hi) = (t_peak - half_width_s, t_peak + half_width_s);
    if lo < *first {
        hi = (hi + (first - lo)).min(*last);
        lo = *first;
    }
    if hi > *last {
        lo = (lo - (hi - last)).max(*first);
        hi = *last;
    }
    Some((lo, hi))
}

/// The number of samples at or before `stop_time_s` (the trip tick included): a stopped run's
/// curves end there.
pub fn samples_until(time_s: &[f64], stop_time_s: f64) -> usize {
    time_s.partition_point(|t| *t <= stop_time_s + 1e-9)
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

/// Tick label with as many decimals as a span of `span` needs (exponent form below 0.001), and
/// no "-0".
fn tick_label(v: f64, span: f64) -> String {
    if span < 1e-3 && span > 0.0 {
        return if v.abs() < span * 1e-6 {
            "0".to_string()
        } else {
            format!("{v:.1e}")
        };
    }
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

/// Draw `panels` stacked vertically over a shared time axis (s) into the PNG `path`, under `title`
/// ([`draw`] without a marker).
pub fn stacked_time_series(path: &Path, title: &str, panels: &[Panel<'_>]) -> anyhow::Result<()> {
    draw(
        path,
        &Figure {
            title: title.to_string(),
            panels: panels.to_vec(),
            marker: None,
            time_span_s: None,
        },
    )
}

/// Grey of [`LineStyle::Reference`].
const REFERENCE_GREY: plotters::style::RGBColor = plotters::style::RGBColor(150, 150, 150);
/// Colour of a [`Marker`] (Okabe–Ito vermillion is a curve's; this is a darker red).
const MARKER_RED: plotters::style::RGBColor = plotters::style::RGBColor(190, 0, 0);

/// Draw `figure` into the PNG `path`: its panels stacked vertically, every panel with its own y
/// range and, where a curve is labelled, a legend; panels share the time axis (s) but a zoom panel
/// ([`Panel::zoom_s`]) has its own, labelled under it; the marker is a vertical line in every
/// panel, its label in the first.
pub fn draw(path: &Path, figure: &Figure<'_>) -> anyhow::Result<()> {
    use plotters::prelude::*;
    init_fonts()?;
    let panels = &figure.panels;
    if panels.is_empty() {
        anyhow::bail!("nothing to plot");
    }
    let data: Vec<Vec<Vec<(f64, f64)>>> = panels
        .iter()
        .map(|p| {
            p.series
                .iter()
                .map(|s| {
                    let pts = drawable(s.time_s, s.values);
                    match p.zoom_s {
                        Some((lo, hi)) => pts
                            .into_iter()
                            .filter(|(t, _)| *t >= lo && *t <= hi)
                            .collect(),
                        None => pts,
                    }
                })
                .collect()
        })
        .collect();
    let (t0, t1) = match figure.time_span_s {
        Some(span) => span,
        None => panels
            .iter()
            .zip(&data)
            .filter(|(p, _)| p.zoom_s.is_none())
            .flat_map(|(_, d)| d.iter().flatten())
            .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), (t, _)| {
                (a.min(*t), b.max(*t))
            }),
    };
    if !data.iter().flatten().flatten().any(|_| true) || !t0.is_finite() {
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
        .titled(&figure.title, ("sans-serif", 24))
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
        let x_range = match panel.zoom_s {
            Some((a, b)) if b > a => a..b,
            _ => t_range.clone(),
        };
        // A time axis is labelled under the last panel, and under a zoom panel and the one above
        // it (their axes differ).
        let next_zoomed = panels.get(i + 1).is_some_and(|p| p.zoom_s.is_some());
        let time_axis = i == last || panel.zoom_s.is_some() || next_zoomed;
        let y_span = y_range.end - y_range.start;
        let t_span = x_range.end - x_range.start;
        let y_fmt = move |v: &f64| tick_label(*v, y_span);
        let t_fmt = move |v: &f64| tick_label(*v, t_span);
        let mut chart = ChartBuilder::on(area)
            .margin_left(10)
            .margin_right(25)
            .margin_top(8)
            .x_label_area_size(if time_axis { 45 } else { 22 })
            .y_label_area_size(85)
            .build_cartesian_2d(x_range.clone(), y_range.clone())
            .map_err(|e| err(&e))?;
        let mut mesh = chart.configure_mesh();
        mesh.y_desc(panel.y_label.as_str())
            .label_style(("sans-serif", 15))
            .axis_desc_style(("sans-serif", 17))
            .y_label_formatter(&y_fmt)
            .x_label_formatter(&t_fmt)
            .light_line_style(WHITE.mix(0.0));
        let zoom_desc;
        if let Some((a, b)) = panel.zoom_s {
            zoom_desc = format!("Time (s), zoom on {a:.2}-{b:.2} s");
            mesh.x_desc(zoom_desc.as_str());
        } else if time_axis {
            mesh.x_desc("Time (s)");
        }
        mesh.draw().map_err(|e| err(&e))?;
        let mut labelled = false;
        let mut colour_index = 0;
        for (s, pts) in panel.series.iter().zip(series) {
            let pts = pts.iter().copied();
            let drawn = match s.line {
                LineStyle::Reference => {
                    let style = REFERENCE_GREY.stroke_width(4);
                    let d = chart
                        .draw_series(LineSeries::new(pts, style))
                        .map_err(|e| err(&e))?;
                    if !s.label.is_empty() {
                        d.label(s.label.as_str()).legend(move |(x, y)| {
                            PathElement::new(vec![(x, y), (x + 24, y)], style)
                        });
                    }
                    !s.label.is_empty()
                }
                LineStyle::Solid | LineStyle::Dashed => {
                    let colour = PALETTE[colour_index % PALETTE.len()];
                    colour_index += 1;
                    let style = colour.stroke_width(1);
                    let d = if s.line == LineStyle::Dashed {
                        chart
                            .draw_series(DashedLineSeries::new(pts, 6, 4, style))
                            .map_err(|e| err(&e))?
                    } else {
                        chart
                            .draw_series(LineSeries::new(pts, style))
                            .map_err(|e| err(&e))?
                    };
                    if !s.label.is_empty() {
                        let legend = colour.stroke_width(2);
                        if s.line == LineStyle::Dashed {
                            d.label(s.label.as_str()).legend(move |(x, y)| {
                                plotters::element::DashedPathElement::new(
                                    vec![(x, y), (x + 24, y)],
                                    6,
                                    3,
                                    legend,
                                )
                            });
                        } else {
                            d.label(s.label.as_str()).legend(move |(x, y)| {
                                PathElement::new(vec![(x, y), (x + 24, y)], legend)
                            });
                        }
                    }
                    !s.label.is_empty()
                }
            };
            labelled |= drawn;
        }
        if let Some(m) = &figure.marker {
            if m.time_s >= x_range.start && m.time_s <= x_range.end {
                let style = MARKER_RED.stroke_width(2);
                let d = chart
                    .draw_series(LineSeries::new(
                        [(m.time_s, y_range.start), (m.time_s, y_range.end)],
                        style,
                    ))
                    .map_err(|e| err(&e))?;
                if i == 0 {
                    // The first panel names the marker beside it; the others in their legend.
                    let y_text = y_range.end - 0.04 * (y_range.end - y_range.start);
                    chart
                        .draw_series(std::iter::once(Text::new(
                            format!(" {}", m.label),
                            (m.time_s, y_text),
                            ("sans-serif", 15).into_font().color(&MARKER_RED),
                        )))
                        .map_err(|e| err(&e))?;
                } else {
                    d.label(m.label.as_str()).legend(move |(x, y)| {
                        PathElement::new(vec![(x + 12, y - 7), (x + 12, y + 7)], style)
                    });
                    labelled = true;
                }
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
    fn figure_helpers() {
        assert_eq!(difference(&[1.0, 2.5, 3.0], &[0.5, 2.0]), vec![0.5, 0.5]);
        let t: Vec<f64> = (0..1001).map(|k| k as f64 * 0.01).collect();
        let mut v = vec![0.0; t.len()];
        v[500] = -3.0;
        v[100] = 2.0;
        assert_eq!(peak_window_s(&t, &v, 1.5), Some((3.5, 6.5)));
        // Near an end the window keeps its width inside the record.
        v[50] = 9.0;
        assert_eq!(peak_window_s(&t, &v, 1.5), Some((0.0, 3.0)));
        v[990] = -10.0;
        assert_eq!(peak_window_s(&t, &v, 1.5), Some((7.0, 10.0)));
        assert_eq!(peak_window_s(&t, &[f64::NAN; 3], 1.5), None);
        assert_eq!(samples_until(&t, 2.35), 236);
        assert_eq!(samples_until(&t, -1.0), 0);
        assert_eq!(samples_until(&t, 100.0), t.len());
    }

    #[test]
    fn draws_a_figure_with_zoom_and_marker() {
        let dir = tempfile::tempdir().unwrap();
        let p = dir.path().join("f.png");
        let t: Vec<f64> = (0..400).map(|k| k as f64 * 0.01).collect();
        let a: Vec<f64> = t.iter().map(|t| t.sin()).collect();
        let panel = Panel::new("A (mm)")
            .with_line("reference", &t, &a, LineStyle::Reference)
            .with_line("command", &t, &a, LineStyle::Dashed)
            .with("measured", &t, &a);
        let fig = Figure {
            title: "test".into(),
            panels: vec![panel.clone(), panel.zoomed("A, zoom (mm)", (1.0, 2.0))],
            marker: Some(Marker {
                time_s: 1.5,
                label: "trip".into(),
            }),
            time_span_s: Some((0.0, 10.0)),
        };
        draw(&p, &fig).unwrap();
        assert!(std::fs::metadata(&p).unwrap().len() > 1000);
    }

    #[test]
    fn tick_labels() {
        assert_eq!(tick_label(-0.0001, 0.6), "0.00");
        assert_eq!(tick_label(15000.0, 30000.0), "15000");
        assert_eq!(tick_label(-12.5, 25.0), "-12.5");
        assert_eq!(tick_label(0.25, 0.3), "0.250");
        // A tiny span (a pure run's round-off error) keeps its ticks apart.
        assert_eq!(tick_label(2.5e-5, 1e-4), "2.5e-5");
        assert_eq!(tick_label(-5e-5, 1e-4), "-5.0e-5");
        assert_eq!(tick_label(1e-20, 1e-4), "0");
    }
}
