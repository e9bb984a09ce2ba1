//! iceoryx2 transport: zero-copy publish–subscribe between processes, with the run's
//! [doorbells](super::doorbell) for wakeups.
//!
//! Layout of one run (everything under the run's own prefix `cohort_<run id>_` and root
//! directory, so two runs on one machine never see each other):
//! - `meas/<i>`   pub/sub [`Measurement`], plant → agent i.
//! - `share/<i>`  pub/sub [`Share`], agent i → plant and every agent that has i as neighbour.
//! - `doorbells`  a file in the run's root, not a service: one doorbell per process; whoever sends
//!   p a message rings p's afterwards, with its sender id, so a process with many subscriptions
//!   (the plant) drains only the senders that rang ([`Marks`]) — a 1 000-agent plant that looked
//!   at every subscriber on every wakeup spent O(N²) per step in `drain` — and a process that
//!   spins is woken without a system call.
//! - `control`    pub/sub [`RunControl`], orchestrator → all (history 1, so a late reader sees stop).
//! - `status`     pub/sub [`Status`], all → orchestrator.
//!
//! The orchestrator creates every service with limits sized from the scenario ([`IoxServices`])
//! before it spawns anything, and holds them for the run; plant and agents only `open()` them, so
//! there is no creation race and every limit is set in one place.
//!
//! A zenoh run with gateways ([`super::gateway`]) has one such layout per host, its *domain*
//! ([`Domain`]: prefix `cohort_<run id>_<k>_`, root `<run id>-<k>`), made and held by the host's
//! gateway instead of the orchestrator; a process rings the gateway's doorbell (with its sender
//! id) instead of a reader's on another host.
//!
//! Ownership (issue 18): a run's root directory lives in the user's own base directory
//! ([`user_base`], 0700, checked before use), the orchestrator holds an `flock` on the run's lock
//! file for the run's life ([`IoxRun::claim`]) so the stale-run sweep ([`IoxRun::sweep_stale`])
//! never needs a pid it would have to trust, and iceoryx2's world-writable management segment is
//! replaced by an owner-only copy before any child starts.
//!
//! What permissions cannot stop: a process of the same user that writes into a run's data
//! segments. iceoryx2 0.10 keeps its pool allocator's free list in the publisher's data segment
//! and follows the relocatable offsets stored there without a bounds check: random bytes written
//! over every `.data` segment of a running consensus ring made the plant and an agent SIGSEGV in
//! `UniqueIndexSet::release_raw_index` (iceoryx2-bb-lock-free `unique_index_set.rs:452`), called
//! from `Sender::retrieve_returned_chunks` (`sender.rs:530`) on the next `loan`. That is
//! iceoryx2's (it trusts its peers by design); the orchestrator reports the crash by process and
//! signal. Nothing of ours uses a number read from shared memory as an index or a bound before
//! `validate` has checked it, and `run.authenticate` makes a damaged or forged payload a counted
//! rejection instead of a wrong value.

use std::path::{Path as StdPath, PathBuf};
use std::time::Duration;

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::publish_subscribe as ps_factory;

use super::doorbell::Doorbells;
use super::{ControlHub, DataPath, Incoming, Proc, RunControlPort, Split, Topology, TransportError, monotonic_ns};
use crate::msg::{
    CONTROL_DEAD, CONTROL_RESUME, CONTROL_START, CONTROL_STOP, Measurement, PLANT_ID, Roster, RunControl,
    SCHEMA_VERSION, Share, Status,
};

pub(crate) type Svc = ipc::Service;
/// The gateway's in side: ports a zenoh callback thread may use (see [`IoxRun::shared_node`]).
pub(crate) type SharedSvc = ipc_threadsafe::Service;

/// Subscriber queue depth for shares: a neighbour can be one step ahead, so two suffice; four
/// leave room without ever making a sender wait (safe overflow is on, and in lockstep the queue
/// never fills).
pub(crate) const SHARE_BUFFER: usize = 8;
pub(crate) const MEAS_BUFFER: usize = 2;
const STATUS_BUFFER: usize = 64;
/// Connections of departed publishers a subscriber keeps readable (see [`IoxRun::config`]); at
/// least iceoryx2's borrowed-sample limit (2).
const EXPIRED_CONNECTIONS: usize = 8;
/// In the user's base directory: a run's lock file is `<run id>.lock` beside its root `<run id>/`.
const LOCK_SUFFIX: &str = ".lock";

/// This user's euid.
fn euid() -> u32 {
    // SAFETY: geteuid cannot fail.
    unsafe { libc::geteuid() }
}

/// The environment variable by which an orchestrator (or a host daemon) gives its children the
/// base directory it resolved, so that a fallback ([`user_base`]) is the same in every process
/// of a run. It is checked like any base before use.
pub const BASE_ENV: &str = "COHORT_RUN_BASE";

/// The base this process resolved (see [`user_base`]); reset when it stops passing its check.
static RESOLVED: std::sync::Mutex<Option<Resolved>> = std::sync::Mutex::new(None);

#[derive(Clone)]
struct Resolved {
    base: PathBuf,
    /// Why the usual base was not used, when it was not.
    note: Option<String>,
}

/// The usual parent of this user's run directories: `$XDG_RUNTIME_DIR/cohort` when that
/// variable names an absolute directory, else `/dev/shm/cohort-<uid>` (`/tmp/cohort-<uid>` where
/// there is no `/dev/shm`). Per user, so one user's runs never meet another's (a shared
/// `/tmp/iceoryx2` let a second user neither run nor trust the sweep). On a memory file system
/// because iceoryx2 writes and fsyncs a file for every service, port and node: on this project's
/// ext4 disk that cost ≈ 9 ms per service (26 ms per agent for the orchestrator alone, and the
/// plant opens three services per agent), against 0.25 ms on tmpfs — it was most of a large
/// run's start-up.
pub fn usual_user_base() -> PathBuf {
    match std::env::var_os("XDG_RUNTIME_DIR").map(PathBuf::from) {
        Some(x) if x.is_absolute() && x.is_dir() => x.join("cohort"),
        _ if StdPath::new("/dev/shm").is_dir() => PathBuf::from(format!("/dev/shm/cohort-{}", euid())),
        _ => PathBuf::from(format!("/tmp/cohort-{}", euid())),
    }
}

