//! `orchestrator`: validate scenarios, launch runs (multi-process over iceoryx2, or the in-process
//! reference), supervise, soak, sweep and bench them, and draw their reports. It knows no paper:
//! scenario kinds, analyses, figures, trainers and each paper's own subcommand come from the
//! registry (`papers/registry`).
//!
//! Exit codes: 0 success; 1 the run failed; 2 invalid input (scenario, arguments, run
//! directory); 128 + signal when interrupted (130 for Ctrl-C).

/// `println!` that never panics: a closed stdout (`| head`, `| true`, `> /dev/full`) must not
/// end a run early or change its exit code, so a failed write is ignored.
macro_rules! outln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stdout(), $($t)*);
    }};
}

/// `eprintln!` that never panics (a closed or full stderr), for the same reason.
macro_rules! errln {
    ($($t:tt)*) => {{
        use std::io::Write as _;
        let _ = writeln!(std::io::stderr(), $($t)*);
    }};
}

mod bench;
mod campaign;
mod generate;
mod launcher;
mod links_study;
mod live;
mod progress;
mod reference;
mod replay;
mod rundir;
mod salvage;
mod security_args;
mod soak;
mod summary;
mod sweep_report;
mod terminal;

use std::path::{Path, PathBuf};
use std::process::ExitCode;

use clap::{Args, CommandFactory, FromArgMatches, Parser, Subcommand};
use cohort_host::{CommandError, PaperHost, RunStatus};
use cohort_registry::HOSTS;
use cohort_runtime::exit::ToExitCode;
/// The orchestrator's exit codes besides 0 and 128 + N (see [`cohort_runtime::exit`]).
pub(crate) use cohort_runtime::exit::{FAILED as EXIT_FAILED, INVALID as EXIT_INVALID};
use cohort_runtime::paper::Setup;
use cohort_runtime::record::RunDirs;
use cohort_scenario::Overrides;
use cohort_supervisor::supervise::LaunchOutcome;
use cohort_supervisor::{daemon, supervise, zping};
use tracing::{error, info, warn};

pub(crate) use launcher::{load, prepare, run_once};

/// `-q`: no progress bar either.
static QUIET: std::sync::atomic::AtomicBool = std::sync::atomic::AtomicBool::new(false);

const EXIT_CODES_HELP: &str = "Exit codes:
  0        done (also a divergence study, scenario.expect = \"diverge\", that diverged)
  1        a run failed, diverged unexpectedly or lost an agent it had not planned to; a soak or
           bench check failed
  2        invalid input: a scenario, argument or file, named on stderr
  128 + N  stopped by signal N (every child stopped, the run directory kept)";

/// `--version`: the package version, the git commit built from, and the build id (a digest of
/// every source file, which the plant and agent binaries must share).
fn version() -> &'static str {
    let v = format!(
        "{} (commit {}, build {})",
        env!("CARGO_PKG_VERSION"),
        env!("COHORT_GIT_COMMIT"),
        cohort_build_id::BUILD_ID
    );
    // Once per process, for clap's 'static string.
    Box::leak(v.into_boxed_str())
}

#[derive(Parser)]
#[command(
    name = "orchestrator",
    version,
    about = "Cohort: run decentralised spacecraft-formation algorithms the way they would fly",
    after_help = EXIT_CODES_HELP
)]
struct Cli {
    #[command(subcommand)]
    command: Cmd,
    /// More log lines: -v debug, -vv trace (the children log so too; wins over RUST_LOG, which
    /// decides when neither -v nor -q is given).
    #[arg(short, long, global = true, action = clap::ArgAction::Count)]
    verbose: u8,
    /// Warnings and errors only, no progress bar (wins over RUST_LOG, which decides when neither
    /// -v nor -q is given).
    #[arg(short, long, global = true, conflicts_with = "verbose")]
    quiet: bool,
}

