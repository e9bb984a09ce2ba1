//! What one directed link did over a run, for the summary.

use cohort_wire::msg::{LINK_BLOCKED, LINK_BUSY, LINK_LOST_IN_TRANSIT, LINK_OUT_OF_RANGE};
use serde::{Deserialize, Serialize};

/// One directed link's record in the plant's report.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct LinkRow {
    pub from: u32,
    pub to: u32,
    #[serde(flatten)]
    pub stats: LinkStats,
}

/// Counts of one directed link's steps by outcome, with its delays and ranges.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct LinkStats {
    pub steps: u64,
    pub delivered: u64,
    pub lost: u64,
    pub busy: u64,
    pub blocked: u64,
    pub out_of_range: u64,
    /// Sum and largest of the delivered shares' delays, steps.
    pub delay_sum_steps: u64,
    pub delay_max_steps: u64,
    pub range_min_m: f64,
    pub range_max_m: f64,
}

impl LinkStats {
    pub(super) fn count(&mut self, code: u32, range_m: f64) {
        if self.steps == 0 {
            (self.range_min_m, self.range_max_m) = (range_m, range_m);
        }
        self.steps += 1;
        self.range_min_m = self.range_min_m.min(range_m);
        self.range_max_m = self.range_max_m.max(range_m);
        match code {
            LINK_BLOCKED => self.blocked += 1,
            LINK_OUT_OF_RANGE => self.out_of_range += 1,
            LINK_BUSY => self.busy += 1,
            LINK_LOST_IN_TRANSIT => self.lost += 1,
            d => {
                self.delivered += 1;
                self.delay_sum_steps += u64::from(d);
                self.delay_max_steps = self.delay_max_steps.max(u64::from(d));
            }
        }
    }
    /// Fraction of steps the link was in view (neither out of range nor blocked).
    pub fn availability(&self) -> f64 {
        let down = self.blocked + self.out_of_range;
        if self.steps == 0 { 0.0 } else { 1.0 - down as f64 / self.steps as f64 }
    }
    /// Mean delay of the delivered shares, steps.
    pub fn delay_mean_steps(&self) -> f64 {
        if self.delivered == 0 { 0.0 } else { self.delay_sum_steps as f64 / self.delivered as f64 }
    }
}