/// The parent of this user's run directories: [`BASE_ENV`] when the parent process set it, else
/// [`usual_user_base`] unless something there is not this user's private directory (another
/// local user can create `/dev/shm/cohort-<uid>` first, since every run removes it at its end):
/// then a fresh private directory beside it, `<usual>-<3 hex digits>`, created by this user (or
/// one such already this user's, reused), and [`user_base_note`] says so. Short, because a run's
/// root inside it must stay within [`MAX_ROOT_DIR_LEN`].
pub fn user_base() -> PathBuf {
    if let Some(b) = std::env::var_os(BASE_ENV).map(PathBuf::from).filter(|b| b.is_absolute()) {
        return b;
    }
    let mut r = RESOLVED.lock().unwrap_or_else(|p| p.into_inner());
    r.get_or_insert_with(resolve_base).base.clone()
}

/// Why this process's runs are not in [`usual_user_base`], and where they are, if they are not.
pub fn user_base_note() -> Option<String> {
    RESOLVED.lock().unwrap_or_else(|p| p.into_inner()).as_ref().and_then(|r| r.note.clone())
}

fn resolve_base() -> Resolved {
    let usual = usual_user_base();
    let why = match std::fs::symlink_metadata(&usual) {
        Err(_) => return Resolved { base: usual, note: None },
        Ok(_) => match check_private_dir(&usual) {
            Ok(()) => return Resolved { base: usual, note: None },
            Err(why) => why,
        },
    };
    match fallback_base(&usual) {
        Ok(base) => {
            let note = format!(
                "{why}; this user's runs use {} instead (remove {} to get the usual place back)",
                base.display(),
                usual.display()
            );
            Resolved { base, note: Some(note) }
        }
        // Nothing better: the usual base, whose check then fails with its reason.
        Err(_) => Resolved { base: usual, note: None },
    }
}

/// A private directory beside `usual`, named `<usual>-<3 hex digits>`: one of this user's that
/// passes [`check_private_dir`] (the earliest by name), else one made now (mode 0700; `mkdir`
/// fails on a name someone else took, so what it makes is this user's).
fn fallback_base(usual: &StdPath) -> std::io::Result<PathBuf> {
    use std::os::unix::fs::DirBuilderExt;
    let parent = usual.parent().unwrap_or(StdPath::new("/"));
    let stem = usual.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
    let is_ours = |name: &str| {
        name.strip_prefix(&format!("{stem}-")).is_some_and(|h| h.len() == 3 && h.bytes().all(|b| b.is_ascii_hexdigit()))
    };
    let mut mine: Vec<PathBuf> = std::fs::read_dir(parent)?
        .flatten()
        .filter(|e| is_ours(&e.file_name().to_string_lossy()))
        .map(|e| e.path())
        .filter(|p| check_private_dir(p).is_ok())
        .collect();
    mine.sort();
    if let Some(p) = mine.into_iter().next() {
        return Ok(p);
    }
    let mut seed = monotonic_ns() ^ u64::from(std::process::id()).rotate_left(32);
    for _ in 0..256 {
        seed = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
        let dir = parent.join(format!("{stem}-{:03x}", (seed >> 52) & 0xfff));
        match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
            Ok(()) => return Ok(dir),
            Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => continue,
            Err(e) => return Err(e),
        }
    }
    Err(std::io::Error::other("every fallback name is taken"))
}

/// The longest run root directory whose iceoryx2 event sockets still fit a unix socket address
/// (107 bytes, `sun_path` less its NUL). A socket is `<root>/<prefix><id>.event`: the prefix is
/// `cohort_<16 hex>_` (24), the id a `UniqueSystemId` printed in decimal — 96 bits of time and
/// pid under a per-process counter, so 29 digits for the first id and 34 for the 65 536th — and
/// `.event` (6): 107 − 6 − 34 − 24 − 1 = 42. Past it iceoryx2 fails with a bare
/// `ResourceCreationFailed` once a process's counter grows (it did at N = 50 with
/// `XDG_RUNTIME_DIR=/run/user/1000` when run directories were named `cohort_<id>`).
pub const MAX_ROOT_DIR_LEN: usize = 42;

/// Why a directory cannot hold this user's runs: it must be a real directory (not a symlink)
/// owned by this user that nobody else can enter.
pub fn check_private_dir(path: &StdPath) -> Result<(), String> {
    use std::os::unix::fs::{MetadataExt, PermissionsExt};
    let md = std::fs::symlink_metadata(path).map_err(|e| format!("{}: {e}", path.display()))?;
    if !md.file_type().is_dir() {
        return Err(format!("{} is not a directory (a symlink or a file is refused)", path.display()));
    }
    if md.uid() != euid() {
        return Err(format!(
            "{} belongs to uid {}, not to this user (uid {}): another user created it; remove it or set \
             XDG_RUNTIME_DIR to a directory of your own",
            path.display(),
            md.uid(),
            euid()
        ));
    }
    if md.permissions().mode() & 0o077 != 0 {
        return Err(format!(
            "{} has mode {:04o}: other users could reach this user's runs; chmod 700 it",
            path.display(),
            md.permissions().mode() & 0o7777
        ));
    }
    Ok(())
}

/// Create this user's base directory (mode 0700) if absent, then check that it is a directory
/// owned by this user that nobody else can enter. Returns it.
pub fn ensure_user_base() -> Result<PathBuf, TransportError> {
    match ensure_private_dir(user_base()) {
        // Taken by someone else since it was resolved (it did not exist then): resolve again,
        // once, unless a parent process chose it.
        Err(_) if std::env::var_os(BASE_ENV).is_none() => {
            *RESOLVED.lock().unwrap_or_else(|p| p.into_inner()) = None;
            ensure_private_dir(user_base())
        }
        r => r,
    }
}

/// Where a host daemon keeps its processes' run files until the orchestrator fetches them: on
/// disk (`$TMPDIR/cohort-<uid>-hosts`, else `/tmp/…`), not in [`user_base`]'s memory file system,
/// since telemetry can be large. Created and checked like the base.
pub fn ensure_user_files_base() -> Result<PathBuf, TransportError> {
    ensure_private_dir(std::env::temp_dir().join(format!("cohort-{}-hosts", euid())))
}

fn ensure_private_dir(dir: PathBuf) -> Result<PathBuf, TransportError> {
    use std::os::unix::fs::DirBuilderExt;
    match std::fs::DirBuilder::new().mode(0o700).create(&dir) {
        Ok(()) => {}
        Err(e) if e.kind() == std::io::ErrorKind::AlreadyExists => {}
        Err(e) => return Err(TransportError::Other(format!("cannot create {}: {e}", dir.display()))),
    }
    check_private_dir(&dir).map_err(|e| TransportError::Other(format!("unsafe run directory: {e}")))?;
    Ok(dir)
}

