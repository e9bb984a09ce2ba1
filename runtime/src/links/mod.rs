//! Inter-satellite links from the geometry (`[links]` model `geometric`): each step the plant
//! decides, from the true positions, what becomes of the share every agent sends each of its
//! readers at that step, and sends each reader its links' codes with its measurement
//! (`cohort_wire::msg::Measurement::links`). The reader's inbox then uses a share only from the
//! step its link delivers it (`drive::agent_inbox`). All of it is drawn from the plant's own
//! seeded stream in a fixed order, so a run is as deterministic as on ideal links.
//!
//! Per directed link i → j and step s, in this order:
//! 1. out of range (farther than `max_range_m`) → `LINK_OUT_OF_RANGE`;
//! 2. the segment between them passes through the occulting sphere → `LINK_BLOCKED`;
//! 3. still sending i's previous share (its bits over `data_rate_bps` end after tₛ) → `LINK_BUSY`;
//! 4. else the share is sent: lost with the loss law's probability → `LINK_LOST_IN_TRANSIT`,
//!    else it arrives after ⌈(range/c + processing + bits/rate)/dt⌉ steps.
//!
//! A share's size is that of i's latest share the plant received (the plant reads every share):
//! none at step 0, so the first share has no serialisation time.

pub mod loss;
pub mod on_plant;
mod stats;

use cohort_scenario::links::{C_MPS, Links};
use cohort_wire::msg::{LINK_BLOCKED, LINK_BUSY, LINK_LOST_IN_TRANSIT, LINK_OUT_OF_RANGE};
use rand::Rng;
use rand_chacha::ChaCha8Rng;

pub use stats::{LinkRow, LinkStats};

/// What the plant's link model is built from: `[links]`, every reader's neighbours (reader j at
/// index j − 1) and the scenario's seed (the model draws from a stream of its own).
#[derive(Debug, Clone)]
pub struct LinkSetup {
    pub cfg: Links,
    pub readers: Vec<Vec<u32>>,
    pub seed: u64,
}

impl LinkSetup {
    pub fn from_scenario(s: &cohort_scenario::Scenario) -> Self {
        let readers = (1..=s.n_agents()).map(|j| s.agent(j).neighbours.clone()).collect();
        LinkSetup { cfg: s.links.clone(), readers, seed: s.scenario.seed }
    }
    /// The model, with its own random stream.
    pub fn model(&self, dt_s: f64) -> LinkModel {
        LinkModel::new(self.cfg.clone(), dt_s, self.readers.clone(), crate::rng::setup_rng(self.seed, "links"))
    }
}

/// The plant's link model: the configuration, every reader's neighbours, and per directed link
/// when it is free again and what it did.
pub struct LinkModel {
    cfg: Links,
    dt_s: f64,
    /// Per reader j (index j − 1): its neighbours in scenario order.
    readers: Vec<Vec<u32>>,
    /// Per reader, per neighbour: the time the link ends sending its latest share, s.
    busy_until_s: Vec<Vec<f64>>,
    stats: Vec<Vec<LinkStats>>,
    rng: ChaCha8Rng,
}

/// Whether the segment a→b passes within `radius` of the origin.
pub fn occulted(a: &[f64; 3], b: &[f64; 3], radius: f64) -> bool {
    let d = [b[0] - a[0], b[1] - a[1], b[2] - a[2]];
    let dd = dot(&d, &d);
    // The point of the segment nearest the origin: a + t·d, t clamped to [0, 1].
    let t = if dd > 0.0 { (-dot(a, &d) / dd).clamp(0.0, 1.0) } else { 0.0 };
    let p = [a[0] + t * d[0], a[1] + t * d[1], a[2] + t * d[2]];
    dot(&p, &p) < radius * radius
}

