//! Logging of every Cohort process through `tracing`: one set-up for the orchestrator (its
//! terminal) and one for the `plant` and `agent` children (their log files under the run's
//! `logs/`), so that every line carries its level, and a child's its process name and time.
//!
//! - Filter: the level the orchestrator's `-q`/`-v`/`-vv` chose when one is typed (a flag on the
//!   command line is the nearer, more deliberate choice, so it wins over the environment); else
//!   `RUST_LOG` when set (the `tracing-subscriber` directive syntax); else info, for Cohort's
//!   own crates and nothing from the libraries beneath them (zenoh logs through `tracing` too,
//!   and printed nothing before this module). Errors of Cohort's own crates are always written,
//!   whatever the filter: a failed run's `error:` line is its root cause, never filtered away.
//! - A bad `RUST_LOG` is not fatal (it may be meant for another program): the process warns once,
//!   names the value and the reason, and logs at the chosen level; the children get the fallback.
//! - The orchestrator hands its filter and the run's time zero to every child, local or through a
//!   host daemon ([`ChildLog`]), so a child logs what its orchestrator logs and every child's
//!   times count from the same instant (on another host: by that host's clock).
//! - Orchestrator lines: `error: …`, `warning: …`, `info: …`, `debug: …`, `trace: …` on stderr
//!   (the `error:`/`warning:` lines read as before); stdout stays for machine-readable output.
//! - Child lines: `[   12.345 s] INFO  agent-3: ready (…)`: seconds since the run started, level,
//!   process name, message. A child's panic is logged so too (see [`init_child`]).
//! - A failed write (closed pipe, full disk) is ignored, never a panic: the exit code and the
//!   reports say what happened. (So no `parse_lossy`, and no `tracing` `max_level_*` feature:
//!   either makes `tracing-subscriber` warn with `eprintln!`, which panics on a closed stderr.)

use std::ffi::OsString;
use std::fmt;
use std::sync::OnceLock;
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

use serde::{Deserialize, Serialize};
use tracing::{Event, Level, Subscriber};
use tracing_subscriber::filter::{EnvFilter, FilterExt, LevelFilter, filter_fn};
use tracing_subscriber::fmt::format::Writer;
use tracing_subscriber::fmt::{FmtContext, FormatEvent, FormatFields};
use tracing_subscriber::layer::SubscriberExt;
use tracing_subscriber::registry::LookupSpan;
use tracing_subscriber::{Layer, Registry};

/// The environment variable of the filter (the usual one).
pub const FILTER_VAR: &str = "RUST_LOG";
/// The run's time zero a child's log times count from: Unix time in nanoseconds.
pub const T0_VAR: &str = "COHORT_LOG_T0_NS";
/// Target prefixes of Cohort's own crates (`cohort_*`, and the three binaries): the default
/// filter logs these and nothing else.
pub const OWN_TARGETS: [&str; 4] = ["cohort", "orchestrator", "plant", "agent"];

/// The level of the orchestrator's `-q` (warnings and errors) and `-v` (repeatable) flags.
pub fn level_of(verbose: u8, quiet: bool) -> LevelFilter {
    match (quiet, verbose) {
        (true, _) => LevelFilter::WARN,
        (false, 0) => LevelFilter::INFO,
        (false, 1) => LevelFilter::DEBUG,
        (false, _) => LevelFilter::TRACE,
    }
}

/// The default directives at `level`: Cohort's crates at `level`, every other crate off.
pub fn default_directives(level: LevelFilter) -> String {
    let level = level.to_string().to_lowercase();
    let mut d = String::from("off");
    for t in OWN_TARGETS {
        d.push_str(&format!(",{t}={level}"));
    }
    d
}

/// The filter a process logs with, the directives that built it (handed to the children), and
/// why the user's `RUST_LOG` was not used, if it was not.
pub struct Choice {
    pub filter: EnvFilter,
    pub directives: String,
    pub problem: Option<String>,
}

/// Choose the filter from the value of `RUST_LOG` (`var`) and the level flags chose.
pub fn choose(var: Option<OsString>, level: LevelFilter) -> Choice {
    let fallback = |problem: Option<String>| {
        let directives = default_directives(level);
        let filter = EnvFilter::builder().parse(&directives).expect("the default directives parse");
        Choice { filter, directives, problem }
    };
    let Some(var) = var else { return fallback(None) };
    let Some(text) = var.to_str() else {
        return fallback(Some(format!("{FILTER_VAR}={var:?} is not valid UTF-8")));
    };
    if text.trim().is_empty() {
        return fallback(None);
    }
    match EnvFilter::builder().parse(text) {
        Ok(filter) => Choice { filter, directives: text.to_string(), problem: None },
        Err(e) => fallback(Some(format!("{FILTER_VAR}={text:?} is not a valid filter: {e}"))),
    }
}

