//! The figure of a mission run ([`crate::mission::kind`]; Sec. 8 and Table 6 of "Explainable
//! AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"):
//! `vtxo_mission_timeline.png` — the supervisor's location s (0–6) and the operational mode Id
//! (0–9) against mission time (days), as steps, from the events of `telemetry/plant.csv`.

use std::path::Path;

use plotters::prelude::*;

use cohort_report::chart::{
    CAPTION_SIZE, DrawResult, FONT_FAMILY, MARGIN, X_LABEL_AREA, Y_LABEL_AREA, draw_legend, draw_polyline, ensure_font,
    format_tick, series_color,
};
use cohort_report::{FigureSource, PaperFigure, ReportError};

pub struct MissionFigure {
    /// (t in days, location, Id) per event.
    events: Vec<(f64, f64, f64)>,
}

/// A step curve through the events: each value held until the next event.
fn steps(events: &[(f64, f64, f64)], pick: impl Fn(&(f64, f64, f64)) -> f64) -> Vec<(f64, f64)> {
    let mut out = Vec::with_capacity(2 * events.len());
    for (i, e) in events.iter().enumerate() {
        out.push((e.0, pick(e)));
        if let Some(next) = events.get(i + 1) {
            out.push((next.0, pick(e)));
        }
    }
    out
}

impl PaperFigure for MissionFigure {
    fn stem(&self) -> &str {
        "vtxo_mission_timeline"
    }
    fn draw(&self, path: &Path) -> DrawResult {
        ensure_font()?;
        let t_end = self.events.last().map_or(1.0, |e| e.0.max(1e-9));
        let root = BitMapBackend::new(path, (1200, 700)).into_drawing_area();
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(&root)
            .caption("VTXO mission: supervisor location and operational mode", (FONT_FAMILY, CAPTION_SIZE))
            .margin(MARGIN)
            .x_label_area_size(X_LABEL_AREA)
            .y_label_area_size(Y_LABEL_AREA)
            .build_cartesian_2d(0.0..t_end * 1.02, -0.5..9.5)?;
        chart
            .configure_mesh()
            .x_desc("mission time [d]")
            .y_desc("s (0–6), Id (0–9)")
            .x_label_formatter(&format_tick)
            .y_label_formatter(&format_tick)
            .label_style((FONT_FAMILY, 16))
            .axis_desc_style((FONT_FAMILY, 18))
            .draw()?;
        let lines = [
            (
                "location s (0 commissioning, 1 stabilisation, 2 transient, 3 science, 4 next mode, 5 de-commissioning, 6 end)",
                0,
            ),
            ("operational mode Id (Table 6)", 1),
        ];
        for (label, i) in lines {
            let color = series_color(None, i);
            let pts = steps(&self.events, |e| if i == 0 { e.1 } else { e.2 });
            chart
                .draw_series(LineSeries::new(std::iter::empty::<(f64, f64)>(), color.stroke_width(2)))?
                .label(label)
                .legend(move |(x, y)| PathElement::new(vec![(x, y), (x + 24, y)], color.stroke_width(3)));
            draw_polyline(&mut chart, &pts, color.stroke_width(2))?;
        }
        draw_legend(&mut chart)?;
        root.present()?;
        Ok(())
    }
}

/// The figure source of a mission run.
pub struct MissionFigures;

impl FigureSource for MissionFigures {
    fn figures(&self, t: &cohort_report::Telemetry<'_>) -> Result<Vec<Box<dyn PaperFigure>>, ReportError> {
        let Some(plant) = t.plant else { return Ok(Vec::new()) };
        let col = |name: &str| {
            plant.get(name).ok_or_else(|| ReportError::MissingColumn {
                path: t.run_dir.join("telemetry/plant.csv"),
                column: name.to_string(),
            })
        };
        let (s, id) = (col("state")?, col("id")?);
        let events = plant.t.iter().zip(s).zip(id).map(|((t, s), id)| (t / 86_400.0, *s, *id)).collect();
        Ok(vec![Box::new(MissionFigure { events })])
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn steps_hold_each_value_until_the_next_event() {
        let e = [(0.0, 0.0, 0.0), (60.0, 4.0, 1.0), (60.5, 2.0, 1.0)];
        assert_eq!(steps(&e, |e| e.1), vec![(0.0, 0.0), (60.0, 0.0), (60.0, 4.0), (60.5, 4.0), (60.5, 2.0)]);
    }
}
