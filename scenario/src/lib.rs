//! Cohort's scenario files: the schema of what every scenario has ([`schema`]), parsing with key
//! paths ([`parse`]) and the generic sanity checks ([`validate`]) — with the [`validate::Checker`]
//! the papers use for their own sections. The `[plant]` and `[algorithm]` sections stay raw here:
//! the runtime hands each to the paper that registered its kind.

pub mod checker;
pub mod digest;
pub mod dispersion;
pub mod error;
pub mod faults;
pub mod hosts;
pub mod links;
pub mod live_graph;
pub mod locate;
pub mod parse;
pub mod schema;
pub mod validate;

pub use checker::{Checker, fmt_f64};
pub use error::{Problem, ScenarioError};
pub use parse::{Overrides, load, load_all, load_all_digested, parse, parse_all, section, section_of};
pub use schema::*;
pub use validate::MessageSizes;

#[cfg(test)]
mod tests {
    use super::*;
    use std::path::Path;

    fn ring() -> String {
        std::fs::read_to_string(concat!(env!("CARGO_MANIFEST_DIR"), "/../topologies/consensus-ring.toml")).unwrap()
    }

    #[test]
    fn consensus_ring_parses() {
        let s = parse(&ring(), Path::new("ring.toml"), &Overrides::default()).unwrap();
        assert_eq!(s.n_agents(), 6);
        assert_eq!(s.n_steps(), 2000);
        assert_eq!(s.plant.kind, "double-integrator");
        assert!(validate::validate(&s).1.is_empty());
    }

    #[test]
    fn a_run_reads_the_same_scenario_from_its_digest_from_a_damaged_one_and_without() {
        let dir = std::env::temp_dir().join(format!("cohort-digest-l-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let file = dir.join("scenario.toml");
        std::fs::write(&file, ring()).unwrap();
        let o = Overrides { step_timeout_s: Some(7.5), ..Default::default() };
        let parsed = load_all(&file, &o).unwrap();
        let ((none, _), why) = load_all_digested(&file, &o).unwrap();
        assert!(matches!(why, Some(digest::DigestError::Read { .. })), "{why:?}");
        assert_eq!(none, parsed.0);
        let mut bytes = digest::encode(&ring()).unwrap();
        std::fs::write(digest::path_for(&file), &bytes).unwrap();
        let (from_digest, why) = load_all_digested(&file, &o).unwrap();
        assert!(why.is_none(), "{why:?}");
        assert_eq!(from_digest, parsed);
        assert_eq!(from_digest.0.run.step_timeout_s, 7.5, "the overrides apply to the digest's table");
        *bytes.last_mut().unwrap() ^= 1;
        std::fs::write(digest::path_for(&file), &bytes).unwrap();
        let ((damaged, _), why) = load_all_digested(&file, &o).unwrap();
        assert!(matches!(why, Some(digest::DigestError::Damaged { .. })), "{why:?}");
        assert_eq!(damaged, parsed.0);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn errors_name_the_key_path() {
        let bad = ring().replace("neighbours = [6, 2]", "neighbours = [6, \"two\"]");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("agents[0].neighbours[1]"), "{e}");
        let bad = ring().replace("dt_s = 0.01\n", "");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("scenario.dt_s: required key is missing"), "{e}");
        let bad = ring().replace("[run]\n", "[run]\nwait = \"sometimes\"\n");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("run.wait = \"sometimes\": must be \"adaptive\", \"event\" or \"poll\""), "{e}");
    }

    #[test]
    fn each_bad_neighbour_is_named_with_its_reason() {
        let bad = ring()
            .replace("neighbours = [6, 2]", "neighbours = [6, 9, 1]")
            .replace("neighbours = [1, 3]", "neighbours = [1, 3, 1]");
        let s = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap();
        let problems: Vec<String> = validate::validate(&s).1.iter().map(|p| p.to_string()).collect();
        assert_eq!(problems.len(), 3, "{problems:?}");
        assert!(problems[0].contains("agents[0].neighbours[1] = 9: not an agent of this scenario"), "{problems:?}");
        assert!(
            problems[1].contains("agents[0].neighbours[2] = 1: an agent cannot be its own neighbour"),
            "{problems:?}"
        );
        assert!(problems[2].contains("agents[1].neighbours[2] = 1: listed twice"), "{problems:?}");
        // An id out of range is reported as such; a neighbour naming it is not "not an agent".
        let odd = ring()
            .replace("id = 6\n", "id = 60\n")
            .replace("neighbours = [4, 6]", "neighbours = [4, 60]")
            .replace("neighbours = [6, 2]", "neighbours = [60, 2]");
        let s = parse(&odd, Path::new("x.toml"), &Overrides::default()).unwrap();
        let problems: Vec<String> = validate::validate(&s).1.iter().map(|p| p.to_string()).collect();
        assert!(problems.iter().any(|p| p.contains("agents[5].id = 60: out of range")), "{problems:?}");
        assert!(!problems.iter().any(|p| p.contains("not an agent")), "{problems:?}");
    }

    #[test]
    fn every_generic_problem_is_reported_at_once() {
        let bad = ring().replace("dt_s = 0.01", "dt_s = -0.01").replace("step_timeout_s = ", "step_timeout_s = -");
        let s = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap();
        assert_eq!(validate::validate(&s).1.len(), 2, "{:?}", validate::validate(&s).1);
    }

