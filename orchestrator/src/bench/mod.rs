//! `orchestrator bench`: what the multi-process run costs, measured in one invocation with
//! interleaved repetitions (the machine is shared and noisy: medians, min–max, and ratios taken
//! within the same invocation). Writes `bench/results.json` and `bench/results.md`.
//!
//! Cases: each paper's headline scenario (`PaperHost::bench_scenarios`, e.g. the Lb-DNN
//! servicing case, 360 s) multi-process vs in-process reference; the consensus ring at
//! N = 6, 20, 50, 100 agent processes with each waiting strategy (event, poll+yield, adaptive),
//! with a one-step link delay, and as a null round (same processes and message sizes, no
//! computation); the UDP-loopback transport at N = 6 and 50; N = 100 over 10 000 steps (the
//! no-stall target); agents idling behind a plant paced at 10 Hz (their CPU share); the N = 6 ring
//! with two busy-loop hogs the bench starts and stops itself ("loaded": `event` against the
//! default, goal ≤ 1.2× the time of `event`); the cost of `run.authenticate` (the N = 6 ring
//! with it, and ns to seal and check one share); and zenoh (issue 20): the round trip between two
//! processes, and steps/s of the headline (shortened to 2 000 steps) and the ring at N = 6 and 20
//! over zenoh against iceoryx2 on one host, and over zenoh across three network namespaces
//! ([`cohort_supervisor::netlab`], when this runs as root) with no delay and with 1 ms each way, each
//! reported as steps/s × round trip (1.0: one round trip per step). The lab's links are veth pairs
//! delayed by the kernel's netem where the kernel has it, else TAP pairs with the user-space pump
//! of [`cohort_supervisor::linkemu`] (the rows say which); with the pump, the bench also measures
//! the round trip across a veth lab, so the pump's own latency can be read off.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use std::fmt::Write as _;

use cohort_runtime::paper::Setup;
use cohort_scenario::Overrides;
use serde::Serialize;

use cohort_supervisor::netlab::{Lab, Links};

use crate::summary::Summary;

mod python;

/// One benchmark case: a scenario and how to run it.
#[derive(Clone)]
struct Case {
    /// Stable key, e.g. `ring/N=20/poll`.
    key: String,
    group: &'static str,
    n: u32,
    variant: String,
    /// What the case's section calls it (a headline scenario's name).
    label: String,
    scenario: Setup,
    reference: bool,
    /// Run with two busy-loop hogs on the machine (the "loaded" rows).
    hogs: bool,
    /// Across the lab's namespaces, with this delay on what every namespace sends (zero: none).
    lab: Option<Duration>,
}

/// What one run of a case measured.
#[derive(Debug, Clone, Serialize)]
struct Sample {
    wall_s: f64,
    steps: u64,
    steps_per_s: f64,
    round_p50_us: f64,
    round_p99_us: f64,
    round_max_ms: f64,
    startup_s: Option<f64>,
    /// Median over agent processes; and the plant's.
    agent_cpu_s_per_1000_steps: f64,
    plant_cpu_s_per_1000_steps: f64,
    agent_cpu_share: f64,
    agent_rss_mb: f64,
    plant_rss_mb: f64,
    /// Share of the plant's round spent in the agents' own computation (median over agents of
    /// compute / round), from timing/.
    compute_share: Option<f64>,
    /// Agents that solve an optimisation problem every step (their end reports' solver
    /// statistics): the median over agents of their solve-time p50, the largest p99 and the
    /// largest single solve, µs. None when no agent reports a solver.
    solver_p50_us: Option<f64>,
    solver_p99_us: Option<f64>,
    solver_max_us: Option<f64>,
    /// Every process's waits for messages, summed (how adaptive waiting spun or blocked).
    wait: cohort_runtime::record::WaitStats,
    /// An agent's own computation per step (share and step, from timing/): the median over the
    /// first agents of each one's median, µs.
    agent_compute_us: Option<f64>,
}

#[derive(Debug, Serialize)]
struct Aggregate {
    key: String,
    group: String,
    label: String,
    n: u32,
    variant: String,
    samples: Vec<Sample>,
    steps_per_s_median: f64,
    steps_per_s_min: f64,
    steps_per_s_max: f64,
    wall_s_median: f64,
}

/// The median of `xs` (sorted in place) by `cohort_report::stats`'s rule; NaN when empty.
fn median(xs: &mut [f64]) -> f64 {
    xs.sort_by(f64::total_cmp);
    cohort_report::stats::median(xs)
}

/// How a bench scenario differs from the plain consensus ring.
#[derive(Clone, Copy)]
struct RingRun<'a> {
    wait: &'a str,
    transport: &'a str,
    link_delay_steps: u32,
    /// The null plant and algorithm: the same processes and message sizes, no computation.
    null: bool,
    dt_s: f64,
    realtime: bool,
    /// run.authenticate: every message sealed and checked with the run's key.
    authenticate: bool,
    /// A hosts file placing the processes (multi-host zenoh runs).
    hosts: Option<&'a Path>,
    /// An `[algorithm]` section replacing the ring's (a Python twin of the Rust kind).
    algorithm: Option<&'a str>,
}

const RING: RingRun<'static> = RingRun {
    wait: "adaptive",
    transport: "iceoryx2",
    link_delay_steps: 0,
    null: false,
    dt_s: 0.01,
    realtime: false,
    authenticate: false,
    hosts: None,
    algorithm: None,
};

/// The consensus ring with `n` agents (each hears i−1 and i+1), `steps` steps, as scenario text
/// (configured like any file, so the bench runs what users run).
fn ring(n: u32, steps: u64, r: RingRun<'_>) -> Result<Setup, String> {
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
    let file = PathBuf::from(format!("{name}.toml"));
    let hosts = r.hosts.map(cohort_scenario::hosts::HostsFile::load).transpose().map_err(|e| e.to_string())?;
    let s = cohort_scenario::parse(&t, &file, &Overrides { hosts, ..Default::default() }).map_err(|e| e.to_string())?;
    cohort_runtime::paper::configure(s, cohort_registry::PAPERS)
        .map_err(|problems| cohort_scenario::ScenarioError { file, problems }.to_string())
}