#[derive(Subcommand)]
enum Cmd {
    /// Validate scenario files without running anything (exit 2 if any is invalid).
    Check {
        /// Scenario files (TOML).
        #[arg(required = true)]
        files: Vec<PathBuf>,
    },
    /// Validate a scenario, run it, and write its run directory.
    // Boxed: with the security flags it is by far the largest variant (clippy's large_enum_variant).
    Launch(Box<LaunchArgs>),
    /// Run a scenario multi-process again and again for a wall-clock budget, watching latency
    /// per link, deadline misses, message counts, RSS and iceoryx2 entries (exit 1 when one of
    /// them goes wrong; see soak.md in the output directory).
    Soak {
        /// Scenario file (TOML).
        file: PathBuf,
        /// Wall-clock budget: 10m, 90s, 1h.
        #[arg(long, default_value = "10m")]
        wall: String,
        /// Pace the plant by the wall clock.
        #[arg(long)]
        realtime: bool,
        /// With --realtime: sim seconds per wall second.
        #[arg(long, default_value_t = 1.0, requires = "realtime")]
        rate: f64,
        /// Random faults in every run: a comma list of kinds (kill,freeze,restart,delay,drop,corrupt).
        #[arg(long, value_name = "KINDS")]
        faults: Option<String>,
        /// Output directory; default runs/<scenario>-soak-<UTC time>/.
        #[arg(long)]
        out: Option<PathBuf>,
        /// First run's seed (then +1 per run); default the scenario's.
        #[arg(long, value_parser = seed_arg)]
        seed: Option<u64>,
        #[command(flatten)]
        live: LiveArgs,
    },
    /// Run a scenario once per seed (in-process reference runs by default) and write the
    /// distribution of its summary metrics as Markdown and CSV.
    Sweep {
        /// Scenario file (TOML).
        file: PathBuf,
        #[command(flatten)]
        args: SweepArgs,
    },
    /// A Monte Carlo campaign: run the scenario's [[dispersions]] (or --dispersions FILE's) over
    /// N drawn cases on worker threads, and write campaign.parquet (a row per case: the drawn
    /// values, the metrics, the verdict), campaign.md and plots (docs/monte-carlo.md).
    Campaign {
        /// Scenario file (TOML).
        file: PathBuf,
        #[command(flatten)]
        args: campaign::CampaignArgs,
    },
    /// Inter-satellite links from the geometry ([links] model = "geometric"; docs/links.md).
    #[command(subcommand)]
    Links(links_study::LinksCmd),
    /// Measure what the multi-process runtime costs (see bench/results.md); run from the
    /// repository root.
    Bench {
        /// A short smoke version (fewer cases, fewer steps, one repetition).
        #[arg(long)]
        quick: bool,
        /// Interleaved repetitions of every case.
        #[arg(long)]
        reps: Option<u32>,
        /// Where results.md and results.json go [default: `bench` for a whole run; for `--quick`
        /// or `--only`, `target/bench-partial`, so that a partial run never replaces the
        /// committed tables].
        #[arg(long)]
        out: Option<PathBuf>,
        /// Only the cases whose key starts with this, e.g. `headline/` or `ring/N=20` (the keys are in
        /// results.json).
        #[arg(long, value_name = "PREFIX")]
        only: Option<String>,
        /// Keep every run's directory (telemetry, timing, logs, status) under this directory,
        /// one per case and repetition, instead of removing it after the run is measured.
        #[arg(long, value_name = "DIR")]
        keep_runs: Option<PathBuf>,
    },
    /// Serve this machine to multi-host runs: a long-lived daemon that starts, signals and
    /// watches this machine's plant and agent processes for an orchestrator (see the README's
    /// "Multi-host" section). Stops on Ctrl-C or SIGTERM, killing what it started.
    Host {
        /// The zenoh endpoint to listen on, tcp/<address>:<port> (e.g. tcp/0.0.0.0:7447), or
        /// tls/<address>:<port> with --tls-ca/--tls-cert/--tls-key.
        #[arg(long)]
        listen: String,
        /// The name scenarios give this machine in [[hosts]] (default: the host name).
        #[arg(long)]
        name: Option<String>,
        /// How many campaign cases (`orchestrator campaign --hosts`) it runs at once (default:
        /// the machine's cores).
        #[arg(long, value_parser = clap::value_parser!(u64).range(1..=1024))]
        workers: Option<u64>,
        #[command(flatten)]
        security: security_args::SecurityArgs,
    },
    /// (internal) A host's gateway of a run with `run.zenoh_links = "gateway"`: started by the
    /// orchestrator and the host daemons, never by hand.
    #[command(hide = true)]
    Gateway(cohort_supervisor::gateway::GatewayArgs),
    /// (bench) Echo zenoh pings, listening on an endpoint.
    #[command(hide = true)]
    ZenohEcho {
        #[arg(long)]
        listen: String,
    },
    /// (bench) Time zenoh round trips to a zenoh-echo; prints one JSON line.
    #[command(hide = true)]
    ZenohPing {
        #[arg(long)]
        connect: String,
        #[arg(long, default_value_t = 200)]
        warmup: u64,
        #[arg(long, default_value_t = 5000)]
        count: u64,
    },
    /// Re-run one agent of a run recorded with `launch --record` against its recorded
    /// measurements and neighbour shares, and check that every share it sends equals the recorded
    /// one bit for bit (exit 1 naming the first difference: step, byte, field, both values).
    Replay {
        /// A run directory written by `launch --record`.
        run_dir: PathBuf,
        /// The agent to replay (1..=N).
        #[arg(long)]
        agent: u32,
        /// Only this incarnation of the agent: 0 its first process, N its N-th relaunch by a
        /// `restart` fault (recorded to agent-<I>.<N>.mcap). Default: every one it recorded.
        #[arg(long)]
        incarnation: Option<u32>,
        /// Where the replayed agent's telemetry goes; default RUN_DIR/replay/agent-<I>/ (a
        /// relaunch's, when every incarnation is replayed, beside it: <DIR>.<N>).
        #[arg(long)]
        out: Option<PathBuf>,
    },
    /// Turn the `.rows` journals of a run whose orchestrator was killed into its telemetry and
    /// timing files, and write its missing summary.json (status "salvaged"); a damaged journal is
    /// named and left, the others are turned all the same (exit 1 if one could not be).
    Salvage {
        /// A run directory written by `launch`.
        run_dir: PathBuf,
    },
    /// Draw PNG plots of a run directory's telemetry into RUN_DIR/plots/.
    Report {
        /// A run directory written by `launch`.
        run_dir: PathBuf,
    },
    /// Print a shell completion script on stdout (e.g. `orchestrator completions bash >
    /// ~/.local/share/bash-completion/completions/orchestrator`).
    Completions {
        /// bash, zsh, fish, elvish or powershell.
        shell: clap_complete::Shell,
    },
    /// Write the manual pages: orchestrator.1 and one page per command (orchestrator-launch.1, …).
    Man {
        /// Directory for the pages (created if missing).
        #[arg(long, default_value = "man")]
        out: PathBuf,
    },
}

