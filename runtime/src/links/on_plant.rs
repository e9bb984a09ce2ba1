//! The plant's side of geometric links: the model, the positions it reads, each reader's codes,
//! and the link columns of the plant's telemetry.
//!
//! The columns are averages over the last second of steps: with a rate cap every link sends in
//! the same steps, so a per-step fraction only alternates between 0 and 1. The window keeps
//! whole counts, so its running sums are exact however long the run.

use std::collections::VecDeque;

use cohort_wire::msg::{LINK_BLOCKED, LINK_OUT_OF_RANGE};

use super::{LinkModel, LinkSetup, delay_of};

/// The link columns of the plant's telemetry.
pub const COLUMNS: [&str; 3] = ["links_in_view_frac_1s", "links_delivered_frac_1s", "links_delay_mean_steps_1s"];

/// Per step: (links, in view, delivered, sum of the delivered delays).
type StepCounts = [u64; 4];

pub struct PlantLinks {
    model: LinkModel,
    positions: Vec<[f64; 3]>,
    codes: Vec<Vec<u32>>,
    window: VecDeque<StepCounts>,
    window_steps: usize,
    sums: StepCounts,
    /// The columns of the two latest steps decided (a row is written after the next step's
    /// measurements went out): (step, values).
    rows: [(u64, [f64; 3]); 2],
}

impl PlantLinks {
    pub fn new(setup: &LinkSetup, dt_s: f64, n_agents: usize) -> Self {
        PlantLinks {
            model: setup.model(dt_s),
            positions: Vec::with_capacity(n_agents),
            codes: vec![Vec::new(); n_agents],
            window: VecDeque::new(),
            window_steps: (1.0 / dt_s).ceil().max(1.0) as usize,
            sums: [0; 4],
            rows: [(u64::MAX, [0.0; 3]); 2],
        }
    }

    /// Fill with the plant's positions (false: the plant gave none, or not one per agent).
    pub fn read_positions(&mut self, f: impl FnOnce(&mut Vec<[f64; 3]>) -> bool) -> bool {
        self.positions.clear();
        f(&mut self.positions) && self.positions.len() == self.codes.len()
    }

    /// Decide every link for the shares of step k (positions read first), and its columns.
    pub fn decide(&mut self, k: u64, share_bits: &[u64]) {
        self.model.decide(k, &self.positions, share_bits, &mut self.codes);
        let mut counts = [0; 4];
        for code in self.codes.iter().flatten() {
            counts[0] += 1;
            counts[1] += u64::from(!matches!(*code, LINK_BLOCKED | LINK_OUT_OF_RANGE));
            if let Some(d) = delay_of(*code) {
                counts[2] += 1;
                counts[3] += d;
            }
        }
        self.slide(counts);
        let s = self.sums.map(|x| x as f64);
        let frac = |x: f64, of: f64| if of > 0.0 { x / of } else { 0.0 };
        self.rows[(k % 2) as usize] = (k, [frac(s[1], s[0]), frac(s[2], s[0]), frac(s[3], s[2])]);
    }

    /// Add step k's counts to the window and drop the step that leaves it.
    fn slide(&mut self, counts: StepCounts) {
        self.window.push_back(counts);
        self.sums.iter_mut().zip(&counts).for_each(|(s, x)| *s += x);
        if self.window.len() > self.window_steps
            && let Some(old) = self.window.pop_front()
        {
            self.sums.iter_mut().zip(&old).for_each(|(s, x)| *s -= x);
        }
    }

    /// Reader j's codes (agent ids from 1).
    pub fn codes(&self, j: u32) -> &[u32] {
        &self.codes[j as usize - 1]
    }

    /// Step k's columns (decided with its measurements).
    pub fn row(&self, k: u64) -> [f64; 3] {
        let (at, values) = self.rows[(k % 2) as usize];
        debug_assert_eq!(at, k, "step k's links were decided with its measurements");
        values
    }

    /// What every directed link did over the run.
    pub fn stats(&self) -> Vec<super::LinkRow> {
        self.model.stats()
    }
}