/// Errors of Cohort's own crates: written whatever the filter.
fn own_error(m: &tracing::Metadata<'_>) -> bool {
    *m.level() == Level::ERROR && OWN_TARGETS.iter().any(|t| m.target().starts_with(t))
}

/// What a child needs to log as its orchestrator does: the filter's directives and the run's
/// time zero. Set in the child's environment ([`FILTER_VAR`], [`T0_VAR`]); a host daemon
/// receives it in its spawn request.
#[derive(Debug, Clone, PartialEq, Eq, Serialize, Deserialize)]
pub struct ChildLog {
    pub filter: String,
    pub t0_unix_ns: u64,
}

/// The orchestrator's chosen directives (set once by [`init_orchestrator`]).
static DIRECTIVES: OnceLock<String> = OnceLock::new();
/// The current run's time zero, Unix ns (0: not set; then the process's start).
static RUN_T0_NS: AtomicU64 = AtomicU64::new(0);

fn unix_ns(t: SystemTime) -> u64 {
    t.duration_since(UNIX_EPOCH).map_or(0, |d| u64::try_from(d.as_nanos()).unwrap_or(u64::MAX))
}

/// A run starts now: its children's log times count from here.
pub fn start_run() {
    RUN_T0_NS.store(unix_ns(SystemTime::now()), Ordering::Relaxed);
}

/// Seconds since the current run's time zero (since [`start_run`], or since this process's
/// logging was set up).
pub fn run_time_s() -> f64 {
    let t0 = RUN_T0_NS.load(Ordering::Relaxed);
    let now = unix_ns(SystemTime::now());
    now.saturating_sub(t0) as f64 * 1e-9
}

impl ChildLog {
    /// What the orchestrator hands its children now.
    pub fn current() -> Self {
        let filter = DIRECTIVES.get().cloned().unwrap_or_else(|| default_directives(LevelFilter::INFO));
        let t0 = RUN_T0_NS.load(Ordering::Relaxed);
        Self { filter, t0_unix_ns: if t0 == 0 { unix_ns(SystemTime::now()) } else { t0 } }
    }
    /// Set it in a child's environment.
    pub fn apply(&self, cmd: &mut std::process::Command) {
        cmd.env(FILTER_VAR, &self.filter).env(T0_VAR, self.t0_unix_ns.to_string());
    }
}

/// Install a subscriber writing `format` lines to stderr through `filter`, errors of Cohort's own
/// crates always. A second call (a test) leaves the first in place.
fn install<F>(filter: EnvFilter, format: F)
where
    F: FormatEvent<Registry, tracing_subscriber::fmt::format::DefaultFields> + Send + Sync + 'static,
{
    let layer = tracing_subscriber::fmt::layer()
        .with_writer(std::io::stderr)
        .with_ansi(false)
        .log_internal_errors(false)
        .event_format(format)
        .with_filter(filter.or(filter_fn(own_error)));
    let _ = tracing::subscriber::set_global_default(Registry::default().with(layer));
}

/// The orchestrator's logging: `level` from its flags when one was typed (`flagged`: they win
/// over `RUST_LOG`, which is then not read), else `RUST_LOG` when set, else `level`. Returns the
/// warning about a bad `RUST_LOG` already logged, for tests.
pub fn init_orchestrator(level: LevelFilter, flagged: bool) -> Option<String> {
    let choice = choose(if flagged { None } else { std::env::var_os(FILTER_VAR) }, level);
    let _ = DIRECTIVES.set(choice.directives);
    RUN_T0_NS.store(unix_ns(SystemTime::now()), Ordering::Relaxed);
    install(choice.filter, TerminalFormat);
    if let Some(p) = &choice.problem {
        tracing::warn!("{p}; ignoring it: logging at {level} (see the README's \"Logs\" section)");
    }
    choice.problem
}