#[derive(Args)]
struct LaunchArgs {
    /// Scenario file (TOML).
    file: PathBuf,
    /// Run directory (absent or empty); default runs/<scenario>-<UTC time>/.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Override scenario.seed (0 to 2^63 − 1).
    #[arg(long, value_parser = seed_arg)]
    seed: Option<u64>,
    /// Override scenario.duration_s, in seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Override run.step_timeout_s, in seconds.
    #[arg(long)]
    step_timeout: Option<f64>,
    /// Run the plant and every agent as threads of this process over the in-memory
    /// transport (the bit-identical reference of the multi-process run).
    #[arg(long)]
    reference: bool,
    /// With --reference: the plant and every agent as coroutines of one thread instead of a
    /// thread each (the same telemetry, one core; what `campaign` runs its cases as).
    #[arg(long, requires = "reference")]
    one_thread: bool,
    #[command(flatten)]
    security: security_args::SecurityArgs,
    /// Do not draw the plots after a successful run.
    #[arg(long)]
    no_plots: bool,
    /// Print the run's summary (summary.json) on stdout and nothing else there; the human text
    /// goes to stderr. The exit code is the same.
    #[arg(long)]
    json: bool,
    /// Override run.wait: adaptive, event or poll.
    #[arg(long)]
    wait: Option<String>,
    /// Override run.spin_us (the adaptive spin budget), µs.
    #[arg(long)]
    spin_us: Option<f64>,
    /// Override run.link_delay_steps (0 or 1).
    #[arg(long)]
    link_delay: Option<u32>,
    /// Override run.transport: iceoryx2, udp or zenoh.
    #[arg(long)]
    transport: Option<String>,
    /// With zenoh: gateway (one gateway process per host carries what crosses hosts; the
    /// default) or peers (every process its own zenoh peer). Sets run.zenoh_links.
    #[arg(long, value_name = "gateway|peers")]
    zenoh_links: Option<String>,
    /// Machines of a multi-host run: a TOML file of [[hosts]] (name, endpoint, and optionally
    /// plant = true / agents = [ids] placing the processes), replacing the scenario's.
    #[arg(long, value_name = "FILE")]
    hosts: Option<PathBuf>,
    /// Pace the plant by the wall clock (sets run.realtime_rate).
    #[arg(long)]
    realtime: bool,
    /// With --realtime: sim seconds per wall second.
    #[arg(long, default_value_t = 1.0, requires = "realtime")]
    rate: f64,
    /// What a dead or silent agent does to the run: degrade (go on without it; exit 1 at the
    /// end if the loss was not planned) or abort (sets run.on_agent_loss).
    #[arg(long, value_name = "degrade|abort")]
    on_agent_loss: Option<String>,
    /// Seal every message with a keyed MAC and reject any without a valid tag (sets
    /// run.authenticate).
    #[arg(long)]
    authenticate: bool,
    /// Record every measurement and share each agent receives or sends, as its wire bytes, to
    /// RUN_DIR/record/agent-<i>.mcap (opens in Foxglove; `orchestrator replay` reads it). Sets
    /// run.record; changes no result.
    #[arg(long)]
    record: bool,
    /// Inject a fault (repeatable): KIND:agent=ID@t=SECONDS[,for=SECONDS][,p=PROB][,steps=N],
    /// KIND one of kill, freeze, restart, delay, drop, corrupt (see topologies/README.md).
    #[arg(long, value_name = "SPEC")]
    fault: Vec<String>,
    /// Format of the telemetry files (sets run.telemetry; default parquet).
    #[arg(long, value_name = "parquet|csv")]
    telemetry: Option<String>,
    #[command(flatten)]
    live: LiveArgs,
}

/// `--live [ADDR] [--live-rate HZ]` (launch and soak).
#[derive(Args)]
struct LiveArgs {
    /// Serve a live view of the run (3-D scene, every process's telemetry, roster and faults,
    /// progress) over the Foxglove WebSocket protocol at ADDR; open it in Foxglove with "Open
    /// connection" → ws://ADDR (docs/recording.md). Changes no result.
    #[arg(long, value_name = "ADDR", num_args = 0..=1, default_missing_value = "127.0.0.1:8765")]
    live: Option<String>,
    /// With --live: scene and telemetry messages per second of sim time.
    #[arg(long, value_name = "HZ", default_value_t = 20.0, requires = "live")]
    live_rate: f64,
}

impl LiveArgs {
    /// Start the server when asked (before anything runs): a bad address or rate, or a port in
    /// use, is exit 2.
    fn start(&self) -> Result<(), ExitCode> {
        let Some(addr) = &self.live else { return Ok(()) };
        match live::start(live::Options { addr: addr.clone(), rate_hz: self.live_rate }) {
            Ok(server) => {
                info!("live view: ws://{addr} (port {}; Foxglove → Open connection)", server.port());
                Ok(())
            }
            Err(e) => {
                error!("{e}");
                Err(ExitCode::from(EXIT_INVALID))
            }
        }
    }
}

