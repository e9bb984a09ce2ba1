//! The study's ladder of link conditions, each rung adding one thing to the one before.

use cohort_runtime::paper::LinkFrame;
use cohort_scenario::links::{LinkKind, Links, Loss};

/// Atmosphere margin added to the central body's radius for grazing rays, m (the Earth's
/// atmosphere bends and absorbs a crosslink well above the surface; 100 km is our choice).
pub const ATMOSPHERE_MARGIN_M: f64 = 100e3;
/// The last rung's data rate, bit/s: a low-rate crosslink (our choice: what a rate limit does to
/// a formation's exchange, at a rate small enough that its shares queue).
pub const RATE_CAP_BPS: f64 = 64e3;

/// One rung: its name and its `[links]` (None: the rung does not apply to this plant, e.g.
/// blockage in a frame with no central body, and the rung is the one before).
pub struct Rung {
    pub name: &'static str,
    pub links: Option<Links>,
}

/// The ladder for a plant whose positions are in `frame`: ideal; range-only delay; + blockage
/// by the central body; + loss 1 %, 10 %, 30 %; + the rate cap.
pub fn ladder(frame: LinkFrame) -> Vec<Rung> {
    let delay = Links { model: LinkKind::Geometric, ..Links::default() };
    let occulter = match frame {
        LinkFrame::CentralBody(_, radius_m) => Some(radius_m + ATMOSPHERE_MARGIN_M),
        _ => None,
    };
    let blocked = Links { occulting_radius_m: occulter, ..delay.clone() };
    let lossy = |p: f64| Links { loss: Some(Loss::Constant { p }), ..blocked.clone() };
    let capped = Links { data_rate_bps: Some(RATE_CAP_BPS), ..lossy(0.3) };
    vec![
        Rung { name: "ideal", links: Some(Links::default()) },
        Rung { name: "range-only delay", links: Some(delay) },
        Rung { name: "+ blockage", links: occulter.map(|_| blocked.clone()) },
        Rung { name: "+ loss 1 %", links: Some(lossy(0.01)) },
        Rung { name: "+ loss 10 %", links: Some(lossy(0.1)) },
        Rung { name: "+ loss 30 %", links: Some(lossy(0.3)) },
        Rung { name: "+ rate cap 64 kbit/s", links: Some(capped) },
    ]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_rung_adds_to_the_one_before_and_a_relative_frame_skips_blockage() {
        let earth = ladder(LinkFrame::CentralBody("the Earth", 6_378_137.0));
        assert_eq!(earth.len(), 7);
        assert!(earth.iter().all(|r| r.links.is_some()));
        let last = earth[6].links.as_ref().unwrap();
        assert_eq!(last.occulting_radius_m, Some(6_478_137.0));
        assert_eq!(last.loss, Some(Loss::Constant { p: 0.3 }));
        assert_eq!(last.data_rate_bps, Some(RATE_CAP_BPS));
        let relative = ladder(LinkFrame::Relative);
        assert!(relative[2].links.is_none());
        assert_eq!(relative[6].links.as_ref().unwrap().occulting_radius_m, None);
    }
}
