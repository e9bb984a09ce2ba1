//! What the orchestrator and a host daemon (`orchestrator host`) say to each other over zenoh:
//! the key expressions and the JSON bodies of requests and reports.
//!
//! - `cohort/host/<name>/<verb>`: the daemon's queryable. Verbs: `info` (name, build id),
//!   `spawn` ([`SpawnRequest`] → [`Spawned`]), `signal` ([`SignalRequest`]), `collect`
//!   ([`RunRequest`] → the run's files in [`chunk`]s), `rows` ([`RowsRequest`] → one
//!   [`ProcRows`] reply per process: the newest decimated telemetry rows since the last request,
//!   for `launch --live`), `end` ([`RunRequest`]: kill whatever of the run is left, remove its
//!   directory), `case` ([`CaseRequest`] → [`CaseReply`]: one case of a campaign, run in the
//!   daemon's own process on its worker pool; the reply comes when the case has ended).
//! - `cohort/host/<name>`: the daemon's liveliness token (the orchestrator watches it: a daemon
//!   that disappears takes its processes with it).
//! - `cohort/<run id>/host/<name>/exit`: [`ExitReport`]s, one per child that ended, as `waitpid`
//!   saw it.
//! - `cohort/<run id>/host/<name>/log/<proc>`: a child's output, line by line.

use serde::{Deserialize, Serialize};

/// The daemon's request key for `verb`.
pub fn request_key(host: &str, verb: &str) -> String {
    format!("cohort/host/{host}/{verb}")
}

/// The daemon's liveliness token.
pub fn host_token(host: &str) -> String {
    format!("cohort/host/{host}")
}

pub fn exit_key(run_id: u64, host: &str) -> String {
    format!("cohort/{run_id:016x}/host/{host}/exit")
}

pub fn log_key(run_id: u64, host: &str, proc_name: &str) -> String {
    format!("cohort/{run_id:016x}/host/{host}/log/{proc_name}")
}

/// Every log key of a run (for the orchestrator's subscriber).
pub fn all_logs_key(run_id: u64) -> String {
    format!("cohort/{run_id:016x}/host/*/log/*")
}

/// Every exit key of a run.
pub fn all_exits_key(run_id: u64) -> String {
    format!("cohort/{run_id:016x}/host/*/exit")
}

/// The daemon's answer to `info`.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Info {
    pub name: String,
    pub build_id: String,
    pub pid: u32,
    /// How many campaign cases it runs at once (`orchestrator host --workers`).
    #[serde(default = "one")]
    pub workers: u32,
}

fn one() -> u32 {
    1
}

/// `case`: run one case of a campaign to its outcome. The daemon knows nothing of campaigns: it
/// hands the request to the runner it was started with (the orchestrator's) in a scratch
/// directory of its own, and sends back what the runner says.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct CaseRequest {
    /// The orchestrator's build id: a daemon of another build refuses.
    pub build_id: String,
    /// The campaign (a random id of the orchestrator's invocation: scratch names only).
    pub campaign_id: u64,
    pub case: u64,
    /// The scenario file's path on the orchestrator's machine (its relative paths resolve
    /// against its directory, as in a multi-host run: the same checkout at the same path).
    pub file: String,
    /// The drawn case's scenario, as TOML.
    pub scenario_text: String,
    /// `--duration`, when the command line set it.
    pub duration_s: Option<f64>,
}

/// A daemon's answer to a [`CaseRequest`].
#[derive(Debug, Clone, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum CaseReply {
    /// The case ran (to whatever status): the runner's outcome.
    Done(serde_json::Value),
    /// The daemon is stopping (or its case was interrupted): give the case to another host.
    Stopping,
    /// The case could not run here (the reason names the host's problem).
    Failed(String),
}

/// Start one plant or agent process of a run on this host.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SpawnRequest {
    pub run_id: u64,
    /// The orchestrator's build id: a daemon of another build refuses.
    pub build_id: String,
    /// `plant` or `agent-<id>`.
    pub proc_name: String,
    /// A relaunch (restart fault): resume from this step's checkpoint.
    pub restore_at: Option<u64>,
    pub step_timeout_s: f64,
    /// The resolved scenario, written into the daemon's run directory.
    pub scenario_toml: String,
    /// `run.authenticate`: the run's MAC key, hex; the daemon hands it to the child through an
    /// inherited pipe as the orchestrator does locally.
    pub key_hex: Option<String>,
    /// The orchestrator's zenoh endpoint(s) the child connects to.
    pub connect: Vec<String>,
    /// Where the child listens for its peers.
    pub listen: Vec<String>,
    /// The child's log filter and the run's time zero (its environment's `RUST_LOG` and
    /// `COHORT_LOG_T0_NS`); absent: the daemon's own environment decides.
    #[serde(default)]
    pub log: Option<cohort_runtime::logging::ChildLog>,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct Spawned {
    pub pid: u32,
}