#[derive(Args)]
struct SweepArgs {
    /// Number of seeds (1 to 100 000).
    #[arg(long, default_value_t = 10, value_parser = clap::value_parser!(u64).range(1..=100_000))]
    seeds: u64,
    /// First seed; the sweep uses first-seed, first-seed + 1, ...
    #[arg(long, default_value_t = 1, value_parser = seed_arg)]
    first_seed: u64,
    /// Directory for the runs and the results; default runs/<scenario>-sweep-<UTC time>/.
    #[arg(long)]
    out: Option<PathBuf>,
    /// Override scenario.duration_s, in seconds.
    #[arg(long)]
    duration: Option<f64>,
    /// Run every seed multi-process instead of in-process (the two are bit-identical; the
    /// in-process reference is faster).
    #[arg(long)]
    multi_process: bool,
    /// Keep each run's telemetry (a headline run can be ~130 MB).
    #[arg(long)]
    keep_telemetry: bool,
}

/// A seed: 0 to 2^63 − 1 (the resolved scenario stores it as a TOML integer).
fn seed_arg(s: &str) -> Result<u64, String> {
    let max = cohort_scenario::validate::MAX_SEED;
    match s.parse::<u64>() {
        Ok(v) if v <= max => Ok(v),
        _ => Err(format!("must be a whole number from 0 to {max} (2^63 − 1)")),
    }
}

/// The full command line: the generic subcommands, `generate` with the ring and every paper's
/// shapes, `train` with every paper's trainers, and each paper's own subcommand.
fn command_line() -> clap::Command {
    let trainers: Vec<clap::Command> = HOSTS.iter().flat_map(|h| h.trainers()).collect();
    let train = clap::Command::new("train")
        .about("Train a learned model offline and write its weights file and a report beside it")
        .subcommand_required(true)
        .arg_required_else_help(true)
        .subcommands(trainers);
    let papers = HOSTS.iter().filter_map(|h| h.command().map(|c| c.name(h.name())));
    Cli::command().version(version()).subcommand(generate::command()).subcommand(train).subcommands(papers)
}

/// `orchestrator man --out DIR`: the top page and one per command, subcommands included.
fn write_man_pages(out: &Path) -> Result<Vec<PathBuf>, String> {
    std::fs::create_dir_all(out).map_err(|e| format!("{}: {e}", out.display()))?;
    let mut written = Vec::new();
    let mut stack = vec![("orchestrator".to_string(), command_line())];
    while let Some((name, cmd)) = stack.pop() {
        let path = out.join(format!("{name}.1"));
        let mut buf = Vec::new();
        // clap keeps names as 'static strings; a few dozen short ones for a one-shot command.
        let page_name: &'static str = Box::leak(name.clone().into_boxed_str());
        clap_mangen::Man::new(cmd.clone().name(page_name))
            .render(&mut buf)
            .map_err(|e| format!("{}: {e}", path.display()))?;
        std::fs::write(&path, buf).map_err(|e| format!("{}: {e}", path.display()))?;
        written.push(path);
        for sub in cmd.get_subcommands().filter(|s| s.get_name() != "help") {
            stack.push((format!("{name}-{}", sub.get_name()), sub.clone()));
        }
    }
    written.sort();
    Ok(written)
}

fn main() -> ExitCode {
    // First: the handshakes, recordings and `--version` read the id through cohort_wire.
    cohort_wire::set_build_id(cohort_build_id::BUILD_ID);
    // A run is its user's own: every file, directory and shared-memory segment this process and
    // its children create is owner-only.
    // SAFETY: umask(2) cannot fail.
    unsafe { libc::umask(0o077) };
    // Descriptors grow with a run's size (iceoryx2 ports); children inherit the raised limit.
    cohort_wire::limits::raise_nofile_to_hard();
    let matches = command_line().get_matches();
    let quiet = matches.get_flag("quiet");
    let verbose = matches.get_count("verbose");
    // A flag typed on the command line wins over RUST_LOG from the environment.
    let flagged = quiet || verbose > 0;
    cohort_runtime::logging::init_orchestrator(cohort_runtime::logging::level_of(verbose, quiet), flagged);
    QUIET.store(quiet, std::sync::atomic::Ordering::Relaxed);
    // Commands that run things stop them in order on Ctrl-C, SIGTERM or SIGHUP and exit 128 +
    // signal; `check` and `report` only read, `salvage` only converts files and `train` only
    // computes: they die on the signal as usual.
    if !matches!(matches.subcommand_name(), Some("check" | "report" | "salvage" | "train"))
        && let Err(e) = supervise::install_signal_handlers()
    {
        return fail(e);
    }
    match matches.subcommand() {
        Some(("train", m)) => {
            let Some((name, sub)) = m.subcommand() else {
                return ExitCode::from(EXIT_INVALID);
            };
            let host = HOSTS.iter().find(|h| h.trainers().iter().any(|t| t.get_name() == name));
            match host {
                Some(h) => {
                    for (key, value) in h.trainer_env(name) {
                        if std::env::var_os(key).is_none() {
                            // SAFETY: no other thread exists yet: `train` installs no signal
                            // handler and nothing before this point spawns a thread, so nothing
                            // can read the environment while it changes.
                            unsafe { std::env::set_var(key, value) };
                        }
                    }
                    finish(h.run_trainer(name, sub))
                }
                None => fail(CommandError::invalid(format!("no trainer {name:?}"))),
            }
        }
        Some(("generate", m)) => match m.subcommand() {
            Some((shape, sub)) => generate::run(shape, sub),
            None => ExitCode::from(EXIT_INVALID),
        },
        Some((name, sub)) if HOSTS.iter().any(|h| h.name() == name) => {
            let host: &dyn PaperHost = *HOSTS.iter().find(|h| h.name() == name).expect("checked by the guard");
            finish(host.run_command(sub, &launcher::Orchestrator))
        }
        _ => match Cli::from_arg_matches(&matches) {
            Ok(cli) => generic(cli.command),
            Err(e) => e.exit(),
        },
    }
}