/// flock(2) on `f`, without blocking. Ok(true): taken; Ok(false): someone holds it.
fn try_lock(f: &std::fs::File) -> std::io::Result<bool> {
    use std::os::fd::AsRawFd;
    // SAFETY: flock on a descriptor we own.
    if unsafe { libc::flock(f.as_raw_fd(), libc::LOCK_EX | libc::LOCK_NB) } == 0 {
        return Ok(true);
    }
    let e = std::io::Error::last_os_error();
    if e.raw_os_error() == Some(libc::EWOULDBLOCK) { Ok(false) } else { Err(e) }
}

/// A run's claim: its lock file in the user's base directory, locked (flock) for as long as this
/// value lives. A later orchestrator that can take the lock knows, without trusting any pid, that
/// the run's orchestrator is gone: the kernel drops the lock when its process ends, however it
/// ends. Dropping the claim removes the lock file.
pub struct RunClaim {
    file: std::fs::File,
    path: PathBuf,
}

impl Drop for RunClaim {
    fn drop(&mut self) {
        let _ = std::fs::remove_file(&self.path);
        let _ = &self.file; // the lock goes with the descriptor, after the file is gone
        remove_user_base_if_empty();
    }
}

/// Remove this user's base directory once no run is in it (`rmdir` refuses a non-empty one, so
/// a concurrent run keeps it): nothing of ours stays in `/dev/shm` after the last run. A run
/// that is setting up meanwhile creates it again ([`IoxRun::claim`] retries).
fn remove_user_base_if_empty() {
    let _ = std::fs::remove_dir(user_base());
}

/// The names and locations of one run's iceoryx2 resources, and its MAC key when
/// `run.authenticate` is on (run control and status are sealed with it).
#[derive(Debug, Clone)]
pub struct IoxRun {
    pub run_id: u64,
    pub key: Option<crate::auth::MacKey>,
    /// A run with gateways (`run.zenoh_links = "gateway"`): this host's share of it, one
    /// iceoryx2 domain per host (its own prefix and root, as namespaces on one machine share
    /// /dev/shm), and where every process runs, so a message for a process of another host wakes
    /// the gateway instead ([`super::gateway`]).
    pub domain: Option<Domain>,
}

/// One host's iceoryx2 domain of a run with gateways.
#[derive(Debug, Clone)]
pub struct Domain {
    /// The host's index in the placement (0: the orchestrator's machine, k: `hosts[k-1]`).
    pub here: u16,
    pub placement: std::sync::Arc<super::gateway::Placement>,
}

impl Domain {
    /// Whether `p` runs on this host.
    pub fn is_local(&self, p: Proc) -> bool {
        self.placement.host(p) == self.here
    }
}

impl IoxRun {
    pub fn new(run_id: u64) -> Self {
        Self { run_id, key: None, domain: None }
    }
    pub fn with_key(mut self, key: Option<crate::auth::MacKey>) -> Self {
        self.key = key;
        self
    }
    /// This host's domain of a run with gateways.
    pub fn in_domain(mut self, placement: std::sync::Arc<super::gateway::Placement>, here: u16) -> Self {
        self.domain = Some(Domain { here, placement });
        self
    }
    /// The run id, and the domain's host index when it has one: `<run id>` or `<run id>-<k>`
    /// (hex), the name of its root directory and lock file.
    fn stem(&self) -> String {
        match &self.domain {
            None => format!("{:016x}", self.run_id),
            Some(d) => format!("{:016x}-{:x}", self.run_id, d.here),
        }
    }
    /// File prefix of every shared-memory segment and file of this run (of its domain).
    pub fn prefix(&self) -> String {
        match &self.domain {
            None => format!("cohort_{:016x}_", self.run_id),
            Some(d) => format!("cohort_{:016x}_{:x}_", self.run_id, d.here),
        }
    }
    /// The run's own iceoryx2 root directory (removed whole at the end of the run): the run id
    /// alone (and the domain's index), to keep socket paths short (see [`MAX_ROOT_DIR_LEN`]).
    pub fn root_dir(&self) -> PathBuf {
        user_base().join(self.stem())
    }
    fn lock_path(&self) -> PathBuf {
        user_base().join(format!("{}{LOCK_SUFFIX}", self.stem()))
    }
    /// Refuse a root directory too long for iceoryx2's socket paths, naming it and the way out.
    pub fn check_root_len(&self) -> Result<(), TransportError> {
        let root = self.root_dir();
        let len = root.as_os_str().len();
        if len > MAX_ROOT_DIR_LEN {
            return Err(TransportError::Other(format!(
                "the run directory {} is {len} bytes long, more than the {MAX_ROOT_DIR_LEN} that keep its \
                 iceoryx2 socket paths within the kernel's 107-byte limit: set XDG_RUNTIME_DIR to a shorter \
                 directory, or unset it",
                root.display()
            )));
        }
        Ok(())
    }
    /// The iceoryx2 configuration of this run's plant and agent nodes (the orchestrator's
    /// differs in [`Self::orchestrator_config`]).
    pub fn config(&self) -> Result<Config, TransportError> {
        let mut cfg = Config::default();
        cfg.global.prefix = FileName::new(self.prefix().as_bytes()).map_err(|e| TransportError::iox("prefix", e))?;
        let root = format!("{}/", self.root_dir().display());
        cfg.global.set_root_path(&Path::new(root.as_bytes()).map_err(|e| TransportError::iox("root path", e))?);
        // No node of a run scans for dead nodes: the orchestrator removes every resource of the
        // run itself once its processes are gone. The scans cost O(N) each, so O(N²) when all
        // N processes start or exit together, which at N = 100 stalled the last step ~190 ms.
        cfg.global.node.cleanup_dead_nodes_on_creation = false;
        cfg.global.node.cleanup_dead_nodes_on_destruction = false;
        // Likewise every service open checked each node registered in the service for life: the
        // run-wide services (control, status) hold every process's node, so
        // at N = 256 the last agent spent 68 ms opening its ports against 7 ms for the first,
        // and start-up CPU grew as N². A relaunched agent finds its dead predecessor's ports
        // still registered: every limit has spare places for that (`IoxServices::create`).
        cfg.global.service.cleanup_dead_nodes_on_open = false;
        // A subscriber keeps room for this many connections of publishers that left with samples
        // unread (iceoryx2's default, 128, made each subscriber allocate 460 kB: a 1 000-agent
        // plant spent 441 MB on them). A share service has one publisher and its relaunched
        // successors; every drain reads a departed one's samples at once.
        cfg.defaults.publish_subscribe.subscriber_expired_connection_buffer = EXPIRED_CONNECTIONS;
        Ok(cfg)
    }
    /// The orchestrator's: its status subscriber hears every process of the run, and all of them
    /// may leave at once with their last status unread (with room for 8, a 1 000-agent run's
    /// end discarded statuses), so it keeps room for every publisher the service allows.
    fn orchestrator_config(&self, status_publishers: usize) -> Result<Config, TransportError> {
        let mut cfg = self.config()?;
        cfg.defaults.publish_subscribe.subscriber_expired_connection_buffer =
            status_publishers.max(EXPIRED_CONNECTIONS);
        Ok(cfg)
    }
    pub(crate) fn service(&self, what: &str) -> Result<ServiceName, TransportError> {
        ServiceName::new(&format!("cohort/{:016x}/{what}", self.run_id))
            .map_err(|e| TransportError::iox(format!("service name {what}"), e))
    }
    pub(crate) fn node(&self, name: &str) -> Result<Node<Svc>, TransportError> {
        self.node_with(name, &self.config()?)
    }
    /// A node whose ports may be used from any thread (`ipc_threadsafe`: the same shared-memory
    /// resources as `ipc`, its ports behind a mutex), for the gateway's zenoh callback.
    pub(crate) fn shared_node(&self, name: &str) -> Result<Node<SharedSvc>, TransportError> {
        self.node_with(name, &self.config()?)
    }
    fn node_with<S: iceoryx2::service::Service>(&self, name: &str, cfg: &Config) -> Result<Node<S>, TransportError> {
        ensure_user_base()?;
        NodeBuilder::new()
            .name(&NodeName::new(name).map_err(|e| TransportError::iox("node name", e))?)
            .config(cfg)
            // Signals stay ours: SIGTERM/SIGINT handling is done by the processes themselves.
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<S>()
            .map_err(|e| TransportError::iox(format!("create node {name}"), e))
    }

