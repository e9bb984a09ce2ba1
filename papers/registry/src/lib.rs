//! The registry: the only list of papers. The binaries look a scenario's kinds up in [`PAPERS`]
//! (the plant and agent processes) and a paper's analysis, figures and commands up in [`HOSTS`]
//! (the orchestrator). Adding a paper is one line in [`registry!`]'s list below, its dependency in
//! this crate's `Cargo.toml`, and its folder under `papers/` (see `papers/README.md`).

use std::path::Path;

#[cfg(feature = "host")]
use cohort_host::{PaperHost, RunHooks};
use cohort_runtime::paper::{Paper, Setup};
use cohort_scenario::{Overrides, ScenarioError};

/// Declares [`PAPERS`] and [`HOSTS`] from one list of paper values, each of which implements both
/// traits.
macro_rules! registry {
    ($($paper:path),* $(,)?) => {
        /// Every paper's kinds, for configuring a scenario.
        pub static PAPERS: &[&dyn Paper] = &[$(&$paper),*];
        /// Every paper's host side (analysis, figures, commands), in the same order.
        #[cfg(feature = "host")]
        pub static HOSTS: &[&dyn PaperHost] = &[$(&$paper),*];
    };
}

registry! {
    cohort_kinds_generic::Generic,
    cohort_paper_fig1::Fig1,
    cohort_paper_tsnr::Tsnr,
    cohort_paper_dai::Dai,
    cohort_paper_vtxo::Vtxo,
    cohort_paper_nr::Nr,
    cohort_kind_python::Python,
}

/// Read, parse, validate and configure a scenario file with every registered paper.
pub fn load(file: &Path, overrides: &Overrides) -> Result<Setup, ScenarioError> {
    cohort_runtime::paper::load(file, overrides, PAPERS)
}

/// [`load`] of scenario text standing for `file` (see [`cohort_runtime::paper::load_text`]).
pub fn load_text(text: &str, file: &Path, overrides: &Overrides) -> Result<Setup, ScenarioError> {
    cohort_runtime::paper::load_text(text, file, overrides, PAPERS)
}