/// A paper command's result on stdout, or its error on stderr with its exit code.
fn finish(result: Result<String, CommandError>) -> ExitCode {
    match result {
        Ok(text) => {
            outln!("{text}");
            ExitCode::SUCCESS
        }
        Err(e) => fail(e),
    }
}

/// An error on stderr (through the log) and the exit code its type gives: how a command ends
/// when it fails.
fn fail<E: std::fmt::Display + ToExitCode>(e: E) -> ExitCode {
    error!("{e}");
    e.to_exit()
}

fn generic(command: Cmd) -> ExitCode {
    match command {
        Cmd::Check { files } => check(&files),
        Cmd::Launch(a) => launch_command(*a),
        Cmd::Sweep { file, args } => sweep(&file, &args),
        Cmd::Campaign { file, args } => campaign::command(&file, &args),
        Cmd::Links(cmd) => links_study::command(&cmd),
        Cmd::Soak { file, wall, realtime, rate, faults, out, seed, live } => {
            if let Err(code) = live.start() {
                return code;
            }
            soak_command(file, &wall, realtime, rate, faults.as_deref(), out, seed)
        }
        Cmd::Bench { quick, reps, out, only, keep_runs } => {
            let out = out.unwrap_or_else(|| bench::default_out(quick, only.as_deref()));
            bench_command(quick, reps, &out, only.as_deref(), keep_runs.as_deref())
        }
        Cmd::Completions { shell } => {
            let mut cmd = command_line();
            let mut buf = Vec::new();
            clap_complete::generate(shell, &mut cmd, "orchestrator", &mut buf);
            outln!("{}", String::from_utf8_lossy(&buf).trim_end());
            ExitCode::SUCCESS
        }
        Cmd::Man { out } => match write_man_pages(&out) {
            Ok(pages) => {
                outln!("written: {} pages in {}", pages.len(), out.display());
                ExitCode::SUCCESS
            }
            Err(e) => fail(CommandError::failed(e)),
        },
        Cmd::Host { listen, name, workers, security } => {
            let workers =
                workers.map_or_else(|| std::thread::available_parallelism().map_or(1, usize::from), |w| w as usize);
            let cases = daemon::Cases { workers, runner: campaign::serve::runner() };
            match security.install().map_err(daemon::DaemonError::from).and_then(|()| daemon::run(&listen, name, cases))
            {
                Ok(()) => ExitCode::SUCCESS,
                Err(e) => fail(e),
            }
        }
        Cmd::Gateway(args) => cohort_supervisor::gateway::main(args, cohort_registry::PAPERS),
        Cmd::ZenohEcho { listen } => match zping::echo(&listen) {
            Ok(()) => ExitCode::SUCCESS,
            Err(e) => fail(e),
        },
        Cmd::ZenohPing { connect, warmup, count } => match zping::ping(&connect, warmup, count) {
            Ok(line) => {
                outln!("{line}");
                ExitCode::SUCCESS
            }
            Err(e) => fail(e),
        },
        Cmd::Replay { run_dir, agent, incarnation, out } => {
            replay::command(&run_dir, agent, incarnation, out.as_deref())
        }
        Cmd::Salvage { run_dir } => salvage::command(&run_dir),
        Cmd::Report { run_dir } => match launcher::report(&run_dir) {
            Ok(files) => {
                for f in files {
                    outln!("{}", f.display());
                }
                ExitCode::SUCCESS
            }
            Err(e) => fail(CommandError::invalid(e.to_string())),
        },
    }
}

/// `orchestrator soak`: the arguments checked (exit 2), then the soak (exit 1 when it found a
/// problem).
fn soak_command(
    file: PathBuf,
    wall: &str,
    realtime: bool,
    rate: f64,
    faults: Option<&str>,
    out: Option<PathBuf>,
    seed: Option<u64>,
) -> ExitCode {
    let wall = match soak::parse_wall(wall) {
        Ok(w) => w,
        Err(e) => return fail(CommandError::invalid(e)),
    };
    let faults = match faults.map(soak::parse_fault_kinds).transpose() {
        Ok(f) => f.unwrap_or_default(),
        Err(e) => return fail(CommandError::invalid(e)),
    };
    if realtime && !(rate.is_finite() && rate > 0.0) {
        return fail(CommandError::invalid(format!("--rate {rate}: must be a positive number")));
    }
    let out = out.unwrap_or_else(|| {
        let stem = file.file_stem().map(|s| s.to_string_lossy().to_string()).unwrap_or_default();
        PathBuf::from(format!("runs/{stem}-soak-{}", cohort_host::utc_stamp()))
    });
    let o = soak::Options { file, wall, realtime, rate, faults, out, seed };
    match soak::run(&o) {
        Ok((md, ok)) => {
            outln!("{md}");
            outln!("written: {} (soak.md, soak.json, *.png)", o.out.display());
            if ok { ExitCode::SUCCESS } else { ExitCode::from(EXIT_FAILED) }
        }
        Err(e) => fail(CommandError::invalid(e)),
    }
}

