//! The paper's DNN tension estimator as a [`TensionForecast`]: MU i keeps the history samples
//! X_{i,m} of eq. (7) from what it is fed each control step, and asks the [`TensionPredictor`]
//! for the tension over the horizon.
//!
//! Sample m needs MU i's state at t_m and its thrust over [t_m, t_{m+1}) (known one step later,
//! as `thrust_prev_n`), and the same of both adjacent MUs (their shares, `age_steps` old). At t_k
//! the newest complete sample is e = k − 1 with no link delay (k − 2 with one step of delay); the
//! predictor gives T̂(t_{e+1} … t_{e+N_t}), and the forecast for t_{k+n} is its entry
//! k + n − e − 1, the last one held beyond the predictor's horizon.
//!
//! Until N_t complete samples exist (the first N_t·Δt of a run, while the net is still folded and
//! slack) and whenever an adjacent MU has gone silent, the forecast is the measured tension held
//! ([`crate::forecast::HoldMeasured`]); [`DnnForecast::fallbacks`] counts those steps.

use std::collections::BTreeMap;
use std::sync::Arc;

use crate::forecast::{ForecastInput, TensionForecast};
use crate::predictor::{FEATURES_PER_STEP, Sample, TensionPredictor, adjacent_mus};

/// What is known of one step m, filled in as it arrives.
#[derive(Debug, Clone, Copy, Default, serde::Serialize, serde::Deserialize)]
struct Partial {
    own_state: Option<[f64; 6]>,
    own_thrust_n: Option<[f64; 3]>,
    neighbour_states: [Option<[f64; 6]>; 2],
    neighbour_thrust_n: [Option<[f64; 3]>; 2],
}

impl Partial {
    fn complete(&self) -> Option<Sample> {
        Some(Sample {
            own_state: self.own_state?,
            neighbour_states: [self.neighbour_states[0]?, self.neighbour_states[1]?],
            own_thrust_n: self.own_thrust_n?,
            neighbour_thrust_n: [self.neighbour_thrust_n[0]?, self.neighbour_thrust_n[1]?],
        })
    }
}

pub struct DnnForecast {
    predictor: Arc<TensionPredictor>,
    adjacent: [u32; 2],
    steps: BTreeMap<u64, Partial>,
    history: Vec<f64>,
    fallbacks: u64,
}

impl DnnForecast {
    /// The forecast of MU `mu` (1..=4). The predictor's Δt must be the control step (the caller
    /// checks; one call of [`TensionForecast::forecast`] per Δt).
    pub fn new(predictor: Arc<TensionPredictor>, mu: u32) -> Self {
        let cap = FEATURES_PER_STEP * predictor.horizon_steps();
        Self {
            predictor,
            adjacent: adjacent_mus(mu),
            steps: BTreeMap::new(),
            history: Vec::with_capacity(cap),
            fallbacks: 0,
        }
    }

    /// Control steps at which the measured tension was held instead of predicted.
    pub fn fallbacks(&self) -> u64 {
        self.fallbacks
    }

    /// The newest step e whose sample and its N_t − 1 predecessors are complete, with the
    /// history vector (oldest first) written into `self.history`.
    fn newest_window(&mut self) -> Option<u64> {
        let n_t = self.predictor.horizon_steps() as u64;
        let newest = self.steps.iter().rev().find(|(_, p)| p.complete().is_some()).map(|(k, _)| *k)?;
        if newest + 1 < n_t {
            return None;
        }
        self.history.clear();
        for m in newest + 1 - n_t..=newest {
            self.steps.get(&m)?.complete()?.extend_features(&mut self.history);
        }
        Some(newest)
    }
}

fn bincode_config() -> impl bincode::config::Config {
    bincode::config::standard().with_little_endian().with_fixed_int_encoding()
}

impl TensionForecast for DnnForecast {
    fn save(&self) -> Vec<u8> {
        bincode::serde::encode_to_vec((&self.steps, &self.history, self.fallbacks), bincode_config())
            .expect("plain data always encodes")
    }
    fn restore(&mut self, bytes: &[u8]) -> Result<(), String> {
        type State = (BTreeMap<u64, Partial>, Vec<f64>, u64);
        let ((steps, history, fallbacks), used): (State, usize) =
            bincode::serde::decode_from_slice(bytes, bincode_config()).map_err(|e| format!("DNN forecast: {e}"))?;
        if used != bytes.len() {
            return Err("DNN forecast: trailing bytes".into());
        }
        (self.steps, self.history, self.fallbacks) = (steps, history, fallbacks);
        Ok(())
    }

