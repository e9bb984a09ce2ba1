//! The chart kit every figure uses: sizes, the embedded font, the palette, axis ranges and
//! ticks, min/max downsampling, legends, and time-series charts.

use std::error::Error;
use std::path::Path;
use std::sync::OnceLock;

use plotters::coord::ranged1d::ValueFormatter;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;
use plotters::style::register_font;

use crate::ReportError;

/// Most points drawn per series; longer series are reduced to this many.
pub const MAX_POINTS: usize = 4000;
/// A figure whose values are all positive and whose max/min exceeds this gets a log y axis.
pub const LOG_SCALE_RATIO: f64 = 1e3;

pub(crate) const TIME_FIGURE_SIZE: (u32, u32) = (1200, 700);
pub(crate) const XY_FIGURE_SIZE: (u32, u32) = (1000, 1000);
pub const MARGIN: u32 = 20;
pub const X_LABEL_AREA: u32 = 60;
pub const Y_LABEL_AREA: u32 = 110;
pub const CAPTION_SIZE: u32 = 26;
pub const FONT_FAMILY: &str = "sans-serif";
/// Embedded because the `ab_glyph` font backend has no system font lookup. The path is relative
/// to this file: `report/assets/DejaVuSans.ttf`.
static FONT_BYTES: &[u8] = include_bytes!("../assets/DejaVuSans.ttf");

/// One line of a figure; non-finite points split the line.
#[derive(Debug)]
pub struct Series {
    pub label: String,
    pub color: RGBColor,
    pub points: Vec<(f64, f64)>,
}

#[derive(Debug)]
pub struct TimeFigure {
    pub title: String,
    pub y_desc: String,
    pub series: Vec<Series>,
}

/// Agent `id` always gets the same colour, so agents match across figures.
pub fn series_color(owner: Option<u32>, index: usize) -> RGBColor {
    const TABLEAU: [RGBColor; 10] = [
        RGBColor(31, 119, 180),
        RGBColor(255, 127, 14),
        RGBColor(44, 160, 44),
        RGBColor(214, 39, 40),
        RGBColor(148, 103, 189),
        RGBColor(140, 86, 75),
        RGBColor(227, 119, 194),
        RGBColor(127, 127, 127),
        RGBColor(188, 189, 34),
        RGBColor(23, 190, 207),
    ];
    let i = match owner {
        Some(id) => (id as usize).saturating_sub(1),
        None => index,
    };
    match TABLEAU.get(i) {
        Some(c) => *c,
        None => {
            let (r, g, b) = Palette99::pick(i).to_rgba().rgb();
            RGBColor(r, g, b)
        }
    }
}

/// A point that splits a line.
const GAP: (f64, f64) = (f64::NAN, f64::NAN);

pub fn is_finite_point(p: &(f64, f64)) -> bool {
    p.0.is_finite() && p.1.is_finite()
}

/// At most `max_points` finite points of `(x[i], y[i])`: all of them if few enough, else the
/// minimum and maximum of `y` in each of `max_points / 2` equal buckets of rows, in row order,
/// so peaks survive. Non-finite points become gaps (`GAP`, at most one per bucket).
pub fn downsample_min_max(x: &[f64], y: &[f64], max_points: usize) -> Vec<(f64, f64)> {
    let n = x.len().min(y.len());
    let point = |i: usize| (x[i], y[i]);
    let buckets = (max_points / 2).max(1);
    if n <= max_points || n <= buckets {
        return (0..n)
            .map(|i| {
                let p = point(i);
                if is_finite_point(&p) { p } else { GAP }
            })
            .collect();
    }
    let mut out = Vec::with_capacity(max_points + buckets);
    for b in 0..buckets {
        let start = b * n / buckets;
        let end = (b + 1) * n / buckets;
        let mut min: Option<usize> = None;
        let mut max: Option<usize> = None;
        let mut gap = false;
        for i in start..end {
            if !is_finite_point(&point(i)) {
                gap = true;
                continue;
            }
            if min.is_none_or(|m| y[i] < y[m]) {
                min = Some(i);
            }
            if max.is_none_or(|m| y[i] > y[m]) {
                max = Some(i);
            }
        }
        match (min, max) {
            (Some(a), Some(b)) if a == b => out.push(point(a)),
            (Some(a), Some(b)) => {
                out.push(point(a.min(b)));
                out.push(point(a.max(b)));
            }
            _ => {}
        }
        if gap {
            out.push(GAP);
        }
    }
    out
}