/// `orchestrator bench`: exit 2 when `--only` chooses nothing, 1 when a case failed.
fn bench_command(quick: bool, reps: Option<u32>, out: &Path, only: Option<&str>, keep: Option<&Path>) -> ExitCode {
    match bench::run(quick, reps.unwrap_or(if quick { 1 } else { 3 }), only, out, keep) {
        Ok(md) => {
            outln!("{md}");
            outln!("written: {} and {}", out.join("results.md").display(), out.join("results.json").display());
            ExitCode::SUCCESS
        }
        Err(e) => fail(e),
    }
}

fn check(files: &[PathBuf]) -> ExitCode {
    let mut bad = false;
    for f in files {
        match load(f, &Overrides::default()) {
            Ok(s) => {
                outln!("ok: {} ({} agents, {} steps of {} s)", f.display(), s.n_agents(), s.n_steps(), s.scenario.dt_s)
            }
            Err(e) => {
                errln!("{e}");
                bad = true;
            }
        }
    }
    if bad { ExitCode::from(EXIT_INVALID) } else { ExitCode::SUCCESS }
}

fn load_or_exit(file: &Path, o: &Overrides) -> Result<Setup, ExitCode> {
    load(file, o).map_err(|e| {
        errln!("{e}");
        e.to_exit()
    })
}

fn launch_command(a: LaunchArgs) -> ExitCode {
    if let Err(e) = a.security.install() {
        return fail(e);
    }
    if let Err(code) = a.live.start() {
        return code;
    }
    let mut faults = Vec::new();
    for (k, f) in a.fault.iter().enumerate() {
        match cohort_scenario::faults::FaultSpec::parse_cli(f) {
            Ok(spec) => faults.push(spec),
            Err(e) => return fail(CommandError::invalid(format!("--fault (#{}): {e}", k + 1))),
        }
    }
    let hosts = match a.hosts.as_deref().map(cohort_scenario::hosts::HostsFile::load).transpose() {
        Ok(h) => h,
        Err(e) => {
            errln!("{e}");
            return e.to_exit();
        }
    };
    let o = Overrides {
        hosts,
        seed: a.seed,
        duration_s: a.duration,
        step_timeout_s: a.step_timeout,
        wait: a.wait,
        spin_us: a.spin_us,
        link_delay_steps: a.link_delay,
        transport: a.transport,
        zenoh_links: a.zenoh_links,
        realtime_rate: a.realtime.then_some(a.rate),
        faults,
        on_agent_loss: a.on_agent_loss,
        authenticate: a.authenticate.then_some(true),
        record: a.record.then_some(true),
        telemetry: a.telemetry,
    };
    launch(&a.file, a.out.as_deref(), &o, (a.reference, a.one_thread), !a.no_plots, a.json)
}

/// A signal that came while the scenario was read or the hosts were asked (the handlers are
/// installed first, so it was recorded): 128 + signal before anything was created.
fn interrupted_before_the_run() -> Option<ExitCode> {
    let sig = supervise::SIGNALLED.load(std::sync::atomic::Ordering::SeqCst);
    (sig != 0).then(|| {
        errln!("interrupted by signal {sig} before the run started; nothing was created");
        RunStatus::Interrupted(sig as i32).to_exit()
    })
}

/// Human text at the end of a launch: on stdout, or on stderr when stdout carries the JSON.
macro_rules! humanln {
    ($json:expr, $($t:tt)*) => {{
        if $json {
            errln!($($t)*);
        } else {
            outln!($($t)*);
        }
    }};
}

/// `mode`: (--reference, --one-thread).
fn launch(file: &Path, out: Option<&Path>, o: &Overrides, mode: (bool, bool), plots: bool, json: bool) -> ExitCode {
    let s = match load_or_exit(file, o) {
        Ok(s) => s,
        Err(code) => return code,
    };
    let reference = mode.0;
    let how = match mode {
        (false, _) => launcher::How::Processes,
        (true, one_thread) => launcher::How::in_process(&s, one_thread),
    };
    if let Some(code) = interrupted_before_the_run() {
        return code;
    }
    if let Some(code) = refused(&s, file, reference) {
        return code;
    }
    let dirs = match prepare(&s, out) {
        Ok(d) => d,
        Err(e) => return e.to_exit(),
    };
    announce(&s, file, reference, &dirs);
    let (outcome, summary) = launcher::run_once_as(&s, &dirs, how, !QUIET.load(std::sync::atomic::Ordering::Relaxed));
    if let Some(code) = failed(&s, &outcome, &summary, &dirs, json) {
        return code;
    }
    print_done(&s, &outcome, &summary, &dirs, json);
    if plots && let Some(code) = draw_plots(&dirs, json) {
        return code;
    }
    if json {
        print_json(&dirs.root);
    }
    outcome.status.to_exit()
}

