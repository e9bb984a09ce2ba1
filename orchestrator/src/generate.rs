//! `orchestrator generate <shape> …`: write a scenario of any size. `ring` is the orchestrator's
//! own (the consensus ring of the generic kinds); every other shape is a paper's generator
//! ([`cohort_host::PaperHost::generators`]), found in the registry by its name. Each shape gets
//! `--out`; the text is validated (as `launch` would read it) before it is written.

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, FromArgMatches};
use cohort_host::CommandError;
use cohort_registry::HOSTS;
use cohort_scenario::Overrides;

use crate::{bench, fail};

/// The name of the orchestrator's own shape.
const RING: &str = "ring";

/// `generate ring`'s own arguments.
#[derive(Args)]
struct RingArgs {
    /// Agents (3 to 100 000).
    #[arg(long, value_parser = clap::value_parser!(u32).range(3..=100_000))]
    agents: u32,
    /// Lockstep steps of 0.01 s.
    #[arg(long, default_value_t = 1000, value_parser = clap::value_parser!(u64).range(1..))]
    steps: u64,
}

/// `--out`, which every shape takes.
fn out_arg() -> clap::Arg {
    clap::Arg::new("out")
        .long("out")
        .value_name("OUT")
        .value_parser(clap::value_parser!(PathBuf))
        .help("The scenario file to write (default: stdout)")
}

/// The `generate` command: `ring` and every paper's shapes, each with `--out`.
pub fn command() -> clap::Command {
    let ring = RingArgs::augment_args(clap::Command::new(RING)).about(
        "The consensus ring of the generic kinds: each agent hears its two neighbours, so the subscription \
         graph stays sparse at any N (the bench's ring rows run the same text)",
    );
    let papers = HOSTS.iter().flat_map(|h| h.generators());
    clap::Command::new("generate")
        .about(
            "Write a scenario of any size (a shape: `ring`, or a paper's, e.g. `swarm`). Validated before it is \
             written; to --out or stdout",
        )
        .subcommand_required(true)
        .arg_required_else_help(true)
        .subcommands(std::iter::once(ring).chain(papers).map(|c| c.arg(out_arg())))
}

/// Run `generate`'s subcommand `name` with its `matches`.
pub fn run(name: &str, matches: &clap::ArgMatches) -> ExitCode {
    let out = matches.get_one::<PathBuf>("out").cloned();
    let text = if name == RING {
        match RingArgs::from_arg_matches(matches) {
            Ok(a) => ring_text(a.agents, a.steps),
            Err(e) => Err(CommandError::invalid(e.to_string())),
        }
    } else {
        match HOSTS.iter().find(|h| h.generators().iter().any(|g| g.get_name() == name)) {
            Some(h) => h.run_generator(name, matches),
            None => Err(CommandError::invalid(format!("no shape {name:?} to generate"))),
        }
    };
    match text.and_then(|t| validated(name, &t, out.as_deref()).map(|what| (t, what))) {
        Ok((text, what)) => write(&text, &what, out.as_deref()),
        Err(e) => fail(e),
    }
}

/// The ring's text (the bench's, named `ring-…`); [`validated`] checks it, as every shape's.
fn ring_text(agents: u32, steps: u64) -> Result<String, CommandError> {
    let (_, text) = bench::ring_text(agents, steps, bench::RING);
    Ok(text.replacen("name = \"bench-ring", "name = \"ring", 1))
}

/// Validate `text` as the file it will be (relative paths against `out`'s directory): what it
/// holds, for the "written" line; a shape that writes an invalid scenario is a failure (exit 1).
fn validated(name: &str, text: &str, out: Option<&Path>) -> Result<String, CommandError> {
    let file = out.map_or_else(|| PathBuf::from(format!("{name}.toml")), Path::to_path_buf);
    match cohort_registry::load_text(text, &file, &Overrides::default()) {
        Ok(s) => Ok(format!("{} agents, {} steps of {} s", s.n_agents(), s.n_steps(), s.scenario.dt_s)),
        Err(e) => Err(CommandError::failed(format!("the generated {name} does not validate: {e}"))),
    }
}

fn write(text: &str, what: &str, out: Option<&Path>) -> ExitCode {
    match out {
        None => {
            outln!("{}", text.trim_end());
            ExitCode::SUCCESS
        }
        Some(path) => match std::fs::write(path, text) {
            Ok(()) => {
                outln!("written: {} ({what})", path.display());
                ExitCode::SUCCESS
            }
            Err(e) => fail(CommandError::invalid(format!("--out {}: {e}", path.display()))),
        },
    }
}
