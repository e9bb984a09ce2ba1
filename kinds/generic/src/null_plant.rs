//! No dynamics: every agent reads `readings` zeros. With the `null` algorithm a run costs only
//! its messaging, which is what `orchestrator bench` compares real runs against.

use cohort_runtime::model::PlantModel;
use rand_chacha::ChaCha8Rng;

pub struct NullPlant {
    pub readings: usize,
}

impl PlantModel for NullPlant {
    fn columns(&self) -> Vec<String> {
        Vec::new()
    }
    fn readings(&mut self, _agent: u32, _rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        out.resize(out.len() + self.readings, 0.0);
    }
    fn apply_command(&mut self, _agent: u32, _command: &[f64]) {}
    fn advance(&mut self, _dt_s: f64) {}
    fn row(&self, _out: &mut Vec<f64>) {}
    fn metrics(&self) -> Vec<(String, f64)> {
        Vec::new()
    }
}