    fn forecast(&mut self, input: &ForecastInput<'_>, out: &mut [[f64; 3]]) {
        let k = input.k;
        self.steps.entry(k).or_default().own_state = Some(input.state);
        if k >= 1 {
            self.steps.entry(k - 1).or_default().own_thrust_n = Some(input.thrust_prev_n);
        }
        for nb in input.neighbours {
            let Some(slot) = self.adjacent.iter().position(|&j| j == nb.id) else { continue };
            let Some(m) = k.checked_sub(nb.age_steps) else { continue };
            let p = self.steps.entry(m).or_default();
            p.neighbour_states[slot] = Some(nb.state);
            p.neighbour_thrust_n[slot] = Some(nb.thrust_n);
        }
        // Keep what the next windows can still use.
        let keep_from = k.saturating_sub(4 * self.predictor.horizon_steps() as u64 + 8);
        while self.steps.first_key_value().is_some_and(|(m, _)| *m < keep_from) {
            self.steps.pop_first();
        }
        let predicted = self.newest_window().and_then(|e| self.predictor.predict(&self.history).ok().map(|t| (e, t)));
        let Some((e, t)) = predicted else {
            self.fallbacks += 1;
            out.fill(input.tension_measured_n);
            return;
        };
        for (n, o) in out.iter_mut().enumerate() {
            let idx = (k + n as u64 - e - 1) as usize;
            *o = t[idx.min(t.len() - 1)];
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::forecast::NeighbourSample;
    use crate::predictor::{base_metadata, weights_file_bytes};

    /// N_t = 2, one hidden layer of 8, deterministic weights.
    fn predictor() -> Arc<TensionPredictor> {
        let (n_in, h, n_out) = (54, 8, 6);
        let w1: Vec<f32> = (0..h * n_in).map(|i| ((i * 29 % 97) as f32 - 48.0) / 300.0).collect();
        let w2: Vec<f32> = (0..n_out * h).map(|i| ((i * 11 % 23) as f32 - 11.0) / 10.0).collect();
        let layers = vec![(w1, vec![0.2; h], h, n_in), (w2, vec![0.1; n_out], n_out, h)];
        let meta = serde_json::Value::Object(base_metadata(2, 0.1).into_iter().collect());
        let bytes = weights_file_bytes(&layers, &vec![0.0; n_in], &vec![1.0; n_in], &[1.0; 6], &meta).unwrap();
        Arc::new(TensionPredictor::from_bytes(&bytes, std::path::Path::new("t")).unwrap())
    }

    /// What MU 1 sees at step k: made-up states and thrusts that differ every step.
    fn state(id: u32, m: u64) -> [f64; 6] {
        std::array::from_fn(|a| (id as f64) + 0.1 * m as f64 + 0.01 * a as f64)
    }
    fn thrust(id: u32, m: u64) -> [f64; 3] {
        std::array::from_fn(|a| (id as f64 * 0.5 - m as f64 * 0.2 + a as f64).sin())
    }

    fn run(age: u64, steps: u64) -> (Vec<Vec<[f64; 3]>>, u64) {
        let mut f = DnnForecast::new(predictor(), 1);
        let mut outs = Vec::new();
        for k in 0..steps {
            // MU 4 is the diagonal: it must be ignored even when heard.
            let nbs: Vec<NeighbourSample> = [2u32, 3, 4]
                .iter()
                .filter(|_| k >= age)
                .map(|&id| NeighbourSample {
                    id,
                    state: state(id, k - age),
                    thrust_n: thrust(id, k - age),
                    age_steps: age,
                })
                .collect();
            let input = ForecastInput {
                k,
                t_s: k as f64 * 0.1,
                state: state(1, k),
                thrust_prev_n: if k == 0 { [0.0; 3] } else { thrust(1, k - 1) },
                tension_measured_n: [-1.0, -2.0, -3.0],
                neighbours: &nbs,
            };
            let mut out = vec![[0.0; 3]; 4];
            f.forecast(&input, &mut out);
            outs.push(out);
        }
        (outs, f.fallbacks())
    }

    fn expected(e: u64) -> Vec<[f64; 3]> {
        let mut h = Vec::new();
        for m in e - 1..=e {
            let s = Sample {
                own_state: state(1, m),
                neighbour_states: [state(2, m), state(3, m)],
                own_thrust_n: thrust(1, m),
                neighbour_thrust_n: [thrust(2, m), thrust(3, m)],
            };
            s.extend_features(&mut h);
        }
        predictor().predict(&h).unwrap()
    }

    #[test]
    fn the_forecast_predicts_from_the_newest_complete_window() {
        let (outs, fallbacks) = run(1, 6);
        // Windows need samples 0 and 1 complete: sample 1's thrust arrives at k = 2.
        assert_eq!(fallbacks, 2);
        assert!(outs[0].iter().chain(&outs[1]).all(|t| *t == [-1.0, -2.0, -3.0]));
        for k in 2..6u64 {
            let p = expected(k - 1);
            // out[n] is T̂(t_{k+n}) = entry n of the prediction from e = k − 1, then held.
            assert_eq!(outs[k as usize], vec![p[0], p[1], p[1], p[1]], "k = {k}");
            assert_ne!(p[0], p[1]);
        }
    }

    #[test]
    fn a_link_delay_shifts_the_window_not_the_forecast_times() {
        let (outs, fallbacks) = run(2, 6);
        assert_eq!(fallbacks, 3);
        for k in 3..6u64 {
            let p = expected(k - 2);
            // e = k − 2: T̂(t_k) is the prediction's second entry.
            assert_eq!(outs[k as usize], vec![p[1], p[1], p[1], p[1]], "k = {k}");
        }
    }
}
