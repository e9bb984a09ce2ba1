//! `cargo run --release -p cohort-paper-nr --example nr_steptimes -- WEIGHTS [ISO]`: the steps of one
//! NR run that take more than 0.2 ms, with their mode (which steps are slow, and why).
use std::sync::Arc;

use cohort_paper_nr::agent::NrAgent;
use cohort_paper_nr::config::{IsoEncounterConfig, Method, NrAlgorithmConfig, build_plant};
use cohort_paper_nr::sim;
use cohort_paper_nr::sn_dnn::SnDnn;

fn main() {
    let path = std::env::args().nth(1).unwrap();
    let iso: u32 = std::env::args().nth(2).map_or(3, |s| s.parse().unwrap());
    let net = Arc::new(SnDnn::load(std::path::Path::new(&path)).unwrap());
    let cfg = IsoEncounterConfig { iso_index: Some(iso), ..IsoEncounterConfig::default() };
    let mut plant = build_plant(&cfg, 1, 600.0, iso as u64).unwrap();
    let mut a = NrAlgorithmConfig::new(Method::NeuralRendezvous);
    a.weights = Some(path.into());
    let mut agents = [NrAgent::new(a, 600.0, Some(net)).unwrap()];
    let rec = sim::run(&mut plant, &mut agents, 144, 600.0, iso as u64, true);
    for (k, t) in rec.compute_s[0].iter().enumerate() {
        if *t > 2e-4 {
            println!("step {k}: {:.3} ms, mode {}", t * 1e3, rec.agent_rows[k][0][0]);
        }
    }
}
