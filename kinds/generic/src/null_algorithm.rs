//! Shares `share_values` zeros and commands zero, computing nothing: the messaging-only baseline
//! of `orchestrator bench`.

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};

#[derive(serde::Serialize, serde::Deserialize)]
pub struct Null {
    pub share_values: usize,
}

impl Algorithm for Null {
    cohort_runtime::serde_checkpoint!();

    fn columns(&self) -> Vec<String> {
        Vec::new()
    }
    fn share(&mut self, _input: &AgentInput<'_>, out: &mut ShareOut) {
        out.command.extend_from_slice(&[0.0; 3]);
        out.values.resize(self.share_values, 0.0);
    }
    fn step(&mut self, _dt_s: f64, _neighbours: &[Neighbour<'_>]) {}
    fn row(&self, _out: &mut Vec<f64>) {}
}