#[cfg(feature = "host")]
/// The run hooks that serve a run of `setup`, each with its paper's name: those the plant's paper
/// declares for the run's kinds first, then the algorithm's paper's ([`cohort_host::KindHooks::serves`]).
pub fn hooks_of(setup: &Setup) -> Vec<(&'static str, &'static dyn RunHooks)> {
    let hosts = setup.papers.iter().filter_map(|name| HOSTS.iter().find(|h| h.name() == *name));
    hosts.flat_map(|h| h.run_hooks().into_iter().filter(|k| k.serves(setup)).map(|k| (h.name(), k.hooks))).collect()
}

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, ShareOut};

    use super::*;

    fn topologies() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies")
    }

    fn scenario(file: &str) -> Setup {
        load(&topologies().join(file), &Default::default()).unwrap()
    }

    #[test]
    fn kinds_and_names_are_unique_and_hosts_match_papers() {
        let problems = cohort_runtime::paper::registry_problems(PAPERS);
        assert!(problems.is_empty(), "{problems:?}");
        let papers: Vec<&str> = PAPERS.iter().map(|p| p.name()).collect();
        let hosts: Vec<&str> = HOSTS.iter().map(|h| h.name()).collect();
        assert_eq!(papers, hosts);
        let mut trainers: Vec<String> =
            HOSTS.iter().flat_map(|h| h.trainers()).map(|t| t.get_name().to_string()).collect();
        let n = trainers.len();
        trainers.sort();
        trainers.dedup();
        assert_eq!(trainers.len(), n, "two papers register a trainer of the same name: {trainers:?}");
        // `ring` is the orchestrator's own shape of `orchestrator generate`.
        let mut shapes: Vec<String> =
            HOSTS.iter().flat_map(|h| h.generators()).map(|g| g.get_name().to_string()).collect();
        shapes.push("ring".to_string());
        let n = shapes.len();
        shapes.sort();
        shapes.dedup();
        assert_eq!(shapes.len(), n, "two generators of the same shape: {shapes:?}");
    }

    /// Every run-hooks entry names kinds that exist (in its own paper) and at least one of them.
    #[test]
    fn run_hooks_name_registered_kinds() {
        for (paper, host) in PAPERS.iter().zip(HOSTS) {
            for k in host.run_hooks() {
                assert!(k.plant.is_some() || k.algorithm.is_some(), "{}: hooks for every run", paper.name());
                if let Some(p) = k.plant {
                    assert!(
                        PAPERS.iter().any(|q| q.plants().iter().any(|x| x.kind() == p)),
                        "{}: no plant kind {p}",
                        paper.name()
                    );
                }
                if let Some(a) = k.algorithm {
                    assert!(
                        paper.algorithms().iter().any(|x| x.kind() == a),
                        "{}: no algorithm kind {a} of its own",
                        paper.name()
                    );
                }
            }
        }
    }

    /// The hooks picked for the shipped scenarios: each paper's own runs get its hooks, a run of
    /// another paper's or a generic kind gets none of them.
    #[test]
    fn hooks_are_picked_by_the_run_kinds() {
        let names = |file: &str| -> Vec<&str> { hooks_of(&scenario(file)).into_iter().map(|(p, _)| p).collect() };
        assert_eq!(names("fig1.toml"), ["fig1"]);
        assert_eq!(names("consensus-ring.toml"), Vec::<&str>::new());
        assert_eq!(names("vtxo-handoff.toml"), ["vtxo"]);
        assert_eq!(names("nr-iso.toml"), ["nr"]);
        assert_eq!(names("swarm-8.toml"), ["nr"]);
        assert_eq!(names("fig1-coast.toml"), Vec::<&str>::new());
        assert_eq!(names("net-coast.toml"), ["tsnr"]);
    }

    /// Every valid scenario file configures, and its resolved TOML (what the child processes
    /// read from the run directory) configures to the same resolved TOML again.
    #[test]
    fn every_scenario_round_trips_through_its_resolved_toml() {
        let mut n = 0;
        for entry in std::fs::read_dir(topologies()).unwrap() {
            let path = entry.unwrap().path();
            let name = path.file_name().unwrap().to_string_lossy().into_owned();
            if !name.ends_with(".toml") {
                continue;
            }
            let s = load(&path, &Default::default()).unwrap_or_else(|e| panic!("{e}"));
            let resolved = s.to_toml().unwrap();
            let again = cohort_scenario::parse(&resolved, Path::new("resolved.toml"), &Default::default())
                .map_err(|e| e.to_string())
                .and_then(|raw| {
                    cohort_runtime::paper::configure(raw, PAPERS)
                        .map_err(|p| p.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("; "))
                })
                .unwrap_or_else(|e| panic!("{name}: the resolved scenario does not configure: {e}"));
            assert_eq!(again.to_toml().unwrap(), resolved, "{name}");
            n += 1;
        }
        assert!(n >= 10, "only {n} scenarios found");
    }

    /// Run `steps` steps with made-up readings and neighbour values.
    fn drive(a: &mut dyn Algorithm, n_readings: usize, from: u64, steps: u64, out: &mut Vec<f64>) {
        let mut share = ShareOut::default();
        for k in from..from + steps {
            let readings: Vec<f64> = (0..n_readings).map(|r| ((k * 7 + r as u64) % 13) as f64 * 0.1 - 0.6).collect();
            share.command.clear();
            share.values.clear();
            a.share(&AgentInput { k, t_s: k as f64 * 0.01, readings: &readings }, &mut share);
            out.extend(&share.command);
            out.extend(&share.values);
            let nb_values = share.values.clone();
            a.step(0.01, &[Neighbour { id: 2, values: &nb_values, age_steps: 0 }]);
        }
    }

    /// Checkpoints of several algorithm kinds: restoring a saved state into a freshly built agent
    /// gives back the same state, bit for bit, and the same behaviour afterwards.
    #[test]
    fn every_algorithm_restores_its_checkpoint_exactly() {
        for (file, id, n_readings) in [("fig1.toml", 1, 7), ("consensus-ring.toml", 1, 3), ("dai.toml", 1, 3)] {
            let s = scenario(file);
            let mut a = s.algorithm.build(&s, id);
            let mut trace = Vec::new();
            drive(a.as_mut(), n_readings, 0, 20, &mut trace);
            let saved = a.save_state();
            let mut b = s.algorithm.build(&s, id);
            assert_ne!(b.save_state(), saved, "{file}: a fresh agent already equals the stepped one");
            b.restore_state(&saved).unwrap();
            assert_eq!(b.save_state(), saved, "{file}: restored state differs");
            let (mut ta, mut tb) = (Vec::new(), Vec::new());
            drive(a.as_mut(), n_readings, 20, 10, &mut ta);
            drive(b.as_mut(), n_readings, 20, 10, &mut tb);
            let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
            assert_eq!(bits(&ta), bits(&tb), "{file}: behaviour after the restore differs");
            assert!(b.restore_state(&saved[..saved.len() / 2]).is_err(), "{file}: half a state must be refused");
        }
    }

    /// The rows of `papers/README.md`'s table: (folder cell, plant kinds, algorithm kinds), the kinds
    /// read from the third cell's `plant …` / `algorithms …` parts (other parts, e.g. commands,
    /// ignored).
    fn readme_rows() -> Vec<(String, Vec<String>, Vec<String>)> {
        let path = Path::new(env!("CARGO_MANIFEST_DIR")).join("../README.md");
        let text = std::fs::read_to_string(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
        let ticked = |s: &str| -> Vec<String> { s.split('`').skip(1).step_by(2).map(str::to_string).collect() };
        let mut rows = Vec::new();
        for line in text.lines().filter(|l| l.starts_with("| `")) {
            let cells: Vec<&str> = line.split('|').map(str::trim).collect();
            let (Some(folder), Some(kinds)) = (cells.get(1), cells.get(3)) else { continue };
            let (mut plants, mut algorithms) = (Vec::new(), Vec::new());
            for part in kinds.split(';').map(str::trim) {
                if part.starts_with("plant") {
                    plants.extend(ticked(part).into_iter().filter(|k| !k.contains('.') && !k.contains(' ')));
                } else if part.starts_with("algorithm") {
                    // Only the kind names: a parenthesised remark may quote a key (`algorithm.method`).
                    algorithms.extend(ticked(part).into_iter().filter(|k| !k.contains('.') && !k.contains(' ')));
                }
            }
            rows.push((folder.trim_matches('`').to_string(), plants, algorithms));
        }
        rows
    }

    /// `papers/README.md`'s table has one row per registered paper (folder `<name>/`, or
    /// `../kinds/<name>/` for the kinds that are no paper's) naming exactly its plant and algorithm
    /// kinds, and no other row: a paper added without its row, or a kind renamed, fails here.
    #[test]
    fn the_papers_readme_table_matches_the_registry() {
        let rows = readme_rows();
        let mut problems = Vec::new();
        let folder_of = |name: &str| -> [String; 2] { [format!("{name}/"), format!("../kinds/{name}/")] };
        for p in PAPERS {
            let Some((folder, plants, algorithms)) = rows.iter().find(|r| folder_of(p.name()).contains(&r.0)) else {
                problems.push(format!("missing row: paper {:?} (folder `{}/`)", p.name(), p.name()));
                continue;
            };
            let want_plants: Vec<String> = p.plants().iter().map(|k| k.kind().to_string()).collect();
            let want_algorithms: Vec<String> = p.algorithms().iter().map(|k| k.kind().to_string()).collect();
            if *plants != want_plants {
                problems.push(format!("row `{folder}`: plants {plants:?}, the registry has {want_plants:?}"));
            }
            if *algorithms != want_algorithms {
                problems
                    .push(format!("row `{folder}`: algorithms {algorithms:?}, the registry has {want_algorithms:?}"));
            }
        }
        for (folder, _, _) in &rows {
            if !PAPERS.iter().any(|p| folder_of(p.name()).contains(folder)) {
                problems.push(format!("extra row `{folder}`: no registered paper of that name"));
            }
        }
        assert!(problems.is_empty(), "papers/README.md's table disagrees with the registry:\n{}", problems.join("\n"));
    }
}
