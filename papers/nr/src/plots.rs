//! Multi-panel line charts for seed 003's figures (a run's and the campaign's), on the report
//! crate's chart kit (font, palette, ticks, ranges): each panel has its own axes, linear or
//! logarithmic on either, lines solid or dashed or as markers, optional vertical error bars and
//! labelled vertical marker lines (t_s, u_max).

use std::path::Path;

use cohort_report::chart::{
    CAPTION_SIZE, DrawResult, FONT_FAMILY, MARGIN, X_LABEL_AREA, Y_LABEL_AREA, draw_legend, ensure_font, finite_bounds,
    format_tick, linear_range,
};
use plotters::coord::Shift;
use plotters::coord::ranged1d::ValueFormatter;
use plotters::prelude::*;

/// How a line is drawn.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Style {
    Solid,
    Dashed,
    /// Markers only.
    Markers,
    /// A solid line with markers at its points.
    SolidMarkers,
}

/// One series of a panel; non-finite points are left out (and split solid lines). An empty
/// label leaves it out of the legend; a line without points is a legend entry only.
#[derive(Debug, Clone)]
pub struct Line {
    pub label: String,
    pub color: RGBColor,
    pub points: Vec<(f64, f64)>,
    pub style: Style,
    /// Empty, or one half-width per point: a vertical error bar y ± err.
    pub err: Vec<f64>,
}

impl Line {
    pub fn new(label: impl Into<String>, color: RGBColor, points: Vec<(f64, f64)>, style: Style) -> Self {
        Self { label: label.into(), color, points, style, err: Vec::new() }
    }
}

/// One chart of a figure.
#[derive(Debug, Clone, Default)]
pub struct Panel {
    pub caption: String,
    pub x_desc: String,
    pub y_desc: String,
    pub log_x: bool,
    pub log_y: bool,
    pub lines: Vec<Line>,
    /// Vertical lines (x, label), drawn grey and dashed.
    pub marks_x: Vec<(f64, String)>,
    /// Horizontal lines (y, label), drawn grey and dashed.
    pub marks_y: Vec<(f64, String)>,
}

/// `panels` on a grid of `cols` columns under `title`, into a PNG of `size` pixels.
pub fn draw(path: &Path, title: &str, panels: &[Panel], cols: usize, size: (u32, u32)) -> DrawResult {
    ensure_font()?;
    let root = BitMapBackend::new(path, size).into_drawing_area();
    root.fill(&WHITE)?;
    let body = root.titled(title, (FONT_FAMILY, CAPTION_SIZE))?;
    let cols = cols.max(1);
    let rows = panels.len().div_ceil(cols).max(1);
    for (area, panel) in body.split_evenly((rows, cols)).iter().zip(panels) {
        draw_panel(area, panel)?;
    }
    root.present()?;
    Ok(())
}

/// Points a panel may draw on its axes (positive where the axis is logarithmic).
fn usable(p: &Panel, x: f64, y: f64) -> bool {
    x.is_finite() && y.is_finite() && (!p.log_x || x > 0.0) && (!p.log_y || y > 0.0)
}

/// An axis range over `values`: 5 % margins on a linear axis, a factor 1.5 on a log one.
fn range(values: impl Iterator<Item = f64>, log: bool) -> (f64, f64) {
    if !log {
        return linear_range(finite_bounds(values));
    }
    match finite_bounds(values.filter(|v| *v > 0.0)) {
        Some((lo, hi)) if hi > lo => (lo / 1.5, hi * 1.5),
        Some((v, _)) => (v / 10.0, v * 10.0),
        None => (0.1, 10.0),
    }
}

fn draw_panel(area: &DrawingArea<BitMapBackend<'_>, Shift>, p: &Panel) -> DrawResult {
    // The x range covers the points drawn (a point whose y is left out does not widen it).
    let xs = p
        .lines
        .iter()
        .flat_map(|l| l.points.iter().filter(|q| usable(p, q.0, q.1)).map(|q| q.0))
        .chain(p.marks_x.iter().map(|m| m.0));
    let (x0, x1) = range(xs, p.log_x);
    let ys = p.lines.iter().flat_map(|l| {
        l.points.iter().enumerate().flat_map(move |(i, q)| {
            let e = l.err.get(i).copied().unwrap_or(0.0);
            [q.1 - e, q.1 + e]
        })
    });
    let (y0, y1) = range(ys.chain(p.marks_y.iter().map(|m| m.0)), p.log_y);
    let mut b = ChartBuilder::on(area);
    b.caption(&p.caption, (FONT_FAMILY, 20))
        .margin(MARGIN / 2)
        .x_label_area_size(X_LABEL_AREA - 10)
        .y_label_area_size(Y_LABEL_AREA - 20);
    match (p.log_x, p.log_y) {
        (false, false) => fill(&mut b.build_cartesian_2d(x0..x1, y0..y1)?, p, (x0, x1), (y0, y1)),
        (true, false) => fill(&mut b.build_cartesian_2d((x0..x1).log_scale(), y0..y1)?, p, (x0, x1), (y0, y1)),
        (false, true) => fill(&mut b.build_cartesian_2d(x0..x1, (y0..y1).log_scale())?, p, (x0, x1), (y0, y1)),
        (true, true) => {
            fill(&mut b.build_cartesian_2d((x0..x1).log_scale(), (y0..y1).log_scale())?, p, (x0, x1), (y0, y1))
        }
    }
}