fn dot(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

fn range_m(a: &[f64; 3], b: &[f64; 3]) -> f64 {
    ((b[0] - a[0]).powi(2) + (b[1] - a[1]).powi(2) + (b[2] - a[2]).powi(2)).sqrt()
}

impl LinkModel {
    /// The model for readers with these neighbour lists (reader j at index j − 1), drawing from
    /// `rng` (a stream of its own).
    pub fn new(cfg: Links, dt_s: f64, readers: Vec<Vec<u32>>, rng: ChaCha8Rng) -> Self {
        let busy_until_s = readers.iter().map(|n| vec![f64::NEG_INFINITY; n.len()]).collect();
        let stats = readers.iter().map(|n| vec![LinkStats::default(); n.len()]).collect();
        LinkModel { cfg, dt_s, readers, busy_until_s, stats, rng }
    }

    /// Decide every link's fate for the shares of step `k`, from the positions at tₖ (agent i at
    /// index i − 1) and each sender's share size in bits; `codes[j − 1]` gets reader j's codes.
    pub fn decide(&mut self, k: u64, pos: &[[f64; 3]], share_bits: &[u64], codes: &mut [Vec<u32>]) {
        let t_s = k as f64 * self.dt_s;
        for j in 0..self.readers.len() {
            codes[j].clear();
            for n in 0..self.readers[j].len() {
                let i = self.readers[j][n] as usize;
                let (a, b) = (&pos[i - 1], &pos[j]);
                let bits = share_bits[i - 1] as f64;
                let (r, busy) = (range_m(a, b), self.busy_until_s[j][n]);
                let code = self.one(a, b, r, t_s, bits, busy);
                self.busy_until_s[j][n] = self.next_busy(code, t_s, bits, busy);
                self.stats[j][n].count(code, r);
                codes[j].push(code);
            }
        }
    }

    /// One link's code, its ends a and b `r` apart (the caller updates the busy time from it).
    fn one(&mut self, a: &[f64; 3], b: &[f64; 3], r: f64, t_s: f64, bits: f64, busy_until_s: f64) -> u32 {
        let l = &self.cfg;
        if l.max_range_m.is_some_and(|m| r > m) {
            return LINK_OUT_OF_RANGE;
        }
        if l.occulting_radius_m.is_some_and(|rad| occulted(a, b, rad)) {
            return LINK_BLOCKED;
        }
        if t_s < busy_until_s {
            return LINK_BUSY;
        }
        let tx_s = l.data_rate_bps.map_or(0.0, |rate| bits / rate);
        if let Some(law) = &l.loss {
            let p = loss::probability(law, r, bits, l.data_rate_bps.unwrap_or(1.0));
            // Always one draw per link sent, so the stream does not depend on the outcomes.
            if self.rng.random::<f64>() < p {
                return LINK_LOST_IN_TRANSIT;
            }
        }
        let steps = ((r / C_MPS + l.processing_latency_s + tx_s) / self.dt_s).ceil();
        steps.min(f64::from(LINK_BUSY - 1)) as u32
    }

    /// When the link is free again: a share sent (delivered or lost) occupies it for its bits'
    /// time at the data rate.
    fn next_busy(&self, code: u32, t_s: f64, bits: f64, was: f64) -> f64 {
        match (code, self.cfg.data_rate_bps) {
            (LINK_OUT_OF_RANGE | LINK_BLOCKED | LINK_BUSY, _) | (_, None) => was,
            (_, Some(rate)) => t_s + bits / rate,
        }
    }

    /// Per directed link: what it did over the run.
    pub fn stats(&self) -> Vec<LinkRow> {
        let mut out = Vec::new();
        for (j, nbrs) in self.readers.iter().enumerate() {
            for (n, &i) in nbrs.iter().enumerate() {
                out.push(LinkRow { from: i, to: j as u32 + 1, stats: self.stats[j][n].clone() });
            }
        }
        out
    }
}

/// Whether a link code is a delay (the share is delivered), and which.
pub fn delay_of(code: u32) -> Option<u64> {
    (code < LINK_BUSY).then_some(u64::from(code))
}

#[cfg(test)]
mod tests;