    /// This run's entries in /dev/shm that belong to this user.
    fn own_segments(&self) -> Vec<PathBuf> {
        use std::os::unix::fs::MetadataExt;
        let prefix = self.prefix();
        let Ok(rd) = std::fs::read_dir("/dev/shm") else { return Vec::new() };
        rd.flatten()
            .filter(|e| e.file_name().to_string_lossy().starts_with(&prefix))
            .filter(|e| e.metadata().is_ok_and(|m| m.uid() == euid()))
            .map(|e| e.path())
            .collect()
    }

    /// Remove everything this run left in /dev/shm and its root directory — including the
    /// per-prefix management segment iceoryx2 keeps by design. Call only when no process of the
    /// run is alive. Returns how many entries were removed.
    pub fn remove_all_resources(&self) -> usize {
        let mut removed = self.own_segments().iter().filter(|p| std::fs::remove_file(p).is_ok()).count();
        let root = self.root_dir();
        if root.exists() {
            removed += count_files(&root);
            let _ = std::fs::remove_dir_all(&root);
        }
        remove_user_base_if_empty();
        removed
    }

    /// Claim this run for the calling (orchestrator) process: create and lock its lock file, then
    /// its root directory (0700). The lock file is locked under a temporary name and renamed into
    /// place, so a sweeping orchestrator never finds it unlocked while the run is set up.
    pub fn claim(&self) -> Result<RunClaim, TransportError> {
        use std::os::unix::fs::{DirBuilderExt, OpenOptionsExt};
        self.check_root_len()?;
        let err = |what: &str, e: std::io::Error| TransportError::Other(format!("{what}: {e}"));
        // The base may vanish between its check and the first file in it (the last run of
        // another orchestrator removing it as it ends): then make it again.
        let mut attempts = 0;
        let (tmp, file) = loop {
            let base = ensure_user_base()?;
            let tmp = base.join(format!(".claim-{:016x}-{}", self.run_id, std::process::id()));
            match std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .mode(0o600)
                .custom_flags(libc::O_NOFOLLOW)
                .open(&tmp)
            {
                Ok(file) => break (tmp, file),
                Err(e) if e.kind() == std::io::ErrorKind::NotFound && attempts < 3 => attempts += 1,
                Err(e) => return Err(err(&tmp.display().to_string(), e)),
            }
        };
        if !try_lock(&file).map_err(|e| err("flock", e))? {
            let _ = std::fs::remove_file(&tmp);
            return Err(TransportError::Other(format!("{}: locked by another process", tmp.display())));
        }
        let path = self.lock_path();
        std::fs::rename(&tmp, &path).map_err(|e| err(&path.display().to_string(), e))?;
        let claim = RunClaim { file, path };
        let root = self.root_dir();
        std::fs::DirBuilder::new().mode(0o700).create(&root).map_err(|e| err(&root.display().to_string(), e))?;
        Ok(claim)
    }

    /// Remove the resources of every run of this user whose orchestrator is provably gone: its
    /// lock file in the user's base directory can be locked (the kernel released the lock when
    /// that orchestrator ended), or its root directory has no lock file at all (a claim always
    /// makes the lock file first). Another user's runs are never touched. Returns the ids swept.
    /// It never makes the base (with none there is nothing to sweep), and removes it when the
    /// sweep leaves it empty: sweeps also run at ends, after the last run removed it.
    pub fn sweep_stale() -> Vec<u64> {
        if std::fs::symlink_metadata(user_base()).is_err() {
            return Vec::new();
        }
        let swept = Self::sweep_base();
        remove_user_base_if_empty();
        swept
    }

    fn sweep_base() -> Vec<u64> {
        let mut swept = Vec::new();
        let Ok(base) = ensure_user_base() else { return swept };
        let Ok(rd) = std::fs::read_dir(&base) else { return swept };
        let mut locked = std::collections::HashSet::new();
        let mut roots = Vec::new();
        for e in rd.flatten() {
            let name = e.file_name().to_string_lossy().to_string();
            // Anything else here (a daemon's `hosts/`, a claim being made) is not a run.
            if let Some(run) = name.strip_suffix(LOCK_SUFFIX).and_then(Self::from_stem) {
                let Ok(f) = std::fs::OpenOptions::new().read(true).write(true).open(e.path()) else { continue };
                if try_lock(&f).unwrap_or(false) {
                    run.remove_all_resources();
                    let _ = std::fs::remove_file(e.path());
                    swept.push(run.run_id);
                } else {
                    locked.insert(run.stem());
                }
            } else if let Some(run) = Self::from_stem(&name) {
                roots.push(run);
            }
        }
        for run in roots {
            if !locked.contains(&run.stem()) && !run.lock_path().exists() {
                run.remove_all_resources();
                if !swept.contains(&run.run_id) {
                    swept.push(run.run_id);
                }
            }
        }
        swept
    }