/// Every case; the Python rows only when `only` may choose one of them (building them imports
/// their modules, numpy included, so a Rust case must not need a Python environment).
fn cases(
    quick: bool,
    repo: &Path,
    lab_dir: Option<&Path>,
    scratch: &Path,
    only: Option<&str>,
) -> Result<Vec<Case>, String> {
    let ns: &[u32] = if quick { &[6, 20] } else { &[6, 20, 50, 100] };
    let steps = if quick { 500 } else { 2000 };
    let mut out = Vec::new();
    let mut push = |group: &'static str, n: u32, variant: &str, label: &str, scenario: Setup, reference: bool| {
        // A headline case is named by its scenario; the others by group alone.
        let key = if group == "headline" {
            format!("{group}/{label}/N={n}/{variant}")
        } else {
            format!("{group}/N={n}/{variant}")
        };
        let hogs = group == "loaded";
        out.push(Case {
            key,
            group,
            n,
            variant: variant.into(),
            label: label.into(),
            scenario,
            reference,
            hogs,
            lab: None,
        });
    };
    for file in cohort_registry::HOSTS.iter().flat_map(|h| h.bench_scenarios()) {
        // Quick mode shortens a headline run to 20 s; a scenario that is not valid shortened (its
        // own times reach past 20 s) runs whole.
        let o = Overrides { duration_s: quick.then_some(20.0), ..Default::default() };
        let s = match crate::load(&repo.join(file), &o) {
            Ok(s) => s,
            Err(_) if quick => crate::load(&repo.join(file), &Overrides::default()).map_err(|e| e.to_string())?,
            Err(e) => return Err(e.to_string()),
        };
        let (name, n) = (s.scenario.name.clone(), s.n_agents());
        push("headline", n, "multi-process", &name, s.clone(), false);
        push("headline", n, "reference", &name, s, true);
    }
    for &n in ns {
        for wait in ["event", "poll", "adaptive"] {
            push("ring", n, wait, "ring", ring(n, steps, RingRun { wait, ..RING })?, false);
        }
        let delayed = ring(n, steps, RingRun { link_delay_steps: 1, ..RING })?;
        push("ring", n, "adaptive+link-delay", "ring", delayed, false);
        push("null", n, "adaptive", "null", ring(n, steps, RingRun { null: true, ..RING })?, false);
        if n == 6 || n == 50 || quick {
            for wait in ["event", "adaptive"] {
                push("udp", n, wait, "udp", ring(n, steps, RingRun { wait, transport: "udp", ..RING })?, false);
            }
        }
    }
    // The cost of run.authenticate at N = 6.
    let sealed = ring(6, steps, RingRun { authenticate: true, ..RING })?;
    push("mac", 6, "adaptive+authenticate", "mac", sealed, false);
    // A loaded machine: two busy-loop hogs the bench starts and stops around each of these runs.
    for wait in ["event", "adaptive"] {
        push("loaded", 6, wait, "loaded", ring(6, steps, RingRun { wait, ..RING })?, false);
    }
    // Scale: N = 200 and 256 agent processes at the machine's own open-file limit (the
    // orchestrator raises its soft limit to the hard one); start-up against N, 200 steps.
    if !quick {
        for n in [200, 256] {
            push("scale", n, "adaptive", "scale", ring(n, 200, RING)?, false);
        }
    }
    let (n_long, steps_long) = if quick { (20, 1000) } else { (100, 10_000) };
    push("long", n_long, "adaptive", "long", ring(n_long, steps_long, RING)?, false);
    // Agents behind a plant paced at 10 Hz (dt 0.1 s, real time): how much CPU do they burn?
    let idle = ring(6, if quick { 20 } else { 50 }, RingRun { dt_s: 0.1, realtime: true, ..RING })?;
    push("idle", 6, "10Hz", "idle", idle, false);
    out.extend(zenoh_cases(quick, repo, lab_dir)?);
    if only.is_none_or(python::may_choose) {
        out.extend(python::cases(quick, repo, scratch)?);
    }
    Ok(out)
}

/// The lab's "1 ms" rows: every namespace delays what it sends by 1 ms.
const DELAY_1MS: Duration = Duration::from_millis(1);

/// Loads a zenoh-row scenario: (transport, hosts file) → the setup.
type LoadFn = dyn Fn(&str, Option<&Path>) -> Result<Setup, String>;