fn fill<'a, 'b: 'a, X, Y>(
    chart: &mut ChartContext<'a, BitMapBackend<'b>, Cartesian2d<X, Y>>,
    p: &Panel,
    (x0, x1): (f64, f64),
    (y0, y1): (f64, f64),
) -> DrawResult
where
    X: Ranged<ValueType = f64> + ValueFormatter<f64>,
    Y: Ranged<ValueType = f64> + ValueFormatter<f64>,
{
    chart
        .configure_mesh()
        .x_desc(p.x_desc.as_str())
        .y_desc(p.y_desc.as_str())
        .x_label_formatter(&format_tick)
        .y_label_formatter(&format_tick)
        .label_style((FONT_FAMILY, 14))
        .axis_desc_style((FONT_FAMILY, 16))
        .draw()?;
    let grey = RGBColor(110, 110, 110);
    for (x, label) in &p.marks_x {
        let pts = vec![(*x, y0), (*x, y1)];
        let s = chart.draw_series(DashedLineSeries::new(pts, 6, 5, grey.stroke_width(1)))?;
        if !label.is_empty() {
            s.label(label.as_str()).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], grey));
        }
    }
    for (y, label) in &p.marks_y {
        let pts = vec![(x0, *y), (x1, *y)];
        let s = chart.draw_series(DashedLineSeries::new(pts, 6, 5, grey.stroke_width(1)))?;
        if !label.is_empty() {
            s.label(label.as_str()).legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 22, y)], grey));
        }
    }
    for l in &p.lines {
        let color = l.color;
        let pts: Vec<(f64, f64)> = l.points.iter().copied().filter(|q| usable(p, q.0, q.1)).collect();
        let style = color.stroke_width(2);
        let legend = move |(x, y): (i32, i32)| PathElement::new(vec![(x, y), (x + 22, y)], color.stroke_width(3));
        match l.style {
            Style::Solid | Style::SolidMarkers => {
                // Split at the left-out points, so a gap stays a gap.
                let mut runs: Vec<Vec<(f64, f64)>> = vec![Vec::new()];
                for q in &l.points {
                    if usable(p, q.0, q.1) {
                        runs.last_mut().expect("non-empty").push(*q);
                    } else if !runs.last().expect("non-empty").is_empty() {
                        runs.push(Vec::new());
                    }
                }
                if !l.label.is_empty() {
                    chart.draw_series(LineSeries::new(std::iter::empty(), style))?.label(&l.label).legend(legend);
                }
                for run in runs {
                    chart.draw_series(run.windows(2).map(|w| PathElement::new(vec![w[0], w[1]], style)))?;
                }
            }
            Style::Dashed => {
                let a = chart.draw_series(DashedLineSeries::new(pts.clone(), 8, 6, style))?;
                if !l.label.is_empty() {
                    a.label(&l.label).legend(legend);
                }
            }
            Style::Markers => {
                let a = chart.draw_series(pts.iter().map(|q| Circle::new(*q, 4, color.filled())))?;
                if !l.label.is_empty() {
                    a.label(&l.label).legend(move |(x, y)| Circle::new((x + 11, y), 4, color.filled()));
                }
            }
        }
        if l.style == Style::SolidMarkers {
            chart.draw_series(pts.iter().map(|q| Circle::new(*q, 4, color.filled())))?;
        }
        if !l.err.is_empty() {
            let bars = l.points.iter().zip(&l.err).filter(|(q, e)| usable(p, q.0, q.1) && e.is_finite());
            // A vertical segment per point (plotters' ErrorBar needs a feature the workspace leaves off).
            chart.draw_series(bars.map(|(q, e)| {
                let lo = if p.log_y { (q.1 - e).max(q.1 * 1e-3) } else { q.1 - e };
                PathElement::new(vec![(q.0, lo), (q.0, q.1 + e)], color.stroke_width(2))
            }))?;
        }
    }
    let entries = p.lines.iter().filter(|l| !l.label.is_empty()).count()
        + p.marks_x.iter().chain(&p.marks_y).filter(|m| !m.1.is_empty()).count();
    if entries > 1 {
        draw_legend(chart)?;
    }
    Ok(())
}
