//! Whether a run kept the neighbour rule's assumption ([`crate::swarm::dynamics::neighbours`]),
//! from the plant's telemetry (the truth at every control step):
//!
//! - `max_stray_m`: the largest distance of any vehicle from its straight start→goal segment (the
//!   rule assumes ≤ [`crate::swarm::dynamics::neighbours::STRAY_M`]);
//! - `unlisted_pairs_within_r_comm`: pairs that came within R_comm of each other while one of them
//!   did not list the other (0 when the lists held everyone who mattered; all-to-all lists always
//!   give 0).

use std::collections::BTreeMap;

use cohort_report::Table;
use cohort_runtime::paper::Setup;
use cohort_runtime::record::RunDirs;

use crate::swarm::dynamics::neighbours::distance_from_segment_m;
use crate::swarm::dynamics::setup::distance_m;
use crate::swarm::host::analysis::VehicleEnd;

type V3 = [f64; 3];

/// Every vehicle's position at every plant row, vehicle j at index j − 1.
fn paths(dirs: &RunDirs, n: u32) -> Result<Vec<Vec<V3>>, String> {
    let path = dirs.telemetry().join("plant.csv");
    let names: Vec<String> = (1..=n).flat_map(|j| ["x", "y", "z"].map(|a| format!("a{j}_p_{a}_m"))).collect();
    let t = Table::read_columns(&path, &names).map_err(|e| e.to_string())?;
    let paths = (1..=n)
        .map(|j| {
            let c = ["x", "y", "z"].map(|a| t.col(&format!("a{j}_p_{a}_m")));
            (0..t.rows()).map(|k| [c[0][k], c[1][k], c[2][k]]).collect()
        })
        .collect();
    Ok(paths)
}

/// The two metrics of the module docs, into `m`.
pub fn metrics(
    s: &Setup,
    dirs: &RunDirs,
    ends: &[VehicleEnd],
    r_comm_m: f64,
    m: &mut BTreeMap<String, f64>,
) -> Result<(), String> {
    let p = paths(dirs, s.n_agents())?;
    let mut stray = 0.0f64;
    for (path, end) in p.iter().zip(ends) {
        let Some(start) = path.first() else { continue };
        stray = path.iter().map(|q| distance_from_segment_m(*q, *start, end.goal_m)).fold(stray, f64::max);
    }
    let mut lists = vec![Vec::new(); p.len()];
    for a in &s.agents {
        if let Some(l) = lists.get_mut((a.id as usize).wrapping_sub(1)) {
            *l = a.neighbours.clone();
        }
    }
    let hears = |i: usize, j: usize| lists[i].contains(&(j as u32 + 1));
    let mut unlisted = 0usize;
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            let met = p[i].iter().zip(&p[j]).any(|(a, b)| distance_m(*a, *b) < r_comm_m);
            unlisted += usize::from(met && !(hears(i, j) && hears(j, i)));
        }
    }
    m.insert("max_stray_m".into(), stray);
    m.insert("unlisted_pairs_within_r_comm".into(), unlisted as f64);
    Ok(())
}
