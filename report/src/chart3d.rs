//! The 3-D chart every 3-D figure starts from (trajectories, a net's nodes).

use plotters::coord::Shift;
use plotters::coord::ranged3d::Cartesian3d;
use plotters::coord::types::RangedCoordf64;
use plotters::prelude::*;

use crate::chart::{CAPTION_SIZE, FONT_FAMILY, MARGIN, format_tick};

pub type CubeChart<'a, 'b> =
    ChartContext<'a, BitMapBackend<'b>, Cartesian3d<RangedCoordf64, RangedCoordf64, RangedCoordf64>>;

/// A white 3-D chart over `ranges` (in chart order), seen from `view` = (yaw, pitch, scale), its
/// axes, light grid and tick labels drawn: what every 3-D figure of the reports starts from.
pub fn cube_chart<'a, 'b>(
    root: &'a DrawingArea<BitMapBackend<'b>, Shift>,
    title: &str,
    ranges: [(f64, f64); 3],
    view: (f64, f64, f64),
) -> Result<CubeChart<'a, 'b>, Box<dyn std::error::Error + Send + Sync>> {
    root.fill(&WHITE)?;
    let [a, b, c] = ranges;
    let mut chart = ChartBuilder::on(root)
        .caption(title, (FONT_FAMILY, CAPTION_SIZE))
        .margin(MARGIN)
        .build_cartesian_3d(a.0..a.1, b.0..b.1, c.0..c.1)?;
    chart.with_projection(|mut pb| {
        (pb.yaw, pb.pitch, pb.scale) = view;
        pb.into_matrix()
    });
    chart
        .configure_axes()
        .light_grid_style(BLACK.mix(0.08))
        .bold_grid_style(BLACK.mix(0.2))
        .max_light_lines(2)
        .label_style((FONT_FAMILY, 15))
        .x_formatter(&format_tick)
        .y_formatter(&format_tick)
        .z_formatter(&format_tick)
        .draw()?;
    Ok(chart)
}