    /// The run (or a domain of it) a root directory or lock file is named for: 16 hex digits of
    /// run id, then `-<host index>` (hex) for a domain; the placement is not needed to remove it.
    fn from_stem(stem: &str) -> Option<IoxRun> {
        let (id, here) = match stem.split_once('-') {
            None => (stem, None),
            Some((id, k)) => (id, Some(k)),
        };
        let hex = |h: &str, max: usize| !h.is_empty() && h.len() <= max && h.bytes().all(|b| b.is_ascii_hexdigit());
        if id.len() != 16 || !hex(id, 16) {
            return None;
        }
        let mut run = IoxRun::new(u64::from_str_radix(id, 16).ok()?);
        if let Some(k) = here {
            if !hex(k, 4) {
                return None;
            }
            let here = u16::from_str_radix(k, 16).ok()?;
            run = run.in_domain(std::sync::Arc::new(super::gateway::Placement::default()), here);
        }
        Some(run)
    }

    /// iceoryx2 0.10 creates its per-prefix management segment (`…global_mgmt`, a node counter)
    /// with a hard-coded mode 0666 (`enable_global_access(true)` in its
    /// `GlobalManagementSegment::open_or_create`), and no setting changes that: any user could
    /// write it and make the run's next node creation fail. Right after the orchestrator's node
    /// created it, before any child exists, it is replaced by an owner-only copy: created 0600
    /// with O_EXCL, filled with the same bytes, renamed over the name. A process that opened the
    /// world-writable one in that instant holds an inode nobody opens again.
    fn secure_management_segment(&self) -> Result<(), TransportError> {
        use std::io::Write;
        use std::os::unix::fs::{OpenOptionsExt, PermissionsExt};
        let err = |what: String, e: std::io::Error| TransportError::Other(format!("{what}: {e}"));
        for path in self.own_segments() {
            let name = path.file_name().map(|n| n.to_string_lossy().to_string()).unwrap_or_default();
            let mode = std::fs::symlink_metadata(&path).map_err(|e| err(path.display().to_string(), e))?;
            if !name.ends_with("global_mgmt") || mode.permissions().mode() & 0o077 == 0 {
                continue;
            }
            let bytes = std::fs::read(&path).map_err(|e| err(path.display().to_string(), e))?;
            let tmp = path.with_file_name(format!("{name}.owner-only"));
            let mut f = std::fs::OpenOptions::new()
                .write(true)
                .create_new(true)
                .mode(0o600)
                .custom_flags(libc::O_NOFOLLOW)
                .open(&tmp)
                .map_err(|e| err(tmp.display().to_string(), e))?;
            f.write_all(&bytes).map_err(|e| err(tmp.display().to_string(), e))?;
            std::fs::rename(&tmp, &path).map_err(|e| err(path.display().to_string(), e))?;
        }
        Ok(())
    }

    /// Entries of this run currently in /dev/shm and under its root directory.
    pub fn count_resources(&self) -> usize {
        let prefix = self.prefix();
        let shm = std::fs::read_dir("/dev/shm")
            .map(|rd| rd.flatten().filter(|e| e.file_name().to_string_lossy().starts_with(&prefix)).count())
            .unwrap_or(0);
        shm + count_files(&self.root_dir())
    }
}

fn count_files(dir: &StdPath) -> usize {
    let Ok(rd) = std::fs::read_dir(dir) else { return 0 };
    rd.flatten().map(|e| if e.path().is_dir() { count_files(&e.path()) } else { 1 }).sum()
}

/// Every service of a run, created and held by the orchestrator.
pub struct IoxServices {
    _meas: Vec<ps_factory::PortFactory<Svc, Measurement, ()>>,
    _share: Vec<ps_factory::PortFactory<Svc, Share, ()>>,
    _control: ps_factory::PortFactory<Svc, RunControl, ()>,
    _status: ps_factory::PortFactory<Svc, Status, ()>,
    control_pub: Publisher<Svc, RunControl, ()>,
    status_sub: Subscriber<Svc, Status, ()>,
    /// Rung for every process after each control notice (`Doorbells::ring_processes`).
    bells: Doorbells,
    run: IoxRun,
    rejected: std::cell::Cell<u64>,
    // Dropped last: ports and factories above belong to this node.
    _node: Node<Svc>,
}

impl IoxServices {
    /// `spare`: how many agent processes may be relaunched during the run. A killed process's
    /// ports stay registered (dead-node scans are off, see `IoxRun::node`), so every limit gets
    /// that many spare places.
    pub fn create(run: &IoxRun, topo: &Topology, spare: usize) -> Result<Self, TransportError> {
        let n = topo.n_agents() as usize;
        let node = run.node_with("orchestrator", &run.orchestrator_config(n + 1 + spare)?)?;
        run.secure_management_segment()?;
        // A service's node limit: the processes that open it (the orchestrator among them), room
        // for the relaunched ones (a killed process's node stays registered) and two to spare.
        // Sized per service, not from N: every process that opens a service maps state sized by
        // its node limit, so a limit of N on each of the plant's 2 N services grew the plant's
        // memory as N².
        // With gateways (`run.domain`), the host's gateway opens what the orchestrator would and
        // more: two nodes of its own (one receiving for other hosts, one delivering from them),
        // a subscriber on every service it reads for other hosts and a publisher on every one it
        // delivers to.
        let gw = usize::from(run.domain.is_some());
        let nodes = |processes: usize| processes + 2 + 2 * spare + 2 * gw;
        let mut meas = Vec::with_capacity(n);
        let mut share = Vec::with_capacity(n);
        for i in 1..=topo.n_agents() {
            meas.push(
                node.service_builder(&run.service(&format!("meas/{i}"))?)
                    .publish_subscribe::<Measurement>()
                    .max_publishers(1)
                    .max_subscribers(1 + spare + gw)
                    // The orchestrator, the plant, agent i.
                    .max_nodes(nodes(3))
                    .subscriber_max_buffer_size(MEAS_BUFFER)
                    .history_size(0)
                    .create()
                    .map_err(|e| TransportError::iox(format!("create meas/{i}"), e))?,
            );
            share.push(
                node.service_builder(&run.service(&format!("share/{i}"))?)
                    .publish_subscribe::<Share>()
                    .max_publishers(1 + spare)
                    .max_subscribers(1 + topo.readers_of(i).len() + spare + gw)
                    // The orchestrator, agent i, the plant, i's readers.
                    .max_nodes(nodes(3 + topo.readers_of(i).len()))
                    .subscriber_max_buffer_size(SHARE_BUFFER)
                    .history_size(0)
                    .create()
                    .map_err(|e| TransportError::iox(format!("create share/{i}"), e))?,
            );
        }
        // Every process's doorbell (and the gateway's): a file in the run's root, which the node
        // made; the processes map it, the orchestrator (or gateway) makes it and rings every
        // process's after a control notice.
        let bells = Doorbells::create(&run.root_dir(), n)?;
        let control = node
            .service_builder(&run.service("control")?)
            .publish_subscribe::<RunControl>()
            .max_publishers(1)
            .max_subscribers(n + 1 + spare)
            .max_nodes(nodes(n + 2))
            .subscriber_max_buffer_size(16)
            .history_size(1)
            .create()
            .map_err(|e| TransportError::iox("create control", e))?;
        let status = node
            .service_builder(&run.service("status")?)
            .publish_subscribe::<Status>()
            .max_publishers(n + 1 + spare)
            .max_subscribers(1)
            .max_nodes(nodes(n + 2))
            .subscriber_max_buffer_size(STATUS_BUFFER)
            .history_size(0)
            .create()
            .map_err(|e| TransportError::iox("create status", e))?;
        let control_pub =
            control.publisher_builder().create().map_err(|e| TransportError::iox("control publisher", e))?;
        let status_sub = status
            .subscriber_builder()
            .buffer_size(STATUS_BUFFER)
            .create()
            .map_err(|e| TransportError::iox("status subscriber", e))?;
        Ok(Self {
            _meas: meas,
            _share: share,
            _control: control,
            _status: status,
            control_pub,
            status_sub,
            bells,
            run: run.clone(),
            rejected: std::cell::Cell::new(0),
            _node: node,
        })
    }

