//! Charts of samples rather than time series: a histogram of one quantity and a scatter of one
//! quantity against another (a Monte Carlo campaign's metric against each dispersed value).

use std::path::Path;

use plotters::prelude::*;

use crate::chart::{
    CAPTION_SIZE, FONT_FAMILY, MARGIN, X_LABEL_AREA, Y_LABEL_AREA, ensure_font, finite_bounds, format_tick,
    linear_range,
};

const SIZE: (u32, u32) = (1000, 700);
const BLUE: RGBColor = RGBColor(31, 119, 180);

/// A histogram of the finite `values` in `bins` equal bins (Sturges' rule when `None`).
pub fn histogram(path: &Path, title: &str, x_desc: &str, values: &[f64], bins: Option<usize>) -> Result<(), String> {
    ensure_font().map_err(|e| e.to_string())?;
    let xs: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let bins = bins.unwrap_or_else(|| ((xs.len().max(1) as f64).log2().ceil() as usize + 1).clamp(5, 60));
    let (lo, hi) = linear_range(finite_bounds(xs.iter().copied()));
    let width = (hi - lo) / bins as f64;
    let mut counts = vec![0u32; bins];
    for x in &xs {
        counts[(((x - lo) / width) as usize).min(bins - 1)] += 1;
    }
    let top = counts.iter().copied().max().unwrap_or(0).max(1);
    let draw = || -> crate::DrawResult {
        let root = BitMapBackend::new(path, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT_FAMILY, CAPTION_SIZE))
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(lo..hi, 0f64..f64::from(top) * 1.08)?;
        chart.configure_mesh().x_desc(x_desc).y_desc("cases").x_label_formatter(&format_tick).draw()?;
        chart.draw_series(counts.iter().enumerate().map(|(k, &c)| {
            let x0 = lo + k as f64 * width;
            Rectangle::new([(x0, 0.0), (x0 + width, f64::from(c))], BLUE.mix(0.7).filled())
        }))?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}

/// A scatter of `points` (x, y); non-finite points are left out.
pub fn scatter(path: &Path, title: &str, x_desc: &str, y_desc: &str, points: &[(f64, f64)]) -> Result<(), String> {
    ensure_font().map_err(|e| e.to_string())?;
    let pts: Vec<(f64, f64)> = points.iter().copied().filter(|(x, y)| x.is_finite() && y.is_finite()).collect();
    let (x0, x1) = linear_range(finite_bounds(pts.iter().map(|p| p.0)));
    let (y0, y1) = linear_range(finite_bounds(pts.iter().map(|p| p.1)));
    let draw = || -> crate::DrawResult {
        let root = BitMapBackend::new(path, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT_FAMILY, CAPTION_SIZE))
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(x0..x1, y0..y1)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&format_tick)
            .y_label_formatter(&format_tick)
            .draw()?;
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, BLUE.mix(0.6).filled())))?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}