/// What `launch` refuses before it creates anything: process faults in a reference run; hosts
/// that are not reachable, named as the scenario says and of this build (a signal while asking
/// them ends it too).
fn refused(s: &Setup, file: &Path, reference: bool) -> Option<ExitCode> {
    if reference && let Some(why) = reference_refusal(s, "drop --reference") {
        return Some(fail(CommandError::invalid(why)));
    }
    if !reference && !s.hosts.is_empty() {
        // Every daemon reachable, named as the scenario says, of this build: before anything starts.
        if let Err(e) = cohort_supervisor::preflight(&s.hosts) {
            error!("{}: {e}", file.display());
            return Some(e.to_exit());
        }
        if let Some(code) = interrupted_before_the_run() {
            return Some(code);
        }
    }
    None
}

/// Why an in-process reference run cannot fly `s`, if it cannot: a process fault (kill, freeze,
/// restart) signals a process, and the reference's agents are threads. `remedy` says what to do.
pub(crate) fn reference_refusal(s: &Setup, remedy: &str) -> Option<String> {
    let f = s.faults.iter().find(|f| f.is_process_fault())?;
    Some(format!(
        "an in-process reference run has every process as a thread of this one, so it cannot {} agent {} \
         (process faults signal processes); {remedy}, or keep only delay, drop and corrupt faults",
        f.kind, f.agent
    ))
}

/// The launch's first lines: the mode, the scenario's notes, what --reference and run.record do
/// not do here.
fn announce(s: &Setup, file: &Path, reference: bool, dirs: &RunDirs) {
    let mode = match s.algorithm.coupled() {
        Some(c) => c.describe(),
        None if reference => "reference",
        None => "multi-process",
    };
    info!(
        "launching {} ({mode}): {} agents, {} steps of {} s, seed {} → {}",
        file.display(),
        s.n_agents(),
        s.n_steps(),
        s.scenario.dt_s,
        s.scenario.seed,
        dirs.root.display()
    );
    for n in &s.notes {
        info!("{n}");
    }
    if s.run.record
        && let Some(c) = s.algorithm.coupled()
    {
        info!("run.record records nothing here: the scenario is {} (no messages between processes)", c.describe());
    }
    if reference && let Some(c) = s.algorithm.coupled() {
        info!(
            "--reference changes nothing here: the scenario is {} by design; there is no \
             separate multi-process run to compare",
            c.describe()
        );
    }
}

/// A run that failed, said (root cause first, then what it left undone) with its exit code; a
/// divergence is a result, said and not a failure.
fn failed(
    s: &Setup,
    outcome: &LaunchOutcome,
    summary: &summary::Summary,
    dirs: &RunDirs,
    json: bool,
) -> Option<ExitCode> {
    let expect_divergence = s.scenario.expect == cohort_scenario::Expect::Diverge;
    if matches!(outcome.status, RunStatus::Diverged { .. }) {
        // A divergence is a result: its time and last metrics are printed and plotted like a
        // completed run's (the run directory holds the telemetry up to it).
        let e = outcome.error.as_deref().unwrap_or_default();
        if expect_divergence {
            errln!("diverged, as this study expects (scenario.expect = \"diverge\"): {e}");
        } else {
            error!("{e}");
        }
    } else if let Some(e) = &outcome.error {
        // The root cause first, then what it left undone.
        error!("{e}");
        for w in &summary.warnings {
            warn!("{w}");
        }
        errln!("run directory (partial): {}", dirs.root.display());
        if json {
            print_json(&dirs.root);
        }
        return Some(outcome.status.to_exit());
    }
    if expect_divergence && outcome.status == RunStatus::Ok {
        warn!("scenario.expect = \"diverge\", but the run completed every step");
    }
    None
}

/// The end of a run that did not fail: steps, speed, its metrics, real-time deadline misses and
/// where its recording is.
fn print_done(s: &Setup, outcome: &LaunchOutcome, summary: &summary::Summary, dirs: &RunDirs, json: bool) {
    humanln!(
        json,
        "{}: {} steps in {:.3} s wall ({:.0} steps/s); run directory: {}",
        if matches!(outcome.status, RunStatus::Diverged { .. }) { "diverged" } else { "done" },
        summary.steps_completed,
        outcome.wall_s,
        summary.steps_per_s,
        dirs.root.display()
    );
    let text = terminal::render(summary);
    if !text.is_empty() {
        humanln!(json, "{}", text.trim_end());
    }
    if s.run.realtime_rate.is_some()
        && let Some(plant) = summary.processes.iter().find(|p| p.process == "plant")
    {
        match plant.faults.deadline_misses {
            0 => humanln!(json, "real time: no deadline missed"),
            n => humanln!(
                json,
                "real time: {n} deadline misses (each flew the agent's previous command: this run's telemetry \
                 depends on timing, not only on scenario and seed)"
            ),
        }
    }
    if s.run.record && s.algorithm.coupled().is_none() {
        let dir = cohort_runtime::recording::dir(&dirs.root);
        errln!(
            "recorded: {} (one MCAP per agent; orchestrator replay {} --agent I)",
            dir.display(),
            dirs.root.display()
        );
    }
}

