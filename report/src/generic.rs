//! The figures every run gets, inferred from its telemetry's column names (see the crate docs).

use std::collections::{HashMap, HashSet};
use std::path::Path;

use plotters::prelude::*;

use crate::chart::DrawResult;
use crate::chart::*;
use crate::columns::{Quantity, unit_label};
use crate::table::Table;

/// Where a set of figures comes from: `label` prefixes file names, `file_desc` starts titles.
pub(crate) struct Source {
    pub(crate) label: String,
    pub(crate) file_desc: String,
}

#[derive(Debug)]
pub(crate) struct XyFigure {
    title: String,
    x_desc: String,
    y_desc: String,
    paths: Vec<Series>,
}

/// A figure of the generic set.
#[derive(Debug)]
pub(crate) enum Figure {
    Time(String, TimeFigure),
    Xy(String, XyFigure),
}

impl Figure {
    pub(crate) fn stem(&self) -> &str {
        match self {
            Figure::Time(stem, _) | Figure::Xy(stem, _) => stem,
        }
    }
    pub(crate) fn rename(&mut self, stem: String) {
        match self {
            Figure::Time(s, _) | Figure::Xy(s, _) => *s = stem,
        }
    }
    pub(crate) fn draw(&self, path: &Path) -> DrawResult {
        match self {
            Figure::Time(_, fig) => draw_time_figure(path, fig),
            Figure::Xy(_, fig) => draw_xy_figure(path, fig),
        }
    }
}

/// One time-history figure per family (name, unit, scalar/vector) across `tables`, one line
/// per quantity.
pub(crate) fn time_figures(
    source: &Source,
    tables: &[(&Table, Vec<Quantity>)],
    used_stems: &mut HashSet<String>,
) -> Vec<Figure> {
    type FamilyKey = (String, Option<String>, bool);
    let mut order: Vec<FamilyKey> = Vec::new();
    let mut members: HashMap<FamilyKey, Vec<(&Table, &Quantity)>> = HashMap::new();
    for (table, quantities) in tables {
        for q in quantities {
            let key = (q.name.clone(), q.unit.clone(), q.is_vector());
            let entry = members.entry(key.clone()).or_default();
            if entry.is_empty() {
                order.push(key);
            }
            entry.push((table, q));
        }
    }

    let mut figures = Vec::new();
    for key in order {
        let Some(family) = members.get(&key) else {
            continue;
        };
        let (name, unit, vector) = &key;
        let per_agent = family.iter().any(|(_, q)| q.owner.is_some());
        let quantity = if *vector { format!("‖{name}‖") } else { name.clone() };
        let mut title = format!("{} — {quantity}", source.file_desc);
        if per_agent {
            title.push_str(" per agent");
        }
        if let (true, Some((_, q))) = (*vector, family.first()) {
            let axes: Vec<String> =
                q.components.iter().filter_map(|(axis, _)| axis.map(|a| format!("{name}_{a}"))).collect();
            title.push_str(&format!(" (norm of {})", axes.join(", ")));
        }
        let y_desc = match unit.as_deref().and_then(unit_label) {
            Some(unit) => format!("{quantity} [{unit}]"),
            None => quantity.clone(),
        };
        // A family whose every line is constant says nothing a figure adds (a solver status that
        // stays 0): its values are in the telemetry; no figure.
        if family.iter().all(|(table, q)| is_constant(&q.values(table))) {
            continue;
        }
        let series = family
            .iter()
            .enumerate()
            .map(|(i, (table, q))| Series {
                label: match q.owner {
                    Some(id) => format!("agent {id}"),
                    None => quantity.clone(),
                },
                color: series_color(q.owner, i),
                points: downsample_min_max(&table.t, &q.values(table), MAX_POINTS),
            })
            .collect();
        let stem = unique_stem(&format!("{}_{}", source.label, sanitize(name)), used_stems);
        figures.push(Figure::Time(stem, TimeFigure { title, y_desc, series }));
    }
    figures
}

/// Whether every finite value of `xs` is the same (an empty or all-NaN series counts).
fn is_constant(xs: &[f64]) -> bool {
    let mut finite = xs.iter().filter(|x| x.is_finite());
    match finite.next() {
        None => true,
        Some(first) => finite.all(|x| x.to_bits() == first.to_bits()),
    }
}

