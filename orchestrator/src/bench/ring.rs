//! The consensus ring as scenario text: most rows run it, changed in one respect (waiting,
//! transport, link delay, null computation, pacing, authentication, placement, algorithm).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cohort_runtime::paper::Setup;
use cohort_scenario::Overrides;

/// How a bench scenario differs from the plain consensus ring.
#[derive(Clone, Copy)]
pub(crate) struct RingRun<'a> {
    pub(crate) wait: &'a str,
    pub(crate) transport: &'a str,
    /// With zenoh: `gateway` (the default) or `peers` (run.zenoh_links).
    pub(crate) zenoh_links: &'a str,
    pub(crate) link_delay_steps: u32,
    /// The null plant and algorithm: the same processes and message sizes, no computation.
    pub(crate) null: bool,
    pub(crate) dt_s: f64,
    pub(crate) realtime: bool,
    /// run.authenticate: every message sealed and checked with the run's key.
    pub(crate) authenticate: bool,
    /// A hosts file placing the processes (multi-host zenoh runs).
    pub(crate) hosts: Option<&'a Path>,
    /// An `[algorithm]` section replacing the ring's (a Python twin of the Rust kind).
    pub(crate) algorithm: Option<&'a str>,
}

pub(crate) const RING: RingRun<'static> = RingRun {
    wait: "adaptive",
    transport: "iceoryx2",
    zenoh_links: "gateway",
    link_delay_steps: 0,
    null: false,
    dt_s: 0.01,
    realtime: false,
    authenticate: false,
    hosts: None,
    algorithm: None,
};

/// The consensus ring with `n` agents (each hears i−1 and i+1), `steps` steps, configured like
/// any file, so the bench runs what users run (`orchestrator generate ring` writes the same text).
pub(crate) fn ring(n: u32, steps: u64, r: RingRun<'_>) -> Result<Setup, String> {
    let (name, t) = ring_text(n, steps, r);
    let file = PathBuf::from(format!("{name}.toml"));
    let hosts = r.hosts.map(cohort_scenario::hosts::HostsFile::load).transpose().map_err(|e| e.to_string())?;
    let s = cohort_scenario::parse(&t, &file, &Overrides { hosts, ..Default::default() }).map_err(|e| e.to_string())?;
    cohort_runtime::paper::configure(s, cohort_registry::PAPERS)
        .map_err(|problems| cohort_scenario::ScenarioError { file, problems }.to_string())
}

/// The ring's scenario name and text (see [`ring`]): every agent starts scattered about its slot
/// on a circle of radius 2·N m, so there is work to do.
pub(crate) fn ring_text(n: u32, steps: u64, r: RingRun<'_>) -> (String, String) {
    let radius = 2.0 * f64::from(n);
    let name = if r.null { format!("bench-null{n}") } else { format!("bench-ring{n}") };
    let mut t = format!(
        "[scenario]\nname = \"{name}\"\nseed = 7\ndt_s = {:?}\nduration_s = {:?}\n\n[run]\nstep_timeout_s = 60.0\n\
         startup_timeout_s = 300.0\nwait = \"{}\"\ntransport = \"{}\"\nlink_delay_steps = {}\n",
        r.dt_s,
        steps as f64 * r.dt_s,
        r.wait,
        r.transport,
        r.link_delay_steps
    );
    if r.transport == "zenoh" && r.zenoh_links != "gateway" {
        let _ = writeln!(t, "zenoh_links = \"{}\"", r.zenoh_links);
    }
    if r.realtime {
        t.push_str("realtime_rate = 1.0\n");
    }
    if r.authenticate {
        t.push_str("authenticate = true\n");
    }
    if let Some(algorithm) = r.algorithm {
        let plant = if r.null {
            "[plant]\nkind = \"null\"\nreadings = 3\n".to_string()
        } else {
            format!(
                "[plant]\nkind = \"double-integrator\"\nposition_noise_std_m = 0.05\nformation_radius_m = {radius:?}\n"
            )
        };
        let _ = write!(t, "\n{plant}\n{algorithm}");
    } else if r.null {
        t.push_str("\n[plant]\nkind = \"null\"\nreadings = 3\n\n[algorithm]\nkind = \"null\"\nshare_values = 6\n");
    } else {
        let _ = write!(
            t,
            "\n[plant]\nkind = \"double-integrator\"\nposition_noise_std_m = 0.05\n\n[algorithm]\n\
             kind = \"consensus-formation\"\nformation_radius_m = {radius:?}\nkp_per_s2 = 0.5\nkd_per_s = 1.5\n\
             observer_l1_per_s = 6.0\nobserver_l2_per_s2 = 9.0\n"
        );
    }
    for i in 1..=n {
        let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
        let _ = write!(t, "\n[[agents]]\nid = {i}\nneighbours = [{}, {}]\n", (i + n - 2) % n + 1, i % n + 1);
        if !r.null {
            // Start scattered about the slots so there is work to do.
            let r0 = [1.3 * radius * a.cos() + f64::from(i % 3), 0.7 * radius * a.sin(), f64::from(i % 5) - 2.0];
            let _ = writeln!(t, "r0_m = [{:?}, {:?}, {:?}]\nv0_mps = [0.0, 0.0, 0.0]", r0[0], r0[1], r0[2]);
        }
    }
    (name, t)
}