    /// Publish the stop request (kept in the service's history for late readers).
    pub fn request_stop(&self) -> Result<(), TransportError> {
        self.control(CONTROL_STOP)
    }

    /// Tell the plant that every process is ready (see [`Transport::start_granted`]).
    pub fn grant_start(&self) -> Result<(), TransportError> {
        self.control(CONTROL_START)
    }

    fn control(&self, command: u32) -> Result<(), TransportError> {
        self.send_control(RunControl::new(command, self.run.run_id))
    }

    /// Let the plant go on past the hold at `step`, with these roster changes.
    pub fn resume(&self, step: u64, dead: Roster, alive: Roster) -> Result<(), TransportError> {
        let mut msg = RunControl::new(CONTROL_RESUME, self.run.run_id);
        (msg.step, msg.dead, msg.alive) = (step, dead, alive);
        self.send_control(msg)
    }

    /// Tell the plant these agents died outside the fault plan.
    pub fn report_dead(&self, dead: Roster) -> Result<(), TransportError> {
        let mut msg = RunControl::new(CONTROL_DEAD, self.run.run_id);
        msg.dead = dead;
        self.send_control(msg)
    }

    /// Pass on a request another hub sealed (a host's gateway relays the orchestrator's).
    pub fn forward_control(&self, msg: &RunControl) -> Result<(), TransportError> {
        self.publish_control(*msg)
    }

    fn send_control(&self, mut msg: RunControl) -> Result<(), TransportError> {
        if let Some(k) = &self.run.key {
            k.seal_control(&mut msg);
        }
        self.publish_control(msg)
    }

    /// Publish, then wake every process that waits (see [`DataPath::woken_by_control`]).
    fn publish_control(&self, msg: RunControl) -> Result<(), TransportError> {
        self.control_pub.send_copy(msg).map_err(|e| TransportError::iox("send control", e))?;
        self.bells.ring_processes();
        Ok(())
    }

    /// Hand every status received so far to `f`; messages of another version or run, or with a
    /// wrong tag when the run has a key, are skipped and counted ([`IoxServices::rejected`]).
    pub fn poll_status(&self, mut f: impl FnMut(&Status)) -> Result<(), TransportError> {
        while let Some(s) = self.status_sub.receive().map_err(|e| TransportError::iox("receive status", e))? {
            let st = s.payload();
            let tag_ok = self.run.key.as_ref().is_none_or(|k| k.check_status(st));
            if st.version == SCHEMA_VERSION && st.run_id == self.run.run_id && tag_ok {
                f(st);
            } else {
                self.rejected.set(self.rejected.get() + 1);
            }
        }
        Ok(())
    }

    /// Status messages dropped so far (another version or run, or a wrong tag).
    pub fn rejected(&self) -> u64 {
        self.rejected.get()
    }
}

impl ControlHub for IoxServices {
    fn request_stop(&self) -> Result<(), TransportError> {
        IoxServices::request_stop(self)
    }
    fn grant_start(&self) -> Result<(), TransportError> {
        IoxServices::grant_start(self)
    }
    fn resume(&self, step: u64, dead: Roster, alive: Roster) -> Result<(), TransportError> {
        IoxServices::resume(self, step, dead, alive)
    }
    fn report_dead(&self, dead: Roster) -> Result<(), TransportError> {
        IoxServices::report_dead(self, dead)
    }
    fn poll_status(&self, f: &mut dyn FnMut(&Status)) -> Result<(), TransportError> {
        IoxServices::poll_status(self, f)
    }
    fn rejected(&self) -> u64 {
        IoxServices::rejected(self)
    }
}

/// A process's run-control ports: the orchestrator's start/stop requests in, status out. Used
/// by every transport (the UDP baseline carries only the data path over sockets).
pub struct IoxControl {
    control_sub: Subscriber<Svc, RunControl, ()>,
    status_pub: Publisher<Svc, Status, ()>,
    run_id: u64,
    key: Option<crate::auth::MacKey>,
    stop: bool,
    started: bool,
    /// Resume and dead-agent notices not yet taken by the driver.
    events: Vec<RunControl>,
    // Dropped last.
    _node: Node<Svc>,
}

impl IoxControl {
    pub fn open(run: &IoxRun, me: Proc) -> Result<Self, TransportError> {
        let node = run.node(&format!("{}-control", me.name()))?;
        Self::with_node(run, node)
    }

    fn with_node(run: &IoxRun, node: Node<Svc>) -> Result<Self, TransportError> {
        let control_sub = node
            .service_builder(&run.service("control")?)
            .publish_subscribe::<RunControl>()
            .open()
            .map_err(|e| TransportError::iox("open control", e))?
            .subscriber_builder()
            .create()
            .map_err(|e| TransportError::iox("control subscriber", e))?;
        let status_pub = node
            .service_builder(&run.service("status")?)
            .publish_subscribe::<Status>()
            .open()
            .map_err(|e| TransportError::iox("open status", e))?
            .publisher_builder()
            .create()
            .map_err(|e| TransportError::iox("status publisher", e))?;
        Ok(Self {
            control_sub,
            status_pub,
            run_id: run.run_id,
            key: run.key,
            stop: false,
            started: false,
            events: Vec::new(),
            _node: node,
        })
    }

    fn poll(&mut self) {
        while let Ok(Some(s)) = self.control_sub.receive() {
            let c = s.payload();
            let tag_ok = self.key.as_ref().is_none_or(|k| k.check_control(c));
            if c.version == SCHEMA_VERSION && c.run_id == self.run_id && tag_ok {
                match c.command {
                    CONTROL_STOP => self.stop = true,
                    CONTROL_START => self.started = true,
                    CONTROL_RESUME | CONTROL_DEAD => self.events.push(*c),
                    _ => {}
                }
            }
        }
    }
}

