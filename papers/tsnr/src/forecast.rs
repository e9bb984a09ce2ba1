//! The tension forecast T̂ᵢ the AEMC controller optimises against (Sec. 3.1): the net tension on
//! MU i over the next control steps, from what MU i knows at t_k.
//!
//! The controller only sees the [`TensionForecast`] trait. [`HoldMeasured`] — the latest measured
//! tension held over the horizon — is the forecast every controller can use with no model; the
//! paper's DNN estimator (7)–(11) (`crate::predictor`) is another implementation, which keeps its
//! own history of the inputs it is fed here, one call per control step.

/// What a neighbour last published: its state and thrust, `age_steps` control steps old.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct NeighbourSample {
    pub id: u32,
    /// [r; v] in the target's LVLH frame, m and m/s.
    pub state: [f64; 6],
    /// The thrust it applied from the step of `state` on, N.
    pub thrust_n: [f64; 3],
    /// How many control steps before t_k the sample was taken (1 with no link delay: a
    /// neighbour's step-k share is not in when MU i decides at t_k).
    pub age_steps: u64,
}

/// MU i's knowledge at t_k, one call per control step, in step order.
#[derive(Debug, Clone, Copy)]
pub struct ForecastInput<'a> {
    pub k: u64,
    pub t_s: f64,
    /// Own [r; v] at t_k, m and m/s.
    pub state: [f64; 6],
    /// Own thrust over the previous step [t_{k−1}, t_k), N (zero at k = 0).
    pub thrust_prev_n: [f64; 3],
    /// Net tension on MU i measured at t_k, N.
    pub tension_measured_n: [f64; 3],
    /// The neighbours heard from so far (a neighbour never heard is absent).
    pub neighbours: &'a [NeighbourSample],
}

pub trait TensionForecast: Send {
    /// Write T̂ᵢ(t_k + nΔt) for n = 0..out.len() into `out`, N.
    fn forecast(&mut self, input: &ForecastInput<'_>, out: &mut [[f64; 3]]);
    /// What it remembers between calls, as bytes (for the agent's checkpoints); empty when it
    /// remembers nothing.
    fn save(&self) -> Vec<u8> {
        Vec::new()
    }
    /// Take back what [`TensionForecast::save`] gave.
    fn restore(&mut self, bytes: &[u8]) -> Result<(), String> {
        if bytes.is_empty() { Ok(()) } else { Err(format!("this forecast keeps no state, got {} bytes", bytes.len())) }
    }
}

/// The latest measured tension, held constant over the whole horizon: the assumption of a
/// controller that compensates tension as a disturbance.
#[derive(Debug, Clone, Copy, Default)]
pub struct HoldMeasured;

impl TensionForecast for HoldMeasured {
    fn forecast(&mut self, input: &ForecastInput<'_>, out: &mut [[f64; 3]]) {
        out.fill(input.tension_measured_n);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hold_measured_repeats_the_measurement() {
        let input = ForecastInput {
            k: 3,
            t_s: 0.3,
            state: [0.0; 6],
            thrust_prev_n: [0.0; 3],
            tension_measured_n: [1.0, -2.5, 0.25],
            neighbours: &[],
        };
        let mut out = [[9.0; 3]; 4];
        HoldMeasured.forecast(&input, &mut out);
        assert!(out.iter().all(|t| *t == [1.0, -2.5, 0.25]));
    }
}