/// The run's plots (a signal while drawing ends the orchestrator: its exit code).
fn draw_plots(dirs: &RunDirs, json: bool) -> Option<ExitCode> {
    match report_unless_signalled(&dirs.root) {
        Ok(Ok(_)) => humanln!(json, "plots: {}", dirs.root.join("plots").display()),
        Ok(Err(e)) => warn!("plots not drawn: {e}"),
        Err(sig) => {
            errln!(
                "interrupted by signal {sig} while drawing the plots; the run directory {} is complete \
                 (orchestrator report draws them)",
                dirs.root.display()
            );
            return Some(RunStatus::Interrupted(i32::from(sig)).to_exit());
        }
    }
    None
}

/// The plots of a finished run, drawn on a thread while this one watches for a signal: Ctrl-C or
/// SIGTERM while drawing ends the orchestrator at once (128 + signal) instead of being recorded
/// and ignored. `Err(signal)` then; the drawing thread ends with the process.
fn report_unless_signalled(run_dir: &Path) -> Result<Result<Vec<PathBuf>, cohort_host::PlotRunError>, u8> {
    let dir = run_dir.to_path_buf();
    let drawing = std::thread::spawn(move || launcher::report(&dir));
    loop {
        let sig = supervise::SIGNALLED.load(std::sync::atomic::Ordering::SeqCst);
        if sig != 0 {
            return Err(sig as u8);
        }
        if drawing.is_finished() {
            return Ok(drawing.join().unwrap_or(Err(cohort_host::PlotRunError::Panicked)));
        }
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
}

/// `--json`: the run's summary.json, as written, on stdout (a summary that could not be written
/// has already been reported on stderr).
fn print_json(run_dir: &Path) {
    match std::fs::read_to_string(run_dir.join("summary.json")) {
        Ok(text) => {
            use std::io::Write as _;
            let _ = std::io::stdout().write_all(text.as_bytes());
        }
        Err(e) => error!("{}: {e}", run_dir.join("summary.json").display()),
    }
}

fn sweep(file: &Path, args: &SweepArgs) -> ExitCode {
    if args.first_seed.checked_add(args.seeds - 1).is_none_or(|last| last > cohort_scenario::validate::MAX_SEED) {
        return fail(CommandError::invalid(format!(
            "--first-seed {} --seeds {}: the last seed passes 2^63 − 1",
            args.first_seed, args.seeds
        )));
    }
    // Validate once up front, with the first seed, so a bad file fails before any run.
    let o = |seed| Overrides { seed: Some(seed), duration_s: args.duration, ..Default::default() };
    let first = match load_or_exit(file, &o(args.first_seed)) {
        Ok(s) => s,
        Err(code) => return code,
    };
    if !args.multi_process
        && let Some(why) = reference_refusal(&first, "add --multi-process")
    {
        return fail(CommandError::invalid(format!("{}: {why}", file.display())));
    }
    let name = first.scenario.name.clone();
    let root =
        args.out.clone().unwrap_or_else(|| PathBuf::from(format!("runs/{name}-sweep-{}", cohort_host::utc_stamp())));
    if let Err(e) = std::fs::create_dir_all(&root) {
        return fail(CommandError::invalid(format!("{}: {e}", root.display())));
    }
    let mode = if args.multi_process { "multi-process" } else { "reference" };
    info!(
        "sweep of {} over seeds {}..={} ({mode}) → {}",
        file.display(),
        args.first_seed,
        args.first_seed + args.seeds - 1,
        root.display()
    );
    let mut rows = Vec::new();
    for seed in args.first_seed..args.first_seed + args.seeds {
        let s = match load_or_exit(file, &o(seed)) {
            Ok(s) => s,
            Err(code) => return code,
        };
        let dirs = match prepare(&s, Some(&root.join(format!("seed-{seed}")))) {
            Ok(d) => d,
            Err(e) => return e.to_exit(),
        };
        let (outcome, summary) = run_once(&s, &dirs, !args.multi_process, false);
        if outcome.status.is_interrupted() {
            warn!("interrupted at seed {seed}");
            return outcome.status.to_exit();
        }
        if let Some(e) = &outcome.error {
            error!("seed {seed}: {e}");
            return outcome.status.to_exit();
        }
        info!("seed {seed}: {} steps in {:.2} s", summary.steps_completed, outcome.wall_s);
        if !args.keep_telemetry {
            // Ten headline runs would otherwise leave ~1.5 GB; summaries stay.
            dirs.remove_bulk();
        }
        rows.push((seed, summary.metrics));
    }
    let sections: Vec<String> =
        cohort_registry::hooks_of(&first).iter().filter_map(|(_, h)| h.sweep_section(&first, &rows)).collect();
    match sweep_report::write(&root, file, mode, &rows, &sections) {
        Ok(md) => {
            outln!("{md}");
            outln!("sweep results: {} and {}", root.join("sweep.md").display(), root.join("sweep.csv").display());
            ExitCode::SUCCESS
        }
        Err(e) => fail(CommandError::failed(e)),
    }
}