/// Every k-th point of the path `(x[i], y[i])` (and the last one), at most about `max_points`.
/// Non-finite points become gaps.
pub fn downsample_stride(x: &[f64], y: &[f64], max_points: usize) -> Vec<(f64, f64)> {
    let n = x.len().min(y.len());
    if n == 0 {
        return Vec::new();
    }
    let stride = n.div_ceil(max_points.max(1)).max(1);
    let mut indices: Vec<usize> = (0..n).step_by(stride).collect();
    if indices.last() != Some(&(n - 1)) {
        indices.push(n - 1);
    }
    indices
        .into_iter()
        .map(|i| {
            let p = (x[i], y[i]);
            if is_finite_point(&p) { p } else { GAP }
        })
        .collect()
}

/// The runs of finite points between gaps.
pub fn finite_runs(points: &[(f64, f64)]) -> impl Iterator<Item = &[(f64, f64)]> {
    points.split(|p| !is_finite_point(p)).filter(|run| !run.is_empty())
}

pub type DrawResult = Result<(), Box<dyn Error + Send + Sync>>;

/// Register the embedded font once per process (every figure of the orchestrator uses it).
pub fn ensure_font() -> Result<(), ReportError> {
    static REGISTERED: OnceLock<bool> = OnceLock::new();
    let ok = *REGISTERED.get_or_init(|| register_font(FONT_FAMILY, FontStyle::Normal, FONT_BYTES).is_ok());
    if ok { Ok(()) } else { Err(ReportError::Font) }
}

/// Smallest and largest finite value, if any.
pub fn finite_bounds(values: impl Iterator<Item = f64>) -> Option<(f64, f64)> {
    values.filter(|v| v.is_finite()).fold(None, |acc, v| match acc {
        None => Some((v, v)),
        Some((lo, hi)) => Some((lo.min(v), hi.max(v))),
    })
}

/// A finite, non-empty axis range around `bounds` with 5 % margins.
pub fn linear_range(bounds: Option<(f64, f64)>) -> (f64, f64) {
    let Some((lo, hi)) = bounds else {
        return (0.0, 1.0);
    };
    // Keep the span finite so the coordinate maths cannot overflow.
    let (lo, hi) = (lo.max(-f64::MAX / 4.0), hi.min(f64::MAX / 4.0));
    let span = hi - lo;
    if span > 0.0 {
        let pad = span * 0.05;
        (lo - pad, hi + pad)
    } else {
        let pad = if lo == 0.0 { 1.0 } else { lo.abs() * 0.1 };
        (lo - pad, hi + pad)
    }
}

pub fn format_tick(v: &f64) -> String {
    let a = v.abs();
    if a == 0.0 {
        "0".to_string()
    } else if !(1e-3..1e5).contains(&a) {
        let s = format!("{v:.2e}");
        match s.split_once('e') {
            Some((mantissa, exponent)) => format!("{}e{exponent}", trim_zeros(mantissa)),
            None => s,
        }
    } else {
        trim_zeros(&format!("{v:.4}")).to_string()
    }
}

/// `"2.500"` → `"2.5"`, `"40.000"` → `"40"`.
fn trim_zeros(s: &str) -> &str {
    if s.contains('.') { s.trim_end_matches('0').trim_end_matches('.') } else { s }
}

/// More lines than this on one chart hide each other (noisy per-agent series drawn over each
/// other show only the last): such a figure becomes one panel per line, on shared axes.
pub const MAX_OVERLAID_SERIES: usize = 4;