/// The zenoh rows: the headline shortened to 2 000 steps and the ring at N = 6 and 20, over
/// iceoryx2 and zenoh on one host, and over zenoh across the lab (when there is one), without and
/// with 1 ms delay.
fn zenoh_cases(quick: bool, repo: &Path, lab_dir: Option<&Path>) -> Result<Vec<Case>, String> {
    let steps: u64 = if quick { 500 } else { 2000 };
    let mut out = Vec::new();
    let mut push = |label: String, n: u32, variant: &str, scenario: Setup, lab: Option<Duration>| {
        let key = format!("zenoh/{label}/N={n}/{variant}");
        out.push(Case {
            key,
            group: "zenoh",
            n,
            variant: variant.into(),
            label,
            scenario,
            reference: false,
            hogs: false,
            lab,
        });
    };
    let mut sets: Vec<(String, u32, Box<LoadFn>)> = Vec::new();
    // Quick (a smoke run): the 6-agent ring only.
    let headlines =
        if quick { Vec::new() } else { cohort_registry::HOSTS.iter().flat_map(|h| h.bench_scenarios()).collect() };
    for file in headlines {
        let path = repo.join(file);
        let probe = crate::load(&path, &Overrides::default()).map_err(|e| e.to_string())?;
        let duration = steps as f64 * probe.scenario.dt_s;
        let load = move |transport: &str, hosts: Option<&Path>| {
            let hosts = hosts.map(cohort_scenario::hosts::HostsFile::load).transpose().map_err(|e| e.to_string())?;
            let o = Overrides {
                duration_s: Some(duration),
                transport: Some(transport.into()),
                hosts,
                ..Default::default()
            };
            crate::load(&path, &o).map_err(|e| e.to_string())
        };
        sets.push((probe.scenario.name.clone(), probe.n_agents(), Box::new(load)));
    }
    for n in if quick { &[6u32][..] } else { &[6u32, 20][..] } {
        let n = *n;
        let load = move |transport: &str, hosts: Option<&Path>| {
            let transport: &'static str = if transport == "zenoh" { "zenoh" } else { "iceoryx2" };
            ring(n, steps, RingRun { transport, hosts, ..RING })
        };
        sets.push(("ring".into(), n, Box::new(load)));
    }
    for (label, n, load) in &sets {
        push(label.clone(), *n, "iceoryx2", load("iceoryx2", None)?, None);
        push(label.clone(), *n, "zenoh", load("zenoh", None)?, None);
        if let Some(dir) = lab_dir {
            let hosts = Lab::hosts_file(dir, *n)?;
            push(label.clone(), *n, "zenoh-3ns", load("zenoh", Some(&hosts))?, Some(Duration::ZERO));
            push(label.clone(), *n, "zenoh-3ns-1ms", load("zenoh", Some(&hosts))?, Some(DELAY_1MS));
        }
    }
    Ok(out)
}

/// Round trips measured in this bench run: (where, p50 µs, p99 µs).
#[derive(Debug, Clone, Serialize)]
struct Rtt {
    place: String,
    /// The zenoh case variant whose steps/s this round trip goes with (none: a reference row).
    variant: Option<&'static str>,
    p50_us: f64,
    p99_us: f64,
    max_ms: f64,
}

/// The zenoh round trip between an echo process and a ping process, on one host or from lab
/// namespace a to b.
fn measure_rtt(lab: Option<&Lab>, place: &str, variant: Option<&'static str>) -> Result<Rtt, String> {
    use std::process::Stdio;
    let me = std::env::current_exe().map_err(|e| e.to_string())?;
    let (listen, connect) = match lab {
        Some(_) => {
            let e = Lab::endpoint(1).replace(":7447", ":7500");
            (e.clone(), e)
        }
        None => {
            let port = std::net::TcpListener::bind("127.0.0.1:0")
                .and_then(|l| l.local_addr())
                .map_err(|e| e.to_string())?
                .port();
            (format!("tcp/127.0.0.1:{port}"), format!("tcp/127.0.0.1:{port}"))
        }
    };
    let cmd = |x: &str| match lab {
        Some(l) => l.command(x, &me),
        None => std::process::Command::new(&me),
    };
    let mut echo = cmd("b")
        .args(["zenoh-echo", "--listen", &listen])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("zenoh-echo: {e}"))?;
    std::thread::sleep(std::time::Duration::from_millis(300));
    let out = cmd("a").args(["zenoh-ping", "--connect", &connect]).output();
    // SAFETY: kill(2) on the echo this bench started.
    unsafe { libc::kill(echo.id() as libc::pid_t, libc::SIGKILL) };
    let _ = echo.wait();
    let out = out.map_err(|e| format!("zenoh-ping: {e}"))?;
    if !out.status.success() {
        return Err(format!("zenoh-ping ({place}): {}", String::from_utf8_lossy(&out.stderr).trim()));
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).map_err(|e| format!("zenoh-ping output: {e}"))?;
    let f = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    Ok(Rtt { place: place.into(), variant, p50_us: f("p50_us"), p99_us: f("p99_us"), max_ms: f("max_ms") })
}

/// The namespace lab (`None`: none can be made here, e.g. not root), with veth links where the
/// kernel has netem and pumped links where it has not. With pumped links, first the round trip
/// a → b across a veth lab made and removed for it (the two labs share names and addresses, so
/// one at a time): the pump's own latency is the difference from the pumped lab's undelayed row.
fn start_lab() -> (Option<Lab>, Option<Rtt>) {
    let links = match cohort_supervisor::netlab::netem_probe() {
        Ok(()) => Links::Veth,
        Err(e) => {
            tracing::info!("no netem on this kernel ({e}): the lab's links are TAP pairs with a user-space pump");
            Links::Pumped
        }
    };
    let veth_rtt = (links == Links::Pumped)
        .then(|| {
            let veth = Lab::start_with(Links::Veth)?;
            measure_rtt(Some(&veth), "namespace a → b across veth (no pump, no delay)", None)
        })
        .transpose()
        .unwrap_or_else(|e| {
            tracing::warn!("no veth lab for the pump's own latency: {e}");
            None
        });
    match Lab::start_with(links) {
        Ok(l) => (Some(l), veth_rtt),
        Err(e) => {
            tracing::warn!("no network-namespace lab (zenoh across namespaces not measured): {e}");
            (None, None)
        }
    }
}

/// The round trip from namespace a to b in the lab, without and with the 1 ms delay.
fn lab_rtts(l: &Lab) -> Result<Vec<Rtt>, String> {
    let how = l.links().describe();
    let plain = measure_rtt(Some(l), &format!("namespace a → b ({how}, no delay)"), Some("zenoh-3ns"))?;
    l.set_delay(DELAY_1MS)?;
    let delayed = measure_rtt(Some(l), &format!("namespace a → b, 1 ms each way ({how})"), Some("zenoh-3ns-1ms"));
    l.set_delay(Duration::ZERO)?;
    Ok(vec![plain, delayed?])
}

/// A directory removed with everything in it when dropped.
struct RemoveOnDrop(PathBuf);

