//! Cohort's scenario files: the schema ([`schema`]), parsing with key paths ([`parse`]) and the
//! sanity checks that run before any process starts ([`validate`]).

pub mod dai;
pub mod error;
pub mod faults;
pub mod live_graph;
pub mod parse;
pub mod schema;
pub mod tsnr_formation;
pub mod tsnr_net;
pub mod validate;

pub use error::{Problem, ScenarioError};
pub use parse::{Overrides, load, parse};
pub use schema::*;

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn ring() -> String {
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../topologies/consensus-ring.toml")).unwrap()
    }

    #[test]
    fn consensus_ring_parses_and_round_trips() {
        let s = parse(&ring(), Path::new("ring.toml"), &Overrides::default()).unwrap();
        assert_eq!(s.n_agents(), 6);
        assert_eq!(s.n_steps(), 2000);
        let again = parse(&s.to_toml(), Path::new("resolved.toml"), &Overrides::default()).unwrap();
        assert_eq!(s, again);
    }

    #[test]
    fn errors_name_the_key_path() {
        let bad = ring().replace("kp_per_s2 = 0.5", "kp_per_s2 = 0.5\ngain = 3");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("algorithm.gain"), "{e}");
        let bad = ring().replace("neighbours = [6, 2]", "neighbours = [6, \"two\"]");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("agents[0].neighbours[1]"), "{e}");
        let bad = ring().replace("dt_s = 0.01", "dt_s = nan");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("scenario.dt_s = nan"), "{e}");
        let bad = ring().replace("dt_s = 0.01\n", "");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("scenario.dt_s: required key is missing"), "{e}");
    }

    #[test]
    fn every_problem_is_reported_at_once() {
        let bad = ring().replace("dt_s = 0.01", "dt_s = -0.01").replace("kp_per_s2 = 0.5", "kp_per_s2 = 0.0");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert_eq!(e.problems.len(), 2, "{e}");
    }

    #[test]
    fn overrides_are_validated_too() {
        let o = Overrides { duration_s: Some(f64::INFINITY), ..Default::default() };
        let e = parse(&ring(), Path::new("x.toml"), &o).unwrap_err();
        assert!(e.to_string().contains("scenario.duration_s = inf"), "{e}");
    }
}