    #[test]
    fn overrides_are_validated_too() {
        let o = Overrides { duration_s: Some(f64::INFINITY), ..Default::default() };
        let s = parse(&ring(), Path::new("x.toml"), &o).unwrap();
        assert!(validate::validate(&s).1.iter().any(|p| p.to_string().contains("scenario.duration_s = inf")));
        let o = Overrides { on_agent_loss: Some("maybe".into()), ..Default::default() };
        let e = parse(&ring(), Path::new("x.toml"), &o).unwrap_err();
        assert!(e.to_string().contains("run.on_agent_loss = \"maybe\""), "{e}");
    }

    #[test]
    fn problems_carry_line_and_column_and_unknown_keys_hide_nothing() {
        // Two misspelt keys and a bad type in [run], and a bad dt: four problems, each located.
        let bad = ring()
            .replace("step_timeout_s = 10.0", "step_timout_s = 10.0\nwiat = \"poll\"\nlink_delay_steps = \"one\"")
            .replace("dt_s = 0.01", "dt_s = 0.01\ndt_ss = 3");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err().to_string();
        assert!(e.contains("run.step_timout_s: unknown key (did you mean \"step_timeout_s\"?)"), "{e}");
        assert!(e.contains("run.wiat: unknown key (did you mean \"wait\"?)"), "{e}");
        assert!(e.contains("run.link_delay_steps: invalid type: string \"one\", expected an integer ≥ 0"), "{e}");
        assert!(e.contains("scenario.dt_ss: unknown key (did you mean \"dt_s\"?)"), "{e}");
        assert!(e.lines().all(|l| !l.starts_with("  x.toml: run") || l.contains("x.toml:")), "{e}");
        let line_of = |key: &str| e.lines().find(|l| l.contains(key)).unwrap().to_string();
        assert!(line_of("run.wiat").starts_with("  x.toml:16:1:"), "{e}");
    }

    #[test]
    fn a_toml_syntax_error_keeps_its_place_and_caret() {
        let bad = ring().replace("seed = 7", "seed = = 7");
        let e = parse(&bad, Path::new("x.toml"), &Overrides::default()).unwrap_err().to_string();
        assert!(e.contains("x.toml:9:8: (file): not valid TOML"), "{e}");
        assert!(e.contains("| seed = = 7") && e.contains("|        ^"), "{e}");
    }

    #[test]
    fn out_of_range_seeds_and_step_timeouts_are_problems_with_short_values() {
        // Issue 18, findings 3 and 7: seed 2^63 panicked when the resolved scenario was
        // serialised; a step timeout of 1e-300 s ran and printed it with 300 zeros.
        for seed in [1u64 << 63, u64::MAX] {
            let o = Overrides { seed: Some(seed), ..Default::default() };
            let problems = match parse(&ring(), Path::new("x.toml"), &o) {
                Ok(s) => validate::validate(&s).1.iter().map(|p| p.to_string()).collect::<Vec<_>>(),
                Err(e) => vec![e.to_string()],
            };
            assert!(problems.iter().any(|p| p.contains("scenario.seed")), "seed {seed}: {problems:?}");
        }
        let o = Overrides { seed: Some(validate::MAX_SEED), ..Default::default() };
        assert!(validate::validate(&parse(&ring(), Path::new("x.toml"), &o).unwrap()).1.is_empty());
        let o = Overrides { step_timeout_s: Some(1e-300), ..Default::default() };
        let problems = validate::validate(&parse(&ring(), Path::new("x.toml"), &o).unwrap()).1;
        let text = problems.iter().map(|p| p.to_string()).collect::<String>();
        assert!(text.contains("run.step_timeout_s = 1e-300: must be at least 0.1 s"), "{text}");
        assert!(text.len() < 200, "{text}");
    }

    #[test]
    fn run_record_is_a_bool_off_by_default_and_set_by_its_override() {
        let p = |text: &str, o: &Overrides| parse(text, Path::new("x.toml"), o);
        assert!(!p(&ring(), &Overrides::default()).unwrap().run.record);
        let o = Overrides { record: Some(true), ..Default::default() };
        assert!(p(&ring(), &o).unwrap().run.record);
        let e = p(&ring().replace("[run]\n", "[run]\nrecord = \"yes\"\n"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("run.record: invalid type: string \"yes\""), "{e}");
        let e = p(&ring().replace("[run]\n", "[run]\nrecrod = true\n"), &Overrides::default()).unwrap_err();
        assert!(e.to_string().contains("run.recrod: unknown key (did you mean \"record\"?)"), "{e}");
    }

    #[test]
    fn choices_read_like_the_scenario() {
        let opts = |xs: &[&str]| xs.iter().map(|x| format!("{x:?}")).collect::<Vec<_>>();
        assert_eq!(parse::choice_list(&opts(&["a", "b"])), "\"a\" or \"b\"");
        assert_eq!(parse::choice_list(&opts(&["a", "b", "c"])), "\"a\", \"b\" or \"c\"");
        assert!(parse::choice_list(&opts(&["a", "b", "c", "d", "e"])).starts_with("one of: "));
    }
}