/// Send a signal to children of a run (kill, freeze, thaw: SIGKILL, SIGSTOP, SIGCONT; SIGTERM in
/// the shutdown ladder): one request for every process of the host the signal is for, so a
/// shutdown costs one round trip per host, not one per process.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct SignalRequest {
    pub run_id: u64,
    pub proc_names: Vec<String>,
    pub signal: i32,
}

#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RunRequest {
    pub run_id: u64,
}

/// `rows`: the telemetry rows the run's processes on this host appended since the last `rows`
/// request, of the steps `k` with `k % every == 0`, at most `max_rows` (the newest) per process.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct RowsRequest {
    pub run_id: u64,
    pub every: u64,
    pub max_rows: usize,
}

/// One process's part of a `rows` reply: its columns (`k` first) and rows as (k, the values after
/// `k` as `f64::to_bits`, so they cross bit for bit, NaN included).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ProcRows {
    pub proc_name: String,
    pub columns: Vec<String>,
    pub rows: Vec<(u64, Vec<u64>)>,
}

impl ProcRows {
    /// The rows as f64 values.
    pub fn values(&self) -> Vec<(u64, Vec<f64>)> {
        self.rows.iter().map(|(k, bits)| (*k, bits.iter().map(|b| f64::from_bits(*b)).collect())).collect()
    }
}

/// A child ended: its raw wait status (`ExitStatusExt::from_raw` gives it back).
#[derive(Debug, Clone, Serialize, Deserialize)]
pub struct ExitReport {
    pub proc_name: String,
    pub pid: u32,
    pub wait_status: i32,
}

/// The largest file piece one reply carries: well below
/// `cohort_wire::transport::zenoh::MAX_MESSAGE_BYTES` (on the `lowlatency` transport Cohort used
/// before, which cannot fragment, replies of 48 KiB broke the daemon's link); 16 KiB pieces keep
/// each reply one small message.
pub const CHUNK_BYTES: usize = 16 * 1024;

/// A file piece: `[path length u32 LE][path][offset u64 LE][bytes]`.
pub fn chunk(path: &str, offset: u64, bytes: &[u8]) -> Vec<u8> {
    let mut out = Vec::with_capacity(12 + path.len() + bytes.len());
    out.extend_from_slice(&(path.len() as u32).to_le_bytes());
    out.extend_from_slice(path.as_bytes());
    out.extend_from_slice(&offset.to_le_bytes());
    out.extend_from_slice(bytes);
    out
}

/// A file piece back: (relative path, offset, bytes), or why it is malformed. The path must be a
/// relative path of plain components under one of the run directory's data subdirectories.
pub fn unchunk(b: &[u8]) -> Result<(String, u64, &[u8]), String> {
    let n = b.get(..4).map(|x| u32::from_le_bytes(x.try_into().expect("4 bytes")) as usize).ok_or("short piece")?;
    let path = b.get(4..4 + n).ok_or("short path")?;
    let path = std::str::from_utf8(path).map_err(|_| "path is not UTF-8")?.to_string();
    let off = b.get(4 + n..12 + n).ok_or("short offset")?;
    let offset = u64::from_le_bytes(off.try_into().expect("8 bytes"));
    if !collectable(&path) {
        return Err(format!("refusing path {path:?}"));
    }
    Ok((path, offset, &b[12 + n..]))
}

/// The subdirectories of a run directory whose files a daemon sends back at the end.
pub const COLLECTED: &[&str] = &["telemetry", "timing", "status", "checkpoints", "snapshots"];

/// Whether `path` is `<collected dir>/<plain names…>`.
pub fn collectable(path: &str) -> bool {
    let mut parts = path.split('/');
    let first_ok = parts.next().is_some_and(|d| COLLECTED.contains(&d));
    let rest: Vec<&str> = parts.collect();
    first_ok && !rest.is_empty() && rest.iter().all(|p| !p.is_empty() && *p != "." && *p != ".." && !p.contains('\0'))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn chunks_round_trip_and_paths_stay_inside_the_run_directory() {
        let c = chunk("telemetry/agent-3.csv", 49152, b"k,t_s\n");
        let (p, off, bytes) = unchunk(&c).unwrap();
        assert_eq!((p.as_str(), off, bytes), ("telemetry/agent-3.csv", 49152, &b"k,t_s\n"[..]));
        for bad in ["../etc/passwd", "telemetry/../../x", "logs/a.log", "telemetry", "/telemetry/a", "telemetry//a"] {
            assert!(unchunk(&chunk(bad, 0, b"")).is_err(), "{bad}");
        }
        assert!(unchunk(&[1, 0]).is_err());
    }
}