/// The x–y paths of the table's position vectors (`r` with x and y axes), if it has any.
pub(crate) fn trajectory_figure(source: &Source, table: &Table, quantities: &[Quantity]) -> Option<XyFigure> {
    let mut unit = None;
    let paths: Vec<Series> = quantities
        .iter()
        .filter(|q| q.name == "r")
        .filter_map(|q| Some((q, q.column(table, 'x')?, q.column(table, 'y')?)))
        .enumerate()
        .map(|(i, (q, x, y))| {
            unit = unit.or(q.unit.as_deref().and_then(unit_label));
            Series {
                label: match q.owner {
                    Some(id) => format!("agent {id}"),
                    None => "r".to_string(),
                },
                color: series_color(q.owner, i),
                points: downsample_stride(x, y, MAX_POINTS),
            }
        })
        .collect();
    if paths.is_empty() {
        return None;
    }
    let desc = |axis: &str| match unit {
        Some(unit) => format!("{axis} [{unit}]"),
        None => axis.to_string(),
    };
    Some(XyFigure {
        title: format!("{} — x–y trajectories (● start, × end)", source.file_desc),
        x_desc: desc("x"),
        y_desc: desc("y"),
        paths,
    })
}

fn sanitize(name: &str) -> String {
    let s: String =
        name.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '_' }).collect();
    if s.is_empty() { "unnamed".to_string() } else { s }
}

/// `stem`, or `stem_2`, `stem_3`, ... if already taken.
pub fn unique_stem(stem: &str, used: &mut HashSet<String>) -> String {
    let mut candidate = stem.to_string();
    let mut n = 2;
    while !used.insert(candidate.clone()) {
        candidate = format!("{stem}_{n}");
        n += 1;
    }
    candidate
}

fn draw_xy_figure(path: &Path, fig: &XyFigure) -> DrawResult {
    let points = || fig.paths.iter().flat_map(|s| s.points.iter());
    let x = linear_range(finite_bounds(points().map(|p| p.0)));
    let y = linear_range(finite_bounds(points().map(|p| p.1)));
    // Equal scales on both axes: widen the narrower range to the plotting area's aspect ratio.
    let (w, h) = XY_FIGURE_SIZE;
    let plot_w = f64::from(w.saturating_sub(2 * MARGIN + Y_LABEL_AREA).max(1));
    let plot_h = f64::from(h.saturating_sub(2 * MARGIN + X_LABEL_AREA + 2 * CAPTION_SIZE).max(1));
    let scale = ((x.1 - x.0) / plot_w).max((y.1 - y.0) / plot_h);
    let widen = |(lo, hi): (f64, f64), px: f64| {
        let mid = lo / 2.0 + hi / 2.0;
        let half = scale * px / 2.0;
        if (mid - half).is_finite() && (mid + half).is_finite() { (mid - half, mid + half) } else { (lo, hi) }
    };
    let (x, y) = (widen(x, plot_w), widen(y, plot_h));

    let root = BitMapBackend::new(path, XY_FIGURE_SIZE).into_drawing_area();
    root.fill(&WHITE)?;
    let mut chart = ChartBuilder::on(&root)
        .caption(&fig.title, (FONT_FAMILY, CAPTION_SIZE))
        .margin(MARGIN)
        .x_label_area_size(X_LABEL_AREA)
        .y_label_area_size(Y_LABEL_AREA)
        .build_cartesian_2d(x.0..x.1, y.0..y.1)?;
    chart
        .configure_mesh()
        .x_desc(&fig.x_desc)
        .y_desc(&fig.y_desc)
        .x_label_formatter(&format_tick)
        .y_label_formatter(&format_tick)
        .label_style((FONT_FAMILY, 16))
        .axis_desc_style((FONT_FAMILY, 18))
        .draw()?;
    for s in &fig.paths {
        let color = s.color;
        let style = color.stroke_width(2);
        chart
            .draw_series(LineSeries::new(std::iter::empty::<(f64, f64)>(), style))?
            .label(&s.label)
            .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
        for run in finite_runs(&s.points) {
            draw_polyline(&mut chart, run, style)?;
        }
        let finite = || s.points.iter().copied().filter(is_finite_point);
        if let Some(start) = finite().next() {
            chart.draw_series(std::iter::once(Circle::new(start, 6, color.filled())))?;
        }
        if let Some(end) = finite().next_back() {
            chart.draw_series(std::iter::once(Cross::new(end, 7, color.stroke_width(3))))?;
        }
    }
    draw_legend(&mut chart)?;
    root.present()?;
    Ok(())
}