pub(crate) fn draw_time_figure(path: &Path, fig: &TimeFigure) -> DrawResult {
    let x_range = linear_range(finite_bounds(fig.series.iter().flat_map(|s| s.points.iter().map(|p| p.0))));
    let y_bounds = finite_bounds(fig.series.iter().flat_map(|s| s.points.iter().map(|p| p.1)));
    let log = matches!(y_bounds, Some((lo, hi)) if lo > 0.0 && hi / lo > LOG_SCALE_RATIO);

    let panels = if fig.series.len() > MAX_OVERLAID_SERIES { fig.series.len() } else { 1 };
    let cols = if panels == 1 { 1 } else { 2 };
    let rows = panels.div_ceil(cols);
    let size = (TIME_FIGURE_SIZE.0, TIME_FIGURE_SIZE.1.max(280 * rows as u32 + 2 * CAPTION_SIZE));
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let body = if panels == 1 { root.clone() } else { root.titled(&fig.title, (FONT_FAMILY, CAPTION_SIZE))? };
    let areas = body.split_evenly((rows, cols));
    for (i, area) in areas.iter().enumerate().take(panels) {
        let (caption, series): (&str, &[Series]) = if panels == 1 {
            (&fig.title, &fig.series)
        } else {
            (&fig.series[i].label, std::slice::from_ref(&fig.series[i]))
        };
        let mut builder = ChartBuilder::on(area);
        let caption_size = if panels == 1 { CAPTION_SIZE } else { 20 };
        builder
            .caption(caption, (FONT_FAMILY, caption_size))
            .margin(if panels == 1 { MARGIN } else { MARGIN / 2 })
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA);
        // Every panel on the same axes, so the lines compare.
        match (log, y_bounds) {
            (true, Some((lo, hi))) => {
                let y_range = (lo / 1.5)..(hi * 1.5);
                let mut chart = builder.build_cartesian_2d(x_range.0..x_range.1, y_range.log_scale())?;
                let y_desc = format!("{} (log scale)", fig.y_desc);
                fill_time_chart(&mut chart, &y_desc, series)?;
            }
            _ => {
                let y_range = linear_range(y_bounds);
                let mut chart = builder.build_cartesian_2d(x_range.0..x_range.1, y_range.0..y_range.1)?;
                fill_time_chart(&mut chart, &fig.y_desc, series)?;
            }
        }
    }
    root.present()?;
    Ok(())
}

/// A line chart of named series against time, for reports other than a run's (the soak's).
pub fn draw_lines(
    path: &Path,
    title: &str,
    y_desc: &str,
    series: Vec<(String, Vec<(f64, f64)>)>,
) -> Result<(), String> {
    ensure_font().map_err(|e| e.to_string())?;
    let series = series
        .into_iter()
        .enumerate()
        .map(|(i, (label, points))| Series { label, color: series_color(None, i), points })
        .collect();
    let fig = TimeFigure { title: title.into(), y_desc: y_desc.into(), series };
    draw_time_figure(path, &fig).map_err(|e| format!("{}: {e}", path.display()))
}

fn fill_time_chart<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    y_desc: &str,
    series: &[Series],
) -> DrawResult
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    draw_time_series(chart, y_desc, series, 2)?;
    if series.len() > 1 {
        draw_legend(chart)?;
    }
    Ok(())
}

/// Axes, mesh and every series of a time chart (each with a legend entry; `stroke` in pixels).
pub fn draw_time_series<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    y_desc: &str,
    series: &[Series],
    stroke: u32,
) -> DrawResult
where
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc("t [s]")
        .y_desc(y_desc)
        .x_label_formatter(&format_tick)
        .y_label_formatter(&format_tick)
        .label_style((FONT_FAMILY, 16))
        .axis_desc_style((FONT_FAMILY, 18))
        .draw()?;
    for s in series {
        let color = s.color;
        let style = color.stroke_width(stroke);
        // An empty series carries the legend entry; the runs are drawn unlabelled.
        chart
            .draw_series(LineSeries::new(std::iter::empty::<(f64, f64)>(), style))?
            .label(&s.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
        for run in finite_runs(&s.points) {
            if let [p] = run {
                chart.draw_series(std::iter::once(Circle::new(*p, 2, color.filled())))?;
            } else {
                draw_polyline(chart, run, style)?;
            }
        }
    }
    Ok(())
}

/// The legend box, upper right (any chart: time series, trajectories, 3-D).
pub fn draw_legend<'a, 'b: 'a, CT: CoordTranslate>(chart: &mut ChartContext<'a, BitMapBackend<'b>, CT>) -> DrawResult {
    chart
        .configure_series_labels()
        .position(SeriesLabelPosition::UpperRight)
        .label_font((FONT_FAMILY, 16))
        .background_style(WHITE.mix(0.85))
        .border_style(BLACK)
        .draw()?;
    Ok(())
}

/// Draws `run` as separate two-point segments. Plotters turns a path wider than one pixel into
/// a single polygon, whose joins spike far outside the chart where the path zig-zags at pixel
/// scale (noisy data, min/max downsampling); lone segments have no joins.
pub fn draw_polyline<'a, 'b: 'a, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<RangedCoordf64, Y>>,
    run: &[(f64, f64)],
    style: ShapeStyle,
) -> DrawResult
where
    Y: Ranged<ValueType = f64>,
{
    chart.draw_series(run.windows(2).map(|w| PathElement::new(vec![w[0], w[1]], style)))?;
    Ok(())
}
