//! The gateways of one run as the supervisor sees them: started before any plant or agent,
//! watched while the run goes (a remote gateway's end is its host's loss; the local one's fails
//! the run, whose local processes can then reach no one), stopped after the last process.

use std::process::ExitStatus;
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

use cohort_runtime::paper::Setup;
use cohort_runtime::record::RunDirs;
use cohort_wire::transport::iox::IoxRun;

use super::proc_name;
use crate::hostproto::SpawnRequest;
use crate::remote::{HostLink, Remote};
use crate::supervise::{Handle, sibling_binary, spawn_child};

/// How long a stopped gateway has to end before it is killed.
const STOP_GRACE: Duration = Duration::from_secs(5);

struct Gateway {
    host: u16,
    handle: Handle,
    link: Option<Arc<HostLink>>,
    exit: Option<ExitStatus>,
}

/// Every gateway of a run.
pub(crate) struct Gateways {
    list: Mutex<Vec<Gateway>>,
}

impl Gateways {
    /// Start a gateway on every host that runs a process of `s` and wait until each has made its
    /// domain's services (the host's processes open them).
    pub fn start(
        s: &Setup,
        dirs: &RunDirs,
        run: &IoxRun,
        remote: &Arc<Remote>,
        scenario_toml: &str,
    ) -> Result<Self, String> {
        let placement = Arc::new(s.placement());
        let gateways = Gateways { list: Mutex::new(Vec::new()) };
        let timeout = Duration::from_secs_f64(s.run.startup_timeout_s);
        for host in placement.hosts() {
            let started = if host == 0 {
                let local = run.clone().in_domain(Arc::clone(&placement), 0);
                start_local(dirs, &local, remote, timeout).map(|h| (h, None))
            } else {
                let spec = &s.hosts[host as usize - 1];
                let link = remote.host(&spec.name).ok_or_else(|| format!("host {} has no link", spec.name))?;
                start_remote(run, remote, link, host, scenario_toml).map(|h| (h, Some(Arc::clone(link))))
            };
            match started {
                Ok((handle, link)) => gateways.lock().push(Gateway { host, handle, link, exit: None }),
                Err(e) => {
                    gateways.stop();
                    return Err(e);
                }
            }
        }
        Ok(gateways)
    }

    fn lock(&self) -> std::sync::MutexGuard<'_, Vec<Gateway>> {
        self.list.lock().unwrap_or_else(|p| p.into_inner())
    }

    /// Look at every gateway: a remote one that ended makes its host lost (its processes count
    /// as killed); the local one's end is returned, as the run's error.
    pub fn check(&self) -> Option<String> {
        for g in self.lock().iter_mut().filter(|g| g.exit.is_none()) {
            let Some(st) = g.handle.try_wait() else { continue };
            g.exit = Some(st);
            match &g.link {
                Some(link) => {
                    tracing::warn!("the gateway of host {} ended ({st}): the host is lost to the run", link.name);
                    link.gateway_ended();
                }
                None => {
                    return Some(format!("this machine's gateway ({}) ended during the run ({st})", proc_name(g.host)));
                }
            }
        }
        None
    }

    /// Stop every gateway (the run's processes are gone): SIGTERM, then SIGKILL after a grace;
    /// this machine's domain is removed whatever the gateway managed itself.
    pub fn stop(&self) {
        let mut list = self.lock();
        for g in list.iter().filter(|g| g.exit.is_none()) {
            g.handle.signal(libc::SIGTERM);
        }
        let until = Instant::now() + STOP_GRACE;
        while Instant::now() < until && list.iter().any(|g| g.exit.is_none() && !g.gone()) {
            for g in list.iter_mut().filter(|g| g.exit.is_none()) {
                g.exit = g.handle.try_wait();
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        for g in list.iter_mut().filter(|g| g.exit.is_none() && !g.gone()) {
            tracing::warn!("{} did not stop within {} s: killed", proc_name(g.host), STOP_GRACE.as_secs());
            g.exit = g.handle.kill_wait();
        }
        if list.iter().any(|g| g.host == 0) {
            // A killed gateway leaves its domain and lock file; its lock is released with it.
            IoxRun::sweep_stale();
        }
    }
}

impl Gateway {
    /// Whether its end can no longer be learnt (its daemon is gone).
    fn gone(&self) -> bool {
        self.link.as_ref().is_some_and(|l| l.daemon_lost())
    }
}

/// This machine's gateway, once its domain's services exist.
fn start_local(dirs: &RunDirs, run: &IoxRun, remote: &Remote, timeout: Duration) -> Result<Handle, String> {
    let bin = sibling_binary("orchestrator")?;
    let name = proc_name(0);
    let log_path = dirs.logs().join(format!("{name}.log"));
    let args = ["gateway", "--host-index", "0"].map(String::from);
    let zenoh = Some((remote.local_connect.as_str(), remote.local_listen.as_str()));
    let mut child = spawn_child(&bin, &name, (&args, &[]), dirs, run, zenoh, false)?;
    let ended = || {
        let st = child.try_wait().ok().flatten()?;
        let line = std::fs::read_to_string(&log_path).ok().and_then(|t| t.lines().last().map(str::to_string));
        Some(format!("{st}: {}", line.unwrap_or_default()))
    };
    match super::wait_until_ready(run.run_id, 0, timeout, ended) {
        Ok(()) => Ok(Handle::Local(child)),
        Err(e) => {
            let _ = child.kill();
            let _ = child.wait();
            Err(format!("{e} (see logs/{name}.log)"))
        }
    }
}

/// Host `host`'s gateway, through its daemon (which answers once the gateway is ready).
fn start_remote(
    run: &IoxRun,
    remote: &Arc<Remote>,
    link: &Arc<HostLink>,
    host: u16,
    scenario_toml: &str,
) -> Result<Handle, String> {
    let req = SpawnRequest {
        run_id: run.run_id,
        build_id: cohort_wire::build_id().into(),
        proc_name: proc_name(host),
        restore_at: None,
        // Not a stepping process: the daemon gives a gateway its own time to get ready.
        step_timeout_s: 0.0,
        scenario_toml: scenario_toml.to_string(),
        key_hex: run.key.map(|k| k.bytes().iter().map(|b| format!("{b:02x}")).collect()),
        connect: vec![link.connect.clone()],
        listen: vec![link.listen.clone()],
        log: Some(cohort_runtime::logging::ChildLog::current()),
    };
    let pid = remote.spawn(link, &req)?;
    Ok(Handle::Remote { remote: Arc::clone(remote), link: Arc::clone(link), proc_name: proc_name(host), pid })
}