impl Drop for RemoveOnDrop {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

/// Two threads that burn a core each until dropped: a machine busy with other work (the
/// "loaded" rows). As threads of the bench itself they end with it, whatever happens.
struct Hogs {
    stop: std::sync::Arc<std::sync::atomic::AtomicBool>,
    threads: Vec<std::thread::JoinHandle<()>>,
}

impl Hogs {
    fn start() -> Self {
        let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
        let threads = (0..2)
            .map(|_| {
                let stop = std::sync::Arc::clone(&stop);
                std::thread::spawn(move || {
                    let mut x = 0u64;
                    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                        x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
                    }
                })
            })
            .collect();
        Self { stop, threads }
    }
}

impl Drop for Hogs {
    fn drop(&mut self) {
        self.stop.store(true, std::sync::atomic::Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

/// ns per message to seal and check a share of `values` values (what `run.authenticate` adds to
/// every message, once at its sender and once at each reader).
fn mac_ns(values: usize) -> (f64, f64) {
    use cohort_wire::msg::{Header, Share};
    let key = cohort_wire::auth::MacKey::from_bytes([7; 32]);
    let vals: Vec<f64> = (0..values).map(|i| i as f64 * 0.5).collect();
    let mut s = Share::new(Header::new(1, 2, 3, 0.03), &[1.0, 2.0, 3.0], &vals);
    let n = 200_000u32;
    let t0 = Instant::now();
    for k in 0..n {
        s.header.step = u64::from(k);
        key.seal_share(std::hint::black_box(&mut s));
    }
    let seal = t0.elapsed().as_secs_f64() * 1e9 / f64::from(n);
    let t1 = Instant::now();
    let mut ok = 0u32;
    for _ in 0..n {
        ok += u32::from(key.check_share(std::hint::black_box(&s)));
    }
    let check = t1.elapsed().as_secs_f64() * 1e9 / f64::from(n);
    assert_eq!(ok, n, "a sealed share always checks");
    (seal, check)
}

/// One column of a process's timing file (Parquet or CSV), as f64.
fn timing_column(dir: &Path, process: &str, col: &str) -> Vec<f64> {
    cohort_runtime::record::timing_column(&dir.join("timing"), process, col).into_iter().map(|v| v as f64).collect()
}

fn sample(s: &Setup, dir: &Path, summary: &Summary, wall_s: f64) -> Sample {
    let round = summary.latency_ns.get("plant_round");
    let steps = summary.steps_completed.max(1);
    let per_k = |cpu: f64| cpu / steps as f64 * 1000.0;
    let mut agent_cpu: Vec<f64> = Vec::new();
    let mut agent_rss: Vec<f64> = Vec::new();
    let mut agent_share: Vec<f64> = Vec::new();
    let mut plant_cpu = f64::NAN;
    let mut plant_rss = f64::NAN;
    let (mut solver_p50, mut solver_p99, mut solver_max): (Vec<f64>, Vec<f64>, Vec<f64>) = Default::default();
    for st in summary.processes.iter().filter_map(|p| p.solver.as_ref()).filter(|st| st.solves > 0) {
        solver_p50.push(st.solve_time_p50_s * 1e6);
        solver_p99.push(st.solve_time_p99_s * 1e6);
        solver_max.push(st.solve_time_max_s * 1e6);
    }
    let largest = |xs: &[f64]| xs.iter().copied().reduce(f64::max);
    let mut wait = cohort_runtime::record::WaitStats::default();
    for p in &summary.processes {
        wait.waits += p.wait.waits;
        wait.spun += p.wait.spun;
        wait.spin_stalls += p.wait.spin_stalls;
        wait.spin_expired += p.wait.spin_expired;
        wait.spin_s += p.wait.spin_s;
        if p.process == "plant" {
            plant_cpu = per_k(p.cpu_s);
            plant_rss = p.max_rss_kb as f64 / 1024.0;
        } else {
            agent_cpu.push(per_k(p.cpu_s));
            agent_rss.push(p.max_rss_kb as f64 / 1024.0);
            if p.wall_s > 0.0 {
                agent_share.push(p.cpu_s / p.wall_s);
            }
        }
    }
    // Compute share of the round: agent compute (median agent) over plant round, per step.
    let rounds = timing_column(dir, "plant", "round_ns");
    let compute = timing_column(dir, "agent-1", "compute_ns");
    let compute_share = (!rounds.is_empty() && rounds.len() == compute.len()).then(|| {
        let mut r: Vec<f64> = compute.iter().zip(&rounds).map(|(c, r)| c / r.max(1.0)).collect();
        median(&mut r)
    });
    let mut per_agent: Vec<f64> = (1..=s.n_agents().min(8))
        .filter_map(|i| {
            let mut c = timing_column(dir, &format!("agent-{i}"), "compute_ns");
            (!c.is_empty()).then(|| median(&mut c) / 1e3)
        })
        .collect();
    let agent_compute_us = (!per_agent.is_empty()).then(|| median(&mut per_agent));
    Sample {
        wall_s,
        steps: summary.steps_completed,
        steps_per_s: summary.steps_per_s,
        round_p50_us: round.map_or(f64::NAN, |p| p.p50 as f64 / 1e3),
        round_p99_us: round.map_or(f64::NAN, |p| p.p99 as f64 / 1e3),
        round_max_ms: round.map_or(f64::NAN, |p| p.max as f64 / 1e6),
        startup_s: summary.startup_s,
        agent_cpu_s_per_1000_steps: median(&mut agent_cpu),
        plant_cpu_s_per_1000_steps: plant_cpu,
        agent_cpu_share: median(&mut agent_share),
        agent_rss_mb: median(&mut agent_rss),
        plant_rss_mb: plant_rss,
        compute_share,
        solver_p50_us: (!solver_p50.is_empty()).then(|| median(&mut solver_p50)),
        solver_p99_us: largest(&solver_p99),
        solver_max_us: largest(&solver_max),
        wait,
        agent_compute_us,
    }
}

/// Why the bench did not run to the end.
#[derive(Debug)]
pub enum BenchError {
    /// The arguments select nothing (exit 2).
    Invalid(String),
    /// A case could not be set up or run (exit 1).
    Failed(String),
}

impl From<String> for BenchError {
    fn from(e: String) -> Self {
        Self::Failed(e)
    }
}

/// Run every case (or only those whose key starts with `only`), `reps` times interleaved.
pub fn run(quick: bool, reps: u32, only: Option<&str>, out_dir: &Path) -> Result<String, BenchError> {
    let repo = std::env::current_dir().map_err(|e| e.to_string())?;
    let scratch = std::env::temp_dir().join(format!("cohort-bench-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&scratch);
    // Declared before the lab, so dropped after it (the lab writes under the scratch directory
    // until it is torn down), whichever way this function returns.
    let _scratch_guard = RemoveOnDrop(scratch.clone());
    // The cases are listed as if the lab were there, so that `--only` decides whether it is
    // built at all (it takes root, namespaces and seconds): only when a chosen case crosses it.
    let lab_dir = scratch.join("lab");
    let mut cases = cases(quick, &repo, Some(lab_dir.as_path()), &scratch, only)?;
    if let Some(prefix) = only {
        let mut all: Vec<String> = cases.iter().map(|c| c.key.clone()).collect();
        if !python::may_choose(prefix) {
            all.push(format!("{}…", python::KEY_PREFIX));
        }
        cases.retain(|c| c.key.starts_with(prefix));
        if cases.is_empty() {
            return Err(BenchError::Invalid(format!(
                "--only {prefix:?}: no case key starts with it (keys: {})",
                all.join(", ")
            )));
        }
    }
    let wants_lab = cases.iter().any(|c| c.lab.is_some());
    let (lab, veth_rtt) = if wants_lab {
        start_lab()
    } else {
        tracing::info!("no chosen case crosses the network-namespace lab: not building it");
        (None, None)
    };
    if lab.is_none() && wants_lab {
        cases.retain(|c| c.lab.is_none());
        if cases.is_empty() {
            return Err(BenchError::Failed(format!(
                "--only {:?}: every chosen case crosses the network-namespace lab, which cannot be made here",
                only.unwrap_or("")
            )));
        }
    }
    let mut rtts = vec![measure_rtt(None, "one host (TCP loopback)", Some("zenoh"))?];
    rtts.extend(veth_rtt);
    if let Some(l) = &lab {
        rtts.extend(lab_rtts(l)?);
    }
    let mut samples: BTreeMap<String, Vec<Sample>> = BTreeMap::new();
    let started = Instant::now();
    // Interleaved: every case once per repetition, so slow phases of a shared machine hit all.
    for rep in 0..reps {
        for c in &cases {
            let dir = scratch.join(format!("{}-{rep}", c.key.replace(['/', '='], "_")));
            let dirs =
                crate::prepare(&c.scenario, Some(&dir)).map_err(|_| format!("{}: cannot prepare", dir.display()))?;
            let hogs = c.hogs.then(Hogs::start);
            if let (Some(l), Some(delay)) = (&lab, c.lab) {
                l.set_delay(delay)?;
            }
            let (outcome, summary) = crate::run_once(&c.scenario, &dirs, c.reference, false);
            if let (Some(l), Some(_)) = (&lab, c.lab) {
                l.set_delay(Duration::ZERO)?;
            }
            drop(hogs);
            if let Some(e) = outcome.error {
                return Err(BenchError::Failed(format!("{} (repetition {}): {e}", c.key, rep + 1)));
            }
            let smp = sample(&c.scenario, &dir, &summary, outcome.wall_s);
            tracing::info!(
                "[{:6.1} s] rep {}/{reps} {:32} {:9.0} steps/s  round p50 {:8.1} µs  max {:7.2} ms",
                started.elapsed().as_secs_f64(),
                rep + 1,
                c.key,
                smp.steps_per_s,
                smp.round_p50_us,
                smp.round_max_ms
            );
            samples.entry(c.key.clone()).or_default().push(smp);
            let _ = std::fs::remove_dir_all(&dir);
        }
    }
    let aggregates: Vec<Aggregate> = cases
        .iter()
        .map(|c| {
            let s = samples.remove(&c.key).unwrap_or_default();
            let mut sps: Vec<f64> = s.iter().map(|x| x.steps_per_s).collect();
            let mut wall: Vec<f64> = s.iter().map(|x| x.wall_s).collect();
            Aggregate {
                key: c.key.clone(),
                group: c.group.into(),
                label: c.label.clone(),
                n: c.n,
                variant: c.variant.clone(),
                steps_per_s_median: median(&mut sps.clone()),
                steps_per_s_min: sps.iter().cloned().fold(f64::INFINITY, f64::min),
                steps_per_s_max: {
                    sps.sort_by(f64::total_cmp);
                    sps.last().copied().unwrap_or(f64::NAN)
                },
                wall_s_median: median(&mut wall),
                samples: s,
            }
        })
        .collect();
    let links = lab.as_ref().map(|l| l.links());
    drop(lab);
    let mac = [6usize, 106, 512].map(|v| (v, mac_ns(v)));
    let mut md = markdown(&aggregates, quick, reps, only, started.elapsed().as_secs_f64());
    md.push_str(&mac_markdown(&aggregates, &mac));
    md.push_str(&zenoh_markdown(&aggregates, &rtts, links));
    md.push_str(&python::markdown(&aggregates));
    std::fs::create_dir_all(out_dir).map_err(|e| format!("{}: {e}", out_dir.display()))?;
    let json = serde_json::json!({
        "machine": machine(),
        "quick": quick,
        "repetitions": reps,
        "cases": aggregates,
        "zenoh_rtt": rtts,
        "lab_links": links.map(|l| l.describe()),
        "mac_seal_check_ns": mac.iter().map(|(v, (s, c))| serde_json::json!({"values": v, "seal_ns": s, "check_ns": c})).collect::<Vec<_>>(),
        "adaptive_spin_floor_us": cohort_runtime::drive::ADAPTIVE_FLOOR_US,
        "adaptive_spin_cap_us": cohort_runtime::drive::ADAPTIVE_CAP_US,
    });
    let write = |name: &str, text: String| -> Result<PathBuf, String> {
        let p = out_dir.join(name);
        std::fs::write(&p, text).map_err(|e| format!("{}: {e}", p.display()))?;
        Ok(p)
    };
    write("results.json", serde_json::to_string_pretty(&json).map_err(|e| e.to_string())? + "\n")?;
    write("results.md", md.clone())?;
    Ok(md)
}

/// The loaded rows (goal: adaptive under load within 1.2× the time of event under load) and the
/// cost of `run.authenticate`.
fn mac_markdown(a: &[Aggregate], mac: &[(usize, (f64, f64))]) -> String {
    let mut md = String::new();
    let wall = |k: &str| get(a, k).map_or(f64::NAN, |x| x.wall_s_median);
    let sps = |k: &str| get(a, k).map_or(f64::NAN, |x| x.steps_per_s_median);
    if let (Some(ev), Some(ad)) = (get(a, "loaded/N=6/event"), get(a, "loaded/N=6/adaptive")) {
        let ratios: Vec<f64> = ad.samples.iter().zip(&ev.samples).map(|(x, y)| x.wall_s / y.wall_s).collect();
        let ratio = median(&mut ratios.clone());
        let _ = writeln!(
            md,
            "\n## Loaded machine: consensus ring N = 6 with two busy-loop hogs\n\n| wait | steps/s | wall s |\n|---|---|---|\n\
             | event | {} | {:.2} |\n| adaptive (default) | {} | {:.2} |\n| adaptive, no hogs (ring row above) | {} | {:.2} |\n\n\
             Adaptive wall / event wall under load: median {ratio:.2} (per repetition: {}); goal ≤ 1.2: {}.",
            f0(ev.steps_per_s_median),
            ev.wall_s_median,
            f0(ad.steps_per_s_median),
            ad.wall_s_median,
            f0(sps("ring/N=6/adaptive")),
            wall("ring/N=6/adaptive"),
            ratios.iter().map(|r| format!("{r:.2}")).collect::<Vec<_>>().join(", "),
            if ratio <= 1.2 { "met" } else { "not met" }
        );
        md.push_str(
            "\nWaits of every process, summed, per repetition (a wait is one that did not find its messages at once):\n\n\
             | wait | waits | spun | stalled spins | expired spins | spinning s | wall s |\n|---|---|---|---|---|---|---|\n",
        );
        for (label, agg) in [("event", ev), ("adaptive", ad)] {
            for x in &agg.samples {
                let w = &x.wait;
                let _ = writeln!(
                    md,
                    "| {label} | {} | {} | {} | {} | {:.3} | {:.2} |",
                    w.waits, w.spun, w.spin_stalls, w.spin_expired, w.spin_s, x.wall_s
                );
            }
        }
    }
    let _ = writeln!(md, "\n## run.authenticate (keyed BLAKE3 MAC on every message)\n");
    if let (Some(off), Some(on)) = (get(a, "ring/N=6/adaptive"), get(a, "mac/N=6/adaptive+authenticate")) {
        let _ = writeln!(
            md,
            "Consensus ring N = 6, adaptive: {} steps/s without, {} steps/s with (×{:.2}).\n",
            f0(off.steps_per_s_median),
            f0(on.steps_per_s_median),
            on.steps_per_s_median / off.steps_per_s_median
        );
    }
    md.push_str("| share values | seal ns | check ns |\n|---|---|---|\n");
    for (v, (seal, check)) in mac {
        let _ = writeln!(md, "| {v} | {seal:.0} | {check:.0} |");
    }
    md
}

/// The zenoh rows: steps/s and steps/s × the round trip of the same place; `links`: the lab's.
fn zenoh_markdown(a: &[Aggregate], rtts: &[Rtt], links: Option<Links>) -> String {
    let mut md = String::from(
        "\n## zenoh (multi-host transport)\n\nRound trip between two processes (256 B, 5 000 pings after 200 warm-up):\n\n| where | p50 µs | p99 µs | max ms |\n|---|---|---|---|\n",
    );
    for r in rtts {
        let _ = writeln!(md, "| {} | {:.0} | {:.0} | {:.2} |", r.place, r.p50_us, r.p99_us, r.max_ms);
    }
    let rtt_of = |variant: &str| rtts.iter().find(|r| r.variant == Some(variant)).map(|r| r.p50_us);
    if let (Some(veth), Some(pumped), Some(Links::Pumped)) =
        (rtts.iter().find(|r| r.variant.is_none()), rtt_of("zenoh-3ns"), links)
    {
        let _ = writeln!(
            md,
            "\nThe pump's own latency: {:.0} µs per round trip at p50 (pumped links with no delay against veth; a round \
             trip a → b → a passes four pumps).",
            pumped - veth.p50_us
        );
    }
    md.push_str(
        "\n| case | N | transport, placement | steps/s | RTT p50 µs | steps/s × RTT |\n|---|---|---|---|---|---|\n",
    );
    let how = links.map_or("", Links::describe);
    for x in a.iter().filter(|x| x.group == "zenoh") {
        let place = match x.variant.as_str() {
            "iceoryx2" => "iceoryx2, one host".to_string(),
            "zenoh" => "zenoh, one host (TCP loopback)".to_string(),
            "zenoh-3ns" => format!("zenoh, plant on a, agents on b and c ({how}, no delay)"),
            "zenoh-3ns-1ms" => format!("zenoh, a / b / c, 1 ms each way ({how})"),
            other => other.to_string(),
        };
        let rtt = rtt_of(&x.variant);
        let ratio = rtt.map_or("–".to_string(), |r| format!("{:.2}", x.steps_per_s_median * r * 1e-6));
        let _ = writeln!(
            md,
            "| {} | {} | {place} | {} [{}–{}] | {} | {ratio} |",
            x.label,
            x.n,
            f0(x.steps_per_s_median),
            f0(x.steps_per_s_min),
            f0(x.steps_per_s_max),
            rtt.map_or("–".to_string(), |r| format!("{r:.0}"))
        );
    }
    md
}

fn machine() -> String {
    let cores = std::thread::available_parallelism().map_or(0, |n| n.get());
    let model = std::fs::read_to_string("/proc/cpuinfo")
        .ok()
        .and_then(|t| {
            t.lines()
                .find(|l| l.starts_with("model name"))
                .map(|l| l.split(':').nth(1).unwrap_or("").trim().to_string())
        })
        .unwrap_or_else(|| "unknown CPU".into());
    let kernel = std::fs::read_to_string("/proc/sys/kernel/osrelease").unwrap_or_default().trim().to_string();
    format!("{cores} cores ({model}), Linux {kernel}")
}

/// The 1-minute load average (other users of a shared machine inflate every time measured).
fn load_average() -> String {
    std::fs::read_to_string("/proc/loadavg")
        .ok()
        .and_then(|t| t.split_whitespace().next().map(str::to_string))
        .unwrap_or_else(|| "unknown".into())
}

/// For a headline case whose agents solve an optimisation problem every step: the solve times
/// of the multi-process and the reference runs (per repetition: the median agent's p50, the
/// worst agent's p99 and the longest solve; medians over repetitions with [min–max]).
fn solver_line(mp: &Aggregate, rf: &Aggregate) -> Option<String> {
    let cell = |x: &Aggregate, f: &dyn Fn(&Sample) -> Option<f64>| -> Option<String> {
        let mut v: Vec<f64> = x.samples.iter().map(f).collect::<Option<_>>()?;
        let (lo, hi) = (v.iter().copied().fold(f64::INFINITY, f64::min), v.iter().copied().fold(0.0, f64::max));
        Some(format!("{:.1} [{:.1}–{:.1}]", median(&mut v), lo, hi))
    };
    let row = |name: &str, x: &Aggregate| -> Option<String> {
        Some(format!(
            "| {name} | {} | {} | {} |\n",
            cell(x, &|s| s.solver_p50_us)?,
            cell(x, &|s| s.solver_p99_us)?,
            cell(x, &|s| s.solver_max_us)?
        ))
    };
    let mut out = String::from(
        "Solver time per agent (the agents' end reports; per repetition the median agent's p50, the worst \
         agent's p99 and the longest solve), µs:\n\n| run | p50 | p99 | max |\n|---|---|---|---|\n",
    );
    out.push_str(&row("multi-process", mp)?);
    if let Some(r) = row("in-process reference", rf) {
        out.push_str(&r);
    }
    out.push('\n');
    Some(out)
}

fn get<'a>(a: &'a [Aggregate], key: &str) -> Option<&'a Aggregate> {
    a.iter().find(|x| x.key == key)
}

fn f0(x: f64) -> String {
    if x.is_finite() { format!("{x:.0}") } else { "–".into() }
}

fn markdown(a: &[Aggregate], quick: bool, reps: u32, only: Option<&str>, took_s: f64) -> String {
    let mut md = String::new();
    let only_arg = only.map(|p| format!(" --only {p}")).unwrap_or_default();
    let _ = writeln!(
        md,
        "# Cohort benchmarks\n\nMachine: {}; load average at the end {}. {} repetition(s), interleaved{}; medians with \
         [min–max]; generated by `orchestrator bench{}{}` in {:.0} s.\n",
        machine(),
        load_average(),
        reps,
        if quick { ", quick mode" } else { "" },
        if quick { " --quick" } else { "" },
        only_arg,
        took_s
    );
    // Each paper's headline case, multi-process against the in-process reference.
    let mut headlines: Vec<(&str, u32)> =
        a.iter().filter(|x| x.group == "headline").map(|x| (x.label.as_str(), x.n)).collect();
    headlines.dedup();
    for (label, n) in headlines {
        let (mp, rf) = (
            get(a, &format!("headline/{label}/N={n}/multi-process")),
            get(a, &format!("headline/{label}/N={n}/reference")),
        );
        let (Some(mp), Some(rf)) = (mp, rf) else { continue };
        let ratios: Vec<f64> = mp.samples.iter().zip(&rf.samples).map(|(m, r)| m.wall_s / r.wall_s).collect();
        let _ = writeln!(
            md,
            "## {label} ({n} agents, {} steps)\n\n| run | steps/s | wall s |\n|---|---|---|\n| multi-process (iceoryx2, adaptive) | {} [{}–{}] | {:.2} |\n| in-process reference | {} [{}–{}] | {:.2} |\n\nMulti-process wall / reference wall: median {:.2} (per repetition: {}).\n",
            mp.samples.first().map_or(0, |s| s.steps),
            f0(mp.steps_per_s_median),
            f0(mp.steps_per_s_min),
            f0(mp.steps_per_s_max),
            mp.wall_s_median,
            f0(rf.steps_per_s_median),
            f0(rf.steps_per_s_min),
            f0(rf.steps_per_s_max),
            rf.wall_s_median,
            median(&mut ratios.clone()),
            ratios.iter().map(|r| format!("{r:.2}")).collect::<Vec<_>>().join(", ")
        );
        if let Some(line) = solver_line(mp, rf) {
            md.push_str(&line);
        }
    }
    // Ring: strategies per N
    let mut ns: Vec<u32> = a.iter().filter(|x| x.group == "ring").map(|x| x.n).collect();
    ns.dedup();
    // `--only` may leave no ring case: then no ring sections.
    if !ns.is_empty() {
        ring_sections(&mut md, a, &ns);
    }
    // UDP
    let mut udp_ns: Vec<u32> = a.iter().filter(|x| x.group == "udp").map(|x| x.n).collect();
    udp_ns.dedup();
    if !udp_ns.is_empty() {
        md.push_str("\n## iceoryx2 vs UDP loopback (same protocol, same waits)\n\n| N | wait | iceoryx2 steps/s | UDP steps/s | iceoryx2 / UDP |\n|---|---|---|---|---|\n");
        for &n in &udp_ns {
            for w in ["event", "adaptive"] {
                let i = get(a, &format!("ring/N={n}/{w}"));
                let u = get(a, &format!("udp/N={n}/{w}"));
                if let (Some(i), Some(u)) = (i, u) {
                    let ratios: Vec<f64> =
                        i.samples.iter().zip(&u.samples).map(|(x, y)| x.steps_per_s / y.steps_per_s).collect();
                    let _ = writeln!(
                        md,
                        "| {n} | {w} | {} | {} | {:.2} |",
                        f0(i.steps_per_s_median),
                        f0(u.steps_per_s_median),
                        median(&mut ratios.clone())
                    );
                }
            }
        }
    }
    for x in a.iter().filter(|x| x.group == "long") {
        let worst = x.samples.iter().map(|s| s.round_max_ms).fold(0.0, f64::max);
        let _ = writeln!(
            md,
            "\n## N = {} agent processes, {} steps (adaptive)\n\n{} steps/s [{}–{}]; slowest step over all repetitions: {:.1} ms.",
            x.n,
            x.samples.first().map_or(0, |s| s.steps),
            f0(x.steps_per_s_median),
            f0(x.steps_per_s_min),
            f0(x.steps_per_s_max),
            worst
        );
    }
    let scale: Vec<&Aggregate> = a.iter().filter(|x| x.group == "scale").collect();
    if !scale.is_empty() {
        md.push_str(
            "\n## Scale: start-up against N (consensus ring, adaptive)\n\nStart-up: launch until every \
             process is ready (the summary's `startup_s`); medians with [min–max]. N ≤ 100 from the ring \
             rows above.\n\n| N | start-up s | start-up s per agent | steps/s |\n|---|---|---|---|\n",
        );
        for x in scale {
            let mut up: Vec<f64> = x.samples.iter().filter_map(|s| s.startup_s).collect();
            let (lo, hi) = up.iter().fold((f64::INFINITY, 0.0_f64), |(l, h), &v| (l.min(v), h.max(v)));
            let m = median(&mut up);
            let _ = writeln!(
                md,
                "| {} | {m:.2} [{lo:.2}–{hi:.2}] | {:.3} | {} [{}–{}] |",
                x.n,
                m / f64::from(x.n),
                f0(x.steps_per_s_median),
                f0(x.steps_per_s_min),
                f0(x.steps_per_s_max)
            );
        }
    }
    for x in a.iter().filter(|x| x.group == "idle") {
        let share = median(&mut x.samples.iter().map(|s| s.agent_cpu_share).collect::<Vec<_>>());
        let _ = writeln!(
            md,
            "\n## Agents behind a plant paced at 10 Hz (real time)\n\nMedian agent CPU: {:.3} % of a core.",
            100.0 * share
        );
    }
    md
}

/// The consensus ring's two tables (steps/s by strategy; per-step cost), for the N in `ns`.
fn ring_sections(md: &mut String, a: &[Aggregate], ns: &[u32]) {
    let med = |key: &str, f: &dyn Fn(&Sample) -> f64| -> f64 {
        get(a, key).map_or(f64::NAN, |x| median(&mut x.samples.iter().map(f).collect::<Vec<_>>()))
    };
    md.push_str("## Consensus ring: steps/s by waiting strategy (iceoryx2)\n\n");
    md.push_str("| N agents | event | poll + yield | adaptive | adaptive + 1-step link delay | null round (adaptive) | messaging share |\n|---|---|---|---|---|---|---|\n");
    for &n in ns {
        let cell = |k: &str| {
            get(a, k).map_or("–".to_string(), |x| {
                format!("{} [{}–{}]", f0(x.steps_per_s_median), f0(x.steps_per_s_min), f0(x.steps_per_s_max))
            })
        };
        let real = med(&format!("ring/N={n}/adaptive"), &|s| 1.0 / s.steps_per_s);
        let null = med(&format!("null/N={n}/adaptive"), &|s| 1.0 / s.steps_per_s);
        let _ = writeln!(
            md,
            "| {n} | {} | {} | {} | {} | {} | {:.0} % |",
            cell(&format!("ring/N={n}/event")),
            cell(&format!("ring/N={n}/poll")),
            cell(&format!("ring/N={n}/adaptive")),
            cell(&format!("ring/N={n}/adaptive+link-delay")),
            cell(&format!("null/N={n}/adaptive")),
            100.0 * (null / real).min(1.0)
        );
    }
    md.push_str("\n\"messaging share\": the null round's step time over the real step time (same processes and message sizes, no computation).\n\n");
    md.push_str("## Consensus ring, adaptive waiting: per-step cost\n\n| N | round p50 µs | round p99 µs | round max ms | agent CPU s / 1000 steps | plant CPU s / 1000 steps | agent RSS MB | plant RSS MB | start-up s |\n|---|---|---|---|---|---|---|---|---|\n");
    for &n in ns {
        let k = format!("ring/N={n}/adaptive");
        let _ = writeln!(
            md,
            "| {n} | {:.1} | {:.1} | {:.2} | {:.3} | {:.3} | {:.1} | {:.1} | {:.2} |",
            med(&k, &|s| s.round_p50_us),
            med(&k, &|s| s.round_p99_us),
            med(&k, &|s| s.round_max_ms),
            med(&k, &|s| s.agent_cpu_s_per_1000_steps),
            med(&k, &|s| s.plant_cpu_s_per_1000_steps),
            med(&k, &|s| s.agent_rss_mb),
            med(&k, &|s| s.plant_rss_mb),
            med(&k, &|s| s.startup_s.unwrap_or(f64::NAN)),
        );
    }
}