impl RunControlPort for IoxControl {
    /// Best effort: a full status queue must never stall a step.
    fn report(&mut self, s: &Status) {
        let mut s = *s;
        if let Some(k) = &self.key {
            k.seal_status(&mut s);
        }
        let _ = self.status_pub.send_copy(s);
    }
    fn stop_requested(&mut self) -> bool {
        if !self.stop {
            self.poll();
        }
        self.stop
    }
    fn start_granted(&mut self) -> bool {
        if !self.started {
            self.poll();
        }
        self.started
    }
    fn control_events(&mut self, out: &mut Vec<RunControl>) {
        self.poll();
        out.append(&mut self.events);
    }
}

/// One plant or agent process's iceoryx2 endpoint: data ports, then the run-control ports (which
/// own the node, so they are dropped last).
pub type IoxTransport = Split<IoxData, IoxControl>;

/// The data ports of one plant or agent process.
pub struct IoxData {
    me: Proc,
    meas_pubs: Vec<Publisher<Svc, Measurement, ()>>,
    meas_sub: Option<Subscriber<Svc, Measurement, ()>>,
    share_pub: Option<Publisher<Svc, Share, ()>>,
    /// (owner id, subscriber), in a fixed order.
    share_subs: Vec<(u32, Subscriber<Svc, Share, ()>)>,
    /// The run's doorbells, and this process's slot in them.
    bells: Doorbells,
    slot: usize,
    /// The slots this process rings (with gateways, the gateway's for every process of other
    /// hosts); the plant's first for an agent. Plant: agent i's at index i − 1.
    rings: Vec<usize>,
    /// The share subscribers the next drain looks at.
    marks: Marks,
    /// Run control rang this process's doorbell, or a wait ended without any ring, since
    /// [`DataPath::control_rung`] last said so.
    control_rung: bool,
}

/// Which share subscribers a drain looks at: those whose owner notified this process since the
/// last drain (the bits of its doorbell), or every one when a wait ended without a ring (the
/// doorbell loses none, but a sender that died between its sample and its ring leaves one
/// unrung: it costs at most that wait's poll). Agents with two neighbours too: below eight
/// subscriptions every drain looked at all of them, as the bookkeeping seemed dearer than a
/// receive, but a thousand processes on two cores run with cold caches, where every receive on a
/// subscriber that nobody rang reads iceoryx2's shared state for nothing (with run control's own
/// ring, `DataPath::control_rung`, 20.5 → 22.9 steps/s for a thousand-agent ring waiting
/// `event`, two launches each; a 6- and a 50-agent ring no slower).
struct Marks {
    /// Subscriber index of each sender id (`usize::MAX`: none).
    slot: Vec<usize>,
    all: bool,
    /// Marked subscriber indices, each once (`marked` says which).
    list: Vec<usize>,
    marked: Vec<bool>,
}

impl Marks {
    fn new(owners: impl Iterator<Item = u32> + Clone) -> Self {
        let n = owners.clone().count();
        let top = owners.clone().max().unwrap_or(0) as usize;
        let mut slot = vec![usize::MAX; top + 1];
        for (k, id) in owners.enumerate() {
            slot[id as usize] = k;
        }
        Marks { slot, all: true, list: Vec::with_capacity(n), marked: vec![false; n] }
    }
    /// A wakeup from sender `id` (an id of no subscription, e.g. the plant's own measurement
    /// sender for an agent, marks nothing).
    fn mark(&mut self, id: usize) {
        if let Some(&k) = self.slot.get(id)
            && k != usize::MAX
            && !self.marked[k]
        {
            self.marked[k] = true;
            self.list.push(k);
        }
    }
    /// Whether every subscriber must be looked at; the marked ones otherwise (then cleared).
    fn sweep_all(&self) -> bool {
        self.all
    }
    fn clear(&mut self) {
        self.all = false;
        for &k in &self.list {
            self.marked[k] = false;
        }
        self.list.clear();
    }
}

impl IoxData {
    /// Open this process's ports on the services the orchestrator created.
    pub fn open(run: &IoxRun, topo: &Topology, me: Proc) -> Result<IoxTransport, TransportError> {
        let node = run.node(&me.name())?;
        let ps_open = |what: String| -> Result<ServiceName, TransportError> { run.service(&what) };
        let open_meas = |i: u32| {
            node.service_builder(&ps_open(format!("meas/{i}"))?)
                .publish_subscribe::<Measurement>()
                .open()
                .map_err(|e| TransportError::iox(format!("open meas/{i}"), e))
        };
        let open_share = |i: u32| {
            node.service_builder(&ps_open(format!("share/{i}"))?)
                .publish_subscribe::<Share>()
                .open()
                .map_err(|e| TransportError::iox(format!("open share/{i}"), e))
        };
        let bells = Doorbells::open(&run.root_dir(), topo.n_agents() as usize)?;
        // Whose doorbell rings for a message to `p`: p's own, or, when p runs on another host,
        // this host's gateway's.
        let slot_of = |p: Proc| match &run.domain {
            Some(d) if !d.is_local(p) => bells.gateway_slot(),
            _ => p.sender_id() as usize,
        };
        let mut rings: Vec<usize> = Vec::new();
        let mut ring = |p: Proc, dedup: bool| {
            let s = slot_of(p);
            if !(dedup && rings.contains(&s)) {
                rings.push(s);
            }
        };
        let share_sub = |i: u32| -> Result<(u32, Subscriber<Svc, Share, ()>), TransportError> {
            let s = open_share(i)?
                .subscriber_builder()
                .buffer_size(SHARE_BUFFER)
                .create()
                .map_err(|e| TransportError::iox(format!("subscribe share/{i}"), e))?;
            Ok((i, s))
        };

        let mut meas_pubs = Vec::new();
        let mut meas_sub = None;
        let mut share_pub = None;
        let mut share_subs = Vec::new();
        match me {
            Proc::Plant => {
                for i in 1..=topo.n_agents() {
                    meas_pubs.push(
                        open_meas(i)?
                            .publisher_builder()
                            .create()
                            .map_err(|e| TransportError::iox("meas publisher", e))?,
                    );
                    share_subs.push(share_sub(i)?);
                    ring(Proc::Agent(i), false);
                }
            }
            Proc::Agent(id) => {
                meas_sub = Some(
                    open_meas(id)?
                        .subscriber_builder()
                        .buffer_size(MEAS_BUFFER)
                        .create()
                        .map_err(|e| TransportError::iox("meas subscriber", e))?,
                );
                share_pub = Some(
                    open_share(id)?
                        .publisher_builder()
                        .create()
                        .map_err(|e| TransportError::iox("share publisher", e))?,
                );
                for &j in topo.neighbours_of(id) {
                    share_subs.push(share_sub(j)?);
                }
                ring(Proc::Plant, true);
                for j in topo.readers_of(id) {
                    ring(Proc::Agent(j), true);
                }
            }
        }
        // Ports hold their own references to the node's shared state; the node moves into the
        // control part, which is dropped after the data ports (field order of `Split`).
        let control = IoxControl::with_node(run, node)?;
        let marks = Marks::new(share_subs.iter().map(|(id, _)| *id));
        Ok(Split {
            data: Self {
                me,
                meas_pubs,
                meas_sub,
                share_pub,
                share_subs,
                bells,
                slot: me.sender_id() as usize,
                rings,
                marks,
                control_rung: true,
            },
            control,
        })
    }