/// A child's logging, as `name` (`plant`, `agent-3`): the filter and time zero its orchestrator
/// set in its environment ([`ChildLog`]), else info and this process's start. A panic is logged
/// as an error line (then, with `RUST_BACKTRACE` set, the standard report follows).
pub fn init_child(name: &str) {
    let choice = choose(std::env::var_os(FILTER_VAR), LevelFilter::INFO);
    let t0 = std::env::var(T0_VAR).ok().and_then(|v| v.parse::<u64>().ok()).filter(|t| *t > 0);
    RUN_T0_NS.store(t0.unwrap_or_else(|| unix_ns(SystemTime::now())), Ordering::Relaxed);
    install(choice.filter, ChildFormat { name: name.to_string() });
    if let Some(p) = &choice.problem {
        tracing::warn!("{p}; ignoring it: logging at info");
    }
    let standard = std::panic::take_hook();
    std::panic::set_hook(Box::new(move |info| {
        let what = info
            .payload()
            .downcast_ref::<&str>()
            .map(|s| s.to_string())
            .or_else(|| info.payload().downcast_ref::<String>().cloned())
            .unwrap_or_else(|| "(no message)".into());
        let at = info.location().map(|l| format!(" at {}:{}:{}", l.file(), l.line(), l.column())).unwrap_or_default();
        tracing::error!("panicked{at}: {what}");
        if std::env::var_os("RUST_BACKTRACE").is_some_and(|v| v != "0") {
            standard(info);
        }
    }));
}

/// One child log line, as [`init_child`]'s subscriber writes it (the reference run's threads
/// write their log files with it).
pub fn child_line(level: Level, name: &str, t_s: f64, msg: impl fmt::Display) -> String {
    format!("[{t_s:9.3} s] {level:<5} {name}: {msg}\n")
}

/// `error: …`, `warning: …`, `info: …`: the orchestrator's terminal lines.
struct TerminalFormat;

impl<S, N> FormatEvent<S, N> for TerminalFormat
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(&self, ctx: &FmtContext<'_, S, N>, mut w: Writer<'_>, event: &Event<'_>) -> fmt::Result {
        let word = match *event.metadata().level() {
            Level::ERROR => "error",
            Level::WARN => "warning",
            Level::INFO => "info",
            Level::DEBUG => "debug",
            Level::TRACE => "trace",
        };
        write!(w, "{word}: ")?;
        ctx.field_format().format_fields(w.by_ref(), event)?;
        writeln!(w)
    }
}

/// `[   12.345 s] INFO  agent-3: …`: a child's log line.
struct ChildFormat {
    name: String,
}

impl<S, N> FormatEvent<S, N> for ChildFormat
where
    S: Subscriber + for<'a> LookupSpan<'a>,
    N: for<'a> FormatFields<'a> + 'static,
{
    fn format_event(&self, ctx: &FmtContext<'_, S, N>, mut w: Writer<'_>, event: &Event<'_>) -> fmt::Result {
        write!(w, "[{:9.3} s] {:<5} {}: ", run_time_s(), event.metadata().level(), self.name)?;
        ctx.field_format().format_fields(w.by_ref(), event)?;
        writeln!(w)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn flags_choose_the_level() {
        assert_eq!(level_of(0, false), LevelFilter::INFO);
        assert_eq!(level_of(1, false), LevelFilter::DEBUG);
        assert_eq!(level_of(3, false), LevelFilter::TRACE);
        assert_eq!(level_of(2, true), LevelFilter::WARN);
        assert_eq!(default_directives(LevelFilter::WARN), "off,cohort=warn,orchestrator=warn,plant=warn,agent=warn");
    }

    #[test]
    fn rust_log_wins_when_valid_and_falls_back_when_not() {
        let c = choose(Some("cohort_runtime=trace".into()), LevelFilter::INFO);
        assert_eq!(c.directives, "cohort_runtime=trace");
        assert!(c.problem.is_none());
        let c = choose(None, LevelFilter::DEBUG);
        assert_eq!(c.directives, default_directives(LevelFilter::DEBUG));
        let c = choose(Some("".into()), LevelFilter::WARN);
        assert_eq!(c.directives, default_directives(LevelFilter::WARN));
        let c = choose(Some("agent=loud".into()), LevelFilter::INFO);
        assert_eq!(c.directives, default_directives(LevelFilter::INFO));
        let p = c.problem.expect("a bad value is named");
        assert!(p.contains("RUST_LOG=\"agent=loud\"") && p.contains("not a valid filter"), "{p}");
        use std::os::unix::ffi::OsStringExt;
        let c = choose(Some(OsString::from_vec(vec![b'a', 0xff])), LevelFilter::INFO);
        assert!(c.problem.is_some_and(|p| p.contains("UTF-8")));
    }

    #[test]
    fn a_child_line_has_time_level_and_name() {
        assert_eq!(child_line(Level::WARN, "agent-3", 1.5, "x"), "[    1.500 s] WARN  agent-3: x\n");
    }
}
