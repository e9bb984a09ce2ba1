//! Charts of samples rather than time series: a histogram of one quantity and a scatter of one
//! quantity against another (a Monte Carlo campaign's metric against each dispersed value).

use std::ops::Range;
use std::path::Path;

use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::chart::{
    CAPTION_SIZE, FONT_FAMILY, MARGIN, X_LABEL_AREA, Y_LABEL_AREA, ensure_font, finite_bounds, format_tick,
    linear_range,
};

const SIZE: (u32, u32) = (1000, 700);
const BLUE: RGBColor = RGBColor(31, 119, 180);

/// Draw a chart of `x` × `y` to `path`: caption, axes with their descriptions, then `fill`.
fn draw_xy(
    path: &Path,
    title: &str,
    (x_desc, y_desc): (&str, &str),
    (x, y): (Range<f64>, Range<f64>),
    fill: impl FnOnce(
        &mut ChartContext<'_, BitMapBackend<'_>, Cartesian2d<RangedCoordf64, RangedCoordf64>>,
    ) -> crate::DrawResult,
) -> Result<(), String> {
    ensure_font().map_err(|e| e.to_string())?;
    let draw = || -> crate::DrawResult {
        let root = BitMapBackend::new(path, SIZE).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption(title, (FONT_FAMILY, CAPTION_SIZE))
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(x, y)?;
        chart
            .configure_mesh()
            .x_desc(x_desc)
            .y_desc(y_desc)
            .x_label_formatter(&format_tick)
            .y_label_formatter(&format_tick)
            .draw()?;
        fill(&mut chart)?;
        root.present()?;
        Ok(())
    };
    draw().map_err(|e| format!("{}: {e}", path.display()))
}

/// A histogram of the finite `values` in `bins` equal bins (Sturges' rule when `None`).
pub fn histogram(path: &Path, title: &str, x_desc: &str, values: &[f64], bins: Option<usize>) -> Result<(), String> {
    let xs: Vec<f64> = values.iter().copied().filter(|v| v.is_finite()).collect();
    let bins = bins.unwrap_or_else(|| ((xs.len().max(1) as f64).log2().ceil() as usize + 1).clamp(5, 60));
    let (lo, hi) = linear_range(finite_bounds(xs.iter().copied()));
    let width = (hi - lo) / bins as f64;
    let mut counts = vec![0u32; bins];
    for x in &xs {
        counts[(((x - lo) / width) as usize).min(bins - 1)] += 1;
    }
    let top = f64::from(counts.iter().copied().max().unwrap_or(0).max(1));
    draw_xy(path, title, (x_desc, "cases"), (lo..hi, 0.0..top * 1.08), |chart| {
        chart.draw_series(counts.iter().enumerate().map(|(k, &c)| {
            let x0 = lo + k as f64 * width;
            Rectangle::new([(x0, 0.0), (x0 + width, f64::from(c))], BLUE.mix(0.7).filled())
        }))?;
        Ok(())
    })
}

/// A scatter of `points` (x, y); non-finite points are left out.
pub fn scatter(path: &Path, title: &str, x_desc: &str, y_desc: &str, points: &[(f64, f64)]) -> Result<(), String> {
    let pts: Vec<(f64, f64)> = points.iter().copied().filter(|(x, y)| x.is_finite() && y.is_finite()).collect();
    let (x0, x1) = linear_range(finite_bounds(pts.iter().map(|p| p.0)));
    let (y0, y1) = linear_range(finite_bounds(pts.iter().map(|p| p.1)));
    draw_xy(path, title, (x_desc, y_desc), (x0..x1, y0..y1), |chart| {
        chart.draw_series(pts.iter().map(|&p| Circle::new(p, 3, BLUE.mix(0.6).filled())))?;
        Ok(())
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn both_charts_are_drawn_and_empty_data_is_no_error() {
        let dir = std::env::temp_dir().join(format!("cohort-samples-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let xs: Vec<f64> = (0..50).map(|i| (f64::from(i) * 0.37).sin()).collect();
        super::histogram(&dir.join("h.png"), "h", "x", &xs, None).unwrap();
        super::histogram(&dir.join("e.png"), "e", "x", &[f64::NAN], None).unwrap();
        let pts: Vec<(f64, f64)> = xs.iter().map(|&x| (x, x * x)).collect();
        super::scatter(&dir.join("s.png"), "s", "x", "y", &pts).unwrap();
        for f in ["h.png", "e.png", "s.png"] {
            assert!(std::fs::metadata(dir.join(f)).unwrap().len() > 1000, "{f}");
        }
        let _ = std::fs::remove_dir_all(&dir);
    }
}