    fn drain_share(&self, k: usize, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        let (from, sub) = &self.share_subs[k];
        while let Some(s) = sub.receive().map_err(|e| TransportError::iox("receive share", e))? {
            f(Incoming::Share { from: *from, share: s.payload() });
        }
        Ok(())
    }
}

impl DataPath for IoxData {
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError> {
        let idx = (to as usize).checked_sub(1).filter(|&i| i < self.meas_pubs.len());
        let Some(idx) = idx else {
            return Err(TransportError::Other(format!("{} cannot send a measurement to agent {to}", self.me.name())));
        };
        let sample = self.meas_pubs[idx].loan_uninit().map_err(|e| TransportError::iox("loan measurement", e))?;
        let mut m = *m;
        m.header.sent_wall_ns = monotonic_ns();
        sample.write_payload(m).send().map_err(|e| TransportError::iox("send measurement", e))?;
        self.bells.ring(self.rings[idx], self.slot);
        Ok(())
    }

    fn send_share(&mut self, s: &Share) -> Result<(), TransportError> {
        let Some(p) = &self.share_pub else {
            return Err(TransportError::Other("the plant has no share to send".into()));
        };
        let sample = p.loan_uninit().map_err(|e| TransportError::iox("loan share", e))?;
        let mut s = *s;
        s.header.sent_wall_ns = monotonic_ns();
        sample.write_payload(s).send().map_err(|e| TransportError::iox("send share", e))?;
        for &r in &self.rings {
            self.bells.ring(r, self.slot);
        }
        Ok(())
    }

    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        // Rings first, then the samples: a ring after this is seen by the next wait.
        let (marks, rung, control) = (&mut self.marks, &mut self.control_rung, self.bells.control_sender());
        let mut plant_rang = false;
        self.bells.take(self.slot, |id| {
            *rung |= id == control;
            plant_rang |= id == PLANT_ID as usize;
            marks.mark(id);
        });
        // The measurement subscriber only when the plant (or the gateway, as its stand-in) rang,
        // or on a sweep: a receive reads iceoryx2's shared state, cold among many processes.
        if let Some(sub) = self.meas_sub.as_ref().filter(|_| plant_rang || self.marks.sweep_all()) {
            while let Some(s) = sub.receive().map_err(|e| TransportError::iox("receive measurement", e))? {
                f(Incoming::Measurement(s.payload()));
            }
        }
        if self.marks.sweep_all() {
            for k in 0..self.share_subs.len() {
                self.drain_share(k, f)?;
            }
        } else {
            for &k in &self.marks.list {
                self.drain_share(k, f)?;
            }
        }
        self.marks.clear();
        Ok(())
    }

    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        // Not rung before the time was up (or a signal — SIGTERM, or SIGCONT after a freeze — cut
        // the wait short): the next drain looks at every subscriber, as callers re-poll and look
        // at the stop flags after every return anyway.
        if !self.bells.wait(self.slot, timeout) {
            self.marks.all = true;
            self.control_rung = true;
        }
        Ok(())
    }
    fn rung(&self) -> bool {
        self.marks.sweep_all() || self.bells.rung(self.slot)
    }
    fn keeps_ports_until_stopped(&self) -> bool {
        true
    }
    fn woken_by_control(&self) -> bool {
        true
    }
    fn control_rung(&mut self) -> bool {
        std::mem::take(&mut self.control_rung)
    }
    fn wait_advice(&self) -> u64 {
        self.bells.advice()
    }
    fn set_wait_advice(&self, advice: u64) {
        self.bells.set_advice(advice);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A drain after wakeups looks at exactly the senders that woke it, each once, in the order
    /// they woke it; after a wait with none, at all of them.
    #[test]
    fn a_drain_looks_at_the_senders_that_woke_it() {
        let mut m = Marks::new(1..=20u32);
        assert!(m.sweep_all(), "the first drain looks at everything");
        m.clear();
        for id in [7, 3, 7, 0, 99] {
            m.mark(id);
        }
        assert!(!m.sweep_all());
        assert_eq!(m.list, vec![6, 2], "agents 7 and 3, once each; ids of no subscription ignored");
        m.clear();
        assert!(m.list.is_empty() && m.marked.iter().all(|&b| !b));
        m.all = true;
        assert!(m.sweep_all(), "a wait that ended with no wakeup sweeps");
        let mut two = Marks::new([4u32, 9].into_iter());
        two.clear();
        two.mark(9);
        two.mark(10);
        assert!(!two.sweep_all());
        assert_eq!(two.list, vec![1], "an agent's two neighbours are marked too; the control id is ignored");
    }

    /// iceoryx2's dead-node scans cost O(nodes) on every node creation, node drop and service
    /// open, so O(N²) for a run's start-up (a 256-agent ring took 20 s to start with them, 3.4 s
    /// without); the orchestrator cleans up instead. A default that comes back is caught here.
    #[test]
    fn every_dead_node_scan_is_off() {
        let cfg = IoxRun::new(1).config().unwrap();
        assert!(!cfg.global.node.cleanup_dead_nodes_on_creation);
        assert!(!cfg.global.node.cleanup_dead_nodes_on_destruction);
        assert!(!cfg.global.service.cleanup_dead_nodes_on_open);
    }

    /// The longest root this user could get still leaves room for iceoryx2's socket names.
    #[test]
    fn the_default_root_fits_a_socket_path() {
        if std::env::var_os("XDG_RUNTIME_DIR").is_none() {
            let run = IoxRun::new(u64::MAX);
            assert!(run.root_dir().as_os_str().len() <= MAX_ROOT_DIR_LEN, "{}", run.root_dir().display());
            assert!(run.check_root_len().is_ok());
        }
    }
}
