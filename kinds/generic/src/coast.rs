//! Coast: zero command, nothing shared. Lets a plant be checked on its own (e.g. the orbital plant
//! against Basilisk) through the full runtime.

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};

#[derive(serde::Serialize, serde::Deserialize)]
pub struct Coast;

impl Algorithm for Coast {
    cohort_runtime::serde_checkpoint!();

    fn columns(&self) -> Vec<String> {
        vec!["u_x_mps2".into(), "u_y_mps2".into(), "u_z_mps2".into()]
    }
    fn share(&mut self, _input: &AgentInput<'_>, out: &mut ShareOut) {
        out.command.extend_from_slice(&[0.0; 3]);
    }
    fn step(&mut self, _dt_s: f64, _neighbours: &[Neighbour<'_>]) {}
    fn row(&self, out: &mut Vec<f64>) {
        out.extend_from_slice(&[0.0; 3]);
    }
}
