//! Multi-host runs over zenoh with real processes (issue 20). Three "machines" on this one:
//! network namespaces a, b and c, each with a host daemon, joined by veth pairs to a bridge
//! (198.18.77.0/24, the benchmarking range, inside the namespaces only), made and torn down here.
//! Where `ip netns` is refused (no root, no CAP_NET_ADMIN), three daemons on loopback ports stand
//! in, and the test says so; the netem case needs the namespaces and is skipped then, saying so.
//!
//! fig1 with the plant on a and the servicers over b and c is bit-identical to `--reference`; a
//! servicer on c killed by the fault plan degrades the run exactly as on one host (bit-identical
//! to the one-host run with the same fault); the kill of b's daemon declares its servicers dead,
//! the run ends in degrade naming host b, and nothing is left running anywhere; with netem delay
//! 2 ms ± 0.5 ms and 1 % loss on c's link the run is still bit-identical and the plant's latency
//! histograms show c's servicers behind the delay. Serialised: one set of namespaces at a time.
//!
//! Host c's link is a TAP pair with a user-space pump between its ends (`cohort_supervisor::
//! linkemu`, which the bench's network lab uses too), so that the delay-and-loss case runs on
//! kernels built without `sch_netem`: the case first asks the kernel for netem on both TAPs and,
//! when it is refused, sets the same delay, jitter and loss in the pump in both directions, saying
//! which it used. Without /dev/net/tun, c gets a veth like a and b.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

use cohort::OutputWithin;
use cohort::{
    bin_path, describe_output, heavy, heavy_scratch, processes_mentioning, repo_root, scratch_dir, sh, summary,
    telemetry_bits,
};
use serde_json::Value;

use cohort_supervisor::linkemu;

/// fig1, shortened: 1.5 s of simulated time, 150 lockstep steps.
const DURATION: &str = "1.5";
pub(crate) const NAMES: [&str; 3] = ["a", "b", "c"];

/// Three namespaces on a bridge, or nothing (the loopback fallback).
pub(crate) struct Net {
    tag: String,
    namespaces: bool,
    /// Host c's link when it is a TAP pair with the pump between its ends.
    pumped: Option<linkemu::Link>,
}

impl Net {
    fn ns(&self, x: &str) -> String {
        format!("cmh{}{x}", self.tag)
    }
    fn bridge(&self) -> String {
        format!("cmhb{}", self.tag)
    }
    fn veth(&self, x: &str) -> String {
        format!("cmhv{}{x}", self.tag)
    }
    /// Host c's TAP pair: (inside the namespace, on the bridge).
    fn taps(&self) -> (String, String) {
        (format!("cmht{}c", self.tag), format!("cmht{}co", self.tag))
    }
    fn addr(&self, k: usize) -> String {
        if self.namespaces { format!("198.18.77.{}", k + 1) } else { "127.0.0.1".into() }
    }
    fn port(&self, k: usize) -> u16 {
        // Namespaces have ports of their own; on loopback each daemon needs its own.
        if self.namespaces { 7447 } else { 20_000 + (std::process::id() % 20_000) as u16 + k as u16 }
    }
    pub(crate) fn endpoint(&self, k: usize) -> String {
        format!("tcp/{}:{}", self.addr(k), self.port(k))
    }

    pub(crate) fn make() -> Self {
        let tag = format!("{:05}", std::process::id() % 100_000);
        let mut net = Net { tag, namespaces: true, pumped: None };
        if let Err(e) = net.try_namespaces() {
            net.teardown();
            println!("ip netns refused ({e}): falling back to three daemons on loopback ports");
            net.namespaces = false;
        }
        net
    }

    fn try_namespaces(&mut self) -> Result<(), String> {
        let br = self.bridge();
        sh(&["ip", "link", "add", &br, "type", "bridge"])?;
        sh(&["ip", "link", "set", &br, "up"])?;
        for (k, x) in NAMES.iter().enumerate() {
            let (ns, mut v, mut peer) = (self.ns(x), self.veth(x), format!("{}p", self.veth(x)));
            sh(&["ip", "netns", "add", &ns])?;
            let pumped = if *x == "c" {
                let (inner, outer) = self.taps();
                linkemu::Link::start(&inner, &outer, 0x5eed)
                    .map(|link| {
                        self.pumped = Some(link);
                        (v, peer) = (outer, inner);
                    })
                    .inspect_err(|e| println!("host c gets a veth, not the pumped TAP pair: {e}"))
                    .is_ok()
            } else {
                false
            };
            if !pumped {
                sh(&["ip", "link", "add", &v, "type", "veth", "peer", "name", &peer])?;
            }
            sh(&["ip", "link", "set", &peer, "netns", &ns])?;
            sh(&["ip", "link", "set", &v, "master", &br])?;
            sh(&["ip", "link", "set", &v, "up"])?;
            let addr = format!("{}/24", self.addr(k));
            sh(&["ip", "-n", &ns, "addr", "add", &addr, "dev", &peer])?;
            sh(&["ip", "-n", &ns, "link", "set", &peer, "up"])?;
            sh(&["ip", "-n", &ns, "link", "set", "lo", "up"])?;
        }
        Ok(())
    }

    fn teardown(&self) {
        for x in NAMES {
            let _ = sh(&["ip", "netns", "del", &self.ns(x)]);
            let _ = sh(&["ip", "link", "del", &self.veth(x)]);
        }
        let _ = sh(&["ip", "link", "del", &self.bridge()]);
    }

    /// A command run on host `x` (in its namespace).
    pub(crate) fn command(&self, x: &str, program: &Path) -> Command {
        if self.namespaces {
            let mut c = Command::new("ip");
            c.args(["netns", "exec", &self.ns(x)]).arg(program);
            c
        } else {
            Command::new(program)
        }
    }

    /// Delay `delay` ± `jitter` and loss `loss_pct` % on both ends of host `x`'s link: the
    /// kernel's netem where it has one, else the pump's (host c only). Says which it used.
    fn impair(&self, x: &str, delay_ms: f64, jitter_ms: f64, loss_pct: f64) -> Result<String, String> {
        let (v, peer) = match (&self.pumped, x) {
            (Some(_), "c") => {
                let (inner, outer) = self.taps();
                (outer, inner)
            }
            _ => (self.veth(x), format!("{}p", self.veth(x))),
        };
        let args = [format!("{delay_ms}ms"), format!("{jitter_ms}ms"), format!("{loss_pct}%")];
        let args = ["delay", &args[0], &args[1], "loss", &args[2]];
        let mut a = vec!["tc", "qdisc", "replace", "dev", &v, "root", "netem"];
        a.extend_from_slice(&args);
        let ns = self.ns(x);
        let mut b = vec!["ip", "netns", "exec", &ns, "tc", "qdisc", "replace", "dev", &peer, "root", "netem"];
        b.extend_from_slice(&args);
        let kernel = sh(&a).and_then(|()| sh(&b));
        match (kernel, &self.pumped, x) {
            (Ok(()), _, _) => Ok("the kernel's netem".into()),
            (Err(why), Some(link), "c") => {
                let ms = |v: f64| Duration::from_secs_f64(v / 1e3);
                link.set_both(ms(delay_ms), ms(jitter_ms), loss_pct / 100.0);
                Ok(format!("the user-space pump (the kernel refused netem: {why})"))
            }
            (Err(why), _, _) => Err(why),
        }
    }
}

impl Drop for Net {
    fn drop(&mut self) {
        if self.namespaces {
            self.teardown();
        }
    }
}

/// The three host daemons.
pub(crate) struct Daemons<'a> {
    net: &'a Net,
    kids: Vec<Option<Child>>,
}

impl<'a> Daemons<'a> {
    pub(crate) fn start(net: &'a Net) -> Self {
        let mut d = Daemons { net, kids: vec![None, None, None] };
        for k in 0..3 {
            d.start_one(k);
        }
        d
    }
    fn start_one(&mut self, k: usize) {
        let mut c = self.net.command(NAMES[k], &bin_path("orchestrator"));
        c.args(["host", "--listen", &self.net.endpoint(k), "--name", NAMES[k]]);
        c.stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped());
        let mut child = c.spawn().expect("start a host daemon");
        // It prints one line once it listens.
        let mut err = std::io::BufReader::new(child.stderr.take().expect("piped"));
        let mut line = String::new();
        std::io::BufRead::read_line(&mut err, &mut line).expect("the daemon's first line");
        if !line.contains("listening on") {
            // Not kept anywhere a Drop would find it: end it before failing.
            let _ = child.kill();
            let _ = child.wait();
            panic!("daemon {}: {line}", NAMES[k]);
        }
        std::thread::spawn(move || std::io::copy(&mut err, &mut std::io::sink()));
        self.kids[k] = Some(child);
    }
    pub(crate) fn kill(&mut self, k: usize) {
        if let Some(mut c) = self.kids[k].take() {
            // The daemon runs under `ip netns exec`, which execs it: the pid is the daemon's.
            // SAFETY: kill(2) on a child of this test.
            unsafe { libc::kill(c.id() as i32, libc::SIGKILL) };
            let _ = c.wait();
        }
    }
}

impl Drop for Daemons<'_> {
    fn drop(&mut self) {
        for k in 0..3 {
            if let Some(mut c) = self.kids[k].take() {
                // SAFETY: kill(2) on a child of this test; SIGTERM makes it stop its children.
                unsafe { libc::kill(c.id() as i32, libc::SIGTERM) };
                let _ = c.wait();
            }
        }
    }
}

/// A hosts file: the plant on a, servicers 1, 3, 5 on b and 2, 4, 6 on c.
fn hosts_file(net: &Net, dir: &Path) -> PathBuf {
    let mut text = String::new();
    for (k, (x, place)) in NAMES.iter().zip(["plant = true", "agents = [1, 3, 5]", "agents = [2, 4, 6]"]).enumerate() {
        text.push_str(&format!("[[hosts]]\nname = \"{x}\"\nendpoint = \"{}\"\n{place}\n\n", net.endpoint(k)));
    }
    let path = dir.join("hosts.toml");
    std::fs::write(&path, text).unwrap();
    path
}

/// `orchestrator launch` on host a.
fn launch_on_a(net: &Net, run: &Path, extra: &[&str]) -> Output {
    let mut c = net.command("a", &bin_path("orchestrator"));
    c.current_dir(repo_root())
        .args(["launch", "topologies/fig1.toml", "--no-plots", "--duration", DURATION, "--transport", "zenoh", "--out"])
        .arg(run)
        .args(extra);
    c.output_within(cohort::RUN_LIMIT, "fig1 launched from host a across three hosts")
}

fn launch_here(run: &Path, extra: &[&str]) -> Output {
    cohort::launch_scenario(Path::new("topologies/fig1.toml"), run, &[&["--duration", DURATION], extra].concat())
}

/// Nothing of the run left running on any host, and no daemon (but a killed one) keeps its files.
fn assert_nothing_left(run: &Path, killed: &[&str]) {
    let id = summary(run)["run_id"].as_str().unwrap().to_string();
    let deadline = Instant::now() + Duration::from_secs(10);
    while !processes_mentioning(&id).is_empty() {
        assert!(Instant::now() < deadline, "left running: {:?}", processes_mentioning(&id));
        std::thread::sleep(Duration::from_millis(50));
    }
    // No host's iceoryx2 domain (gateways) left in /dev/shm or the user's base: the namespaces
    // share this machine's file system.
    let shm: Vec<String> = std::fs::read_dir("/dev/shm")
        .unwrap()
        .flatten()
        .map(|e| e.file_name().to_string_lossy().to_string())
        .filter(|n| n.starts_with(&format!("cohort_{id}")))
        .collect();
    // A killed daemon's gateway died with it (its next start sweeps what it left, as the run's
    // lock is released); the test removes it, so runs do not pile up.
    for (k, x) in NAMES.iter().enumerate().filter(|(_, x)| killed.contains(x)) {
        let run_id = u64::from_str_radix(&id, 16).unwrap();
        let domain = cohort_wire::transport::iox::IoxRun::new(run_id).in_domain(Default::default(), k as u16 + 1);
        println!("host {x} was killed: removed {} entries of its domain", domain.remove_all_resources());
        let _ = std::fs::remove_file(cohort_wire::transport::iox::user_base().join(format!("{id}-{:x}.lock", k + 1)));
    }
    let shm: Vec<&String> = shm.iter().filter(|n| !killed_domain(n, &id, killed)).collect();
    assert!(shm.is_empty(), "left in /dev/shm: {shm:?}");
    let roots: Vec<String> = std::fs::read_dir(cohort_wire::transport::iox::user_base())
        .map(|rd| rd.flatten().map(|e| e.file_name().to_string_lossy().to_string()).collect())
        .unwrap_or_default();
    assert!(!roots.iter().any(|n| n.starts_with(&id)), "iceoryx2 roots left: {roots:?}");
    let base = cohort_wire::transport::iox::ensure_user_files_base().unwrap();
    for x in NAMES {
        let left = base.join(x).join(&id);
        assert!(!left.exists() || killed.contains(&x), "host {x} kept {}", left.display());
        if killed.contains(&x) {
            // A killed daemon cannot clean up; the test does, so runs do not pile up.
            let _ = std::fs::remove_dir_all(&left);
        }
    }
}

/// Whether a /dev/shm entry belongs to the domain of a killed host (index k + 1 for NAMES[k]).
fn killed_domain(entry: &str, id: &str, killed: &[&str]) -> bool {
    NAMES.iter().enumerate().any(|(k, x)| killed.contains(x) && entry.starts_with(&format!("cohort_{id}_{:x}_", k + 1)))
}

fn latency_p50_ns(s: &Value, agent: &str) -> f64 {
    // The summary keeps each link's percentiles (the buckets are in timing/).
    let link = &s["link_latency_ns"][format!("{agent} → plant")];
    link["p50"].as_f64().unwrap_or_else(|| panic!("no latency of {agent} → plant: {}", s["link_latency_ns"]))
}

#[test]
fn fig1_across_three_hosts_is_bit_identical_survives_kills_and_host_loss_and_netem() {
    let _g = heavy();
    let t0 = Instant::now();
    let net = Net::make();
    let mut daemons = Daemons::start(&net);
    let dir = scratch_dir("multihost");
    let hosts = hosts_file(&net, &dir);
    let hosts_arg = hosts.to_str().unwrap();

    // 1. Clean run across the hosts == the in-process reference, bit for bit.
    let reference = dir.join("reference");
    let o = launch_here(&reference, &["--reference"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let clean = dir.join("clean");
    let o = launch_on_a(&net, &clean, &["--hosts", hosts_arg]);
    assert!(o.status.success(), "{}", describe_output(&o));
    assert_eq!(telemetry_bits(&clean), telemetry_bits(&reference), "multi-host telemetry differs from --reference");
    assert!(clean.join("logs/agent-2.log").is_file() && clean.join("status/agent-2.json").is_file());
    assert_nothing_left(&clean, &[]);

    // 2. A servicer on c killed by the fault plan: the same degrade as on one host, bit for bit.
    let fault = ["--fault", "kill:agent=2@t=0.5"];
    let here = dir.join("kill-here");
    let o = launch_here(&here, &fault);
    assert!(o.status.success(), "{}", describe_output(&o));
    let there = dir.join("kill-there");
    let o = launch_on_a(&net, &there, &[&["--hosts", hosts_arg][..], &fault].concat());
    assert!(o.status.success(), "{}", describe_output(&o));
    let s = summary(&there);
    let dead: Vec<&Value> =
        s["timeline"].as_array().unwrap().iter().filter(|e| e["event"] == "dead" && e["agent"] == 2).collect();
    assert_eq!(dead.len(), 1, "{}", s["timeline"]);
    assert_eq!(dead[0]["step"], 50);
    assert_eq!(telemetry_bits(&there), telemetry_bits(&here), "the remote kill degraded differently");
    assert_nothing_left(&there, &[]);

    // 3. Host b's daemon killed mid-run: its servicers are declared dead, the run ends in
    // degrade naming the host, nothing is left running anywhere.
    let lost = dir.join("host-lost");
    let mut c = net.command("a", &bin_path("orchestrator"));
    c.current_dir(repo_root())
        .args(["launch", "topologies/fig1.toml", "--no-plots", "--duration", "20", "--transport", "zenoh"])
        .args(["--step-timeout", "3", "--realtime", "--rate", "4", "--hosts", hosts_arg, "--out"])
        .arg(&lost)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped());
    let run = c.spawn().expect("launch");
    // Let it run a little (paced at 4× real time: 20 s of simulation take 5 s), then kill b.
    std::thread::sleep(Duration::from_millis(2500));
    daemons.kill(1);
    let o = cohort::finish_within(run, cohort::RUN_LIMIT, "fig1 in real time across three hosts");
    assert_eq!(o.status.code(), Some(1), "a lost host is an unplanned loss:\n{}", describe_output(&o));
    let s = summary(&lost);
    assert_eq!(s["status"], "degraded", "{}", describe_output(&o));
    let timeline = s["timeline"].as_array().unwrap();
    let host_lost = timeline.iter().find(|e| e["event"] == "host-lost").unwrap_or_else(|| panic!("{}", s["timeline"]));
    assert!(host_lost["detail"].as_str().unwrap().contains("host b"), "{host_lost}");
    for a in [1, 3, 5] {
        assert!(timeline.iter().any(|e| e["event"] == "dead" && e["agent"] == a), "agent {a}: {}", s["timeline"]);
    }
    for a in [2, 4, 6] {
        assert!(!timeline.iter().any(|e| e["event"] == "dead" && e["agent"] == a), "agent {a}: {}", s["timeline"]);
    }
    assert_eq!(s["steps_completed"], 2000, "the run goes on to its end on the live graph");
    assert_nothing_left(&lost, &["b"]);
    daemons.start_one(1);

    // 4. Delay and loss on c's link: still bit-identical, and the latency histograms show the
    // delay. The kernel's netem, or the pump's where the kernel has none (it says which).
    let netem =
        if net.namespaces { net.impair("c", 2.0, 0.5, 1.0) } else { Err("it needs the network namespaces".into()) };
    match &netem {
        Err(why) => println!("delay-and-loss case skipped: {why}"),
        Ok(how) => println!("delay 2 ms ± 0.5 ms and 1 % loss on host c's link by {how}"),
    }
    if netem.is_ok() {
        let slow = dir.join("netem");
        let before = net.pumped.as_ref().map(|l| l.counts.dropped.load(std::sync::atomic::Ordering::Relaxed));
        let o = launch_on_a(&net, &slow, &["--hosts", hosts_arg]);
        assert!(o.status.success(), "{}", describe_output(&o));
        if let (Some(link), Some(before), Ok(how)) = (&net.pumped, before, &netem)
            && how.starts_with("the user-space pump")
        {
            // At 1 % of some thousand frames, none lost would mean the loss was never applied.
            let (carried, dropped) = (
                link.counts.carried.load(std::sync::atomic::Ordering::Relaxed),
                link.counts.dropped.load(std::sync::atomic::Ordering::Relaxed),
            );
            println!("host c's link: {carried} frames carried, {} dropped during the run", dropped - before);
            assert!(dropped > before, "no frame of host c's link was dropped at 1 % loss ({carried} carried)");
        }
        assert_eq!(telemetry_bits(&slow), telemetry_bits(&reference), "netem changed the telemetry");
        let s = summary(&slow);
        for a in ["agent-2", "agent-4", "agent-6"] {
            let p50 = latency_p50_ns(&s, a);
            println!("{a} (host c) → plant: share latency p50 {:.3} ms", p50 / 1e6);
            assert!(p50 >= 1.5e6, "{a} (host c, 2 ms netem): share latency p50 {p50} ns");
        }
        for a in ["agent-1", "agent-3", "agent-5"] {
            let p50 = latency_p50_ns(&s, a);
            println!("{a} (host b) → plant: share latency p50 {:.3} ms", p50 / 1e6);
            assert!(p50 < 1.5e6, "{a} (host b, no netem): share latency p50 {p50} ns");
        }
        assert_nothing_left(&slow, &[]);
    }
    println!("multi-host cases took {:.1} s", t0.elapsed().as_secs_f64());
    drop(daemons);
}

#[test]
fn fig1_over_zenoh_on_one_host_is_bit_identical_to_the_reference() {
    let (_g, dir) = heavy_scratch("zenoh-one-host");
    let reference = dir.join("reference");
    let o = launch_here(&reference, &["--reference"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    // Through this machine's gateway (the default), and with every process a zenoh peer.
    for links in ["gateway", "peers"] {
        let zenoh = dir.join(links);
        let o = launch_here(&zenoh, &["--transport", "zenoh", "--zenoh-links", links]);
        assert!(o.status.success(), "{links}: {}", describe_output(&o));
        assert_eq!(telemetry_bits(&zenoh), telemetry_bits(&reference), "{links}");
        assert_eq!(zenoh.join("logs/gateway-0.log").is_file(), links == "gateway", "{links}");
        let id = summary(&zenoh)["run_id"].as_str().unwrap().to_string();
        assert!(processes_mentioning(&id).is_empty(), "{links}: {:?}", processes_mentioning(&id));
    }
}

/// Issue 31: a 60-agent consensus ring across the three hosts through their gateways (plant and
/// agents 1–20 on a, 21–40 on b, 41–60 on c; each ring boundary crosses hosts), sealed, is
/// bit-identical to `--reference`, every gateway carried batches both ways, no message was
/// rejected, and nothing is left anywhere.
#[test]
fn a_sixty_agent_ring_across_three_hosts_through_gateways_is_bit_identical() {
    let _g = heavy();
    let net = Net::make();
    let daemons = Daemons::start(&net);
    let dir = scratch_dir("multihost-ring60");
    let ring = dir.join("ring60.toml");
    let o = Command::new(bin_path("orchestrator"))
        .args(["generate", "ring", "--agents", "60", "--steps", "200", "--out"])
        .arg(&ring)
        .output()
        .unwrap();
    assert!(o.status.success(), "{}", describe_output(&o));
    let mut text = String::new();
    for (k, (x, place)) in NAMES.iter().zip(["plant = true\nagents = [", "agents = [", "agents = ["]).enumerate() {
        let ids: Vec<String> = (1..=20).map(|i| (20 * k + i).to_string()).collect();
        text.push_str(&format!(
            "[[hosts]]\nname = \"{x}\"\nendpoint = \"{}\"\n{place}{}]\n\n",
            net.endpoint(k),
            ids.join(", ")
        ));
    }
    let hosts = dir.join("hosts.toml");
    std::fs::write(&hosts, text).unwrap();
    let (run, reference) = (dir.join("run"), dir.join("reference"));
    // Sealed (`run.authenticate`): every gateway gets the run's key from its daemon, and every
    // message still carries its sender's tag across the gateways.
    let o = cohort::launch_scenario(&ring, &reference, &["--reference", "--authenticate"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let mut c = net.command("a", &bin_path("orchestrator"));
    c.current_dir(repo_root())
        .args(["launch", "--no-plots", "--transport", "zenoh", "--authenticate"])
        .args(["--hosts", hosts.to_str().unwrap(), "--out"])
        .arg(&run)
        .arg(&ring);
    let o = c.output_within(cohort::RUN_LIMIT, "a 60-agent ring across three hosts");
    assert!(o.status.success(), "{}", describe_output(&o));
    let s = summary(&run);
    assert_eq!(s["status"], "ok");
    let rejected: u64 = s["messages_rejected"].as_object().unwrap().values().map(|v| v.as_u64().unwrap()).sum();
    assert_eq!(rejected, 0, "{}", s["messages_rejected"]);
    assert_eq!(s["messages_unaccounted"].as_array().map(Vec::len), Some(0), "{}", s["messages_unaccounted"]);
    assert_eq!(telemetry_bits(&run), telemetry_bits(&reference), "the ring through gateways differs from --reference");
    // Adaptive waiting: the plant's first trial ends at step 80, and its choice reached the
    // agents of the other hosts with the gateways' batches; they waited as it chose.
    for i in 21..=60 {
        let status = std::fs::read_to_string(run.join(format!("status/agent-{i}.json"))).unwrap();
        let st: Value = serde_json::from_str(&status).unwrap();
        let advised = st["wait"]["advised"].as_u64().unwrap_or_else(|| panic!("agent-{i}: {}", st["wait"]));
        assert!(advised > 0, "agent-{i} (host b or c) never waited as the plant's trial chose: {}", st["wait"]);
    }
    for k in 1..=3 {
        let log = std::fs::read_to_string(run.join(format!("logs/gateway-{k}.log"))).unwrap_or_default();
        let done = log.lines().find(|l| l.contains("done: out:")).unwrap_or_else(|| panic!("gateway-{k}: {log}"));
        println!("gateway-{k} {done}");
        let count = |what: &str| -> u64 {
            let after = done.split(what).nth(1).unwrap_or_else(|| panic!("{done}"));
            after.split_whitespace().next().unwrap().parse().unwrap()
        };
        assert!(count("out: ") > 0 && count("in: ") > 0, "gateway-{k} carried nothing: {done}");
        // Hosts b and c send each step's shares (21 to two hosts) as one batch a host (held for
        // the step's last one): 6.7–7.3 messages a batch measured, 1.4–2.4 when each went as it
        // came.
        let (messages, batches) = (count("out: "), count("messages in "));
        if k > 1 {
            assert!(
                messages >= 4 * batches,
                "gateway-{k} sent a batch per {:.1} messages: {done}",
                messages as f64 / batches as f64
            );
        }
        assert!(done.ends_with("0 batches refused"), "{done}");
    }
    assert_nothing_left(&run, &[]);
    drop(daemons);
}

/// A launch refused before anything starts: exit 2, its message, no process of the run.
fn assert_refused(dir: &Path, hosts: &str, expect: &str) {
    let path = dir.join("hosts.toml");
    std::fs::write(&path, hosts).unwrap();
    let run = dir.join("run");
    let o = launch_here(&run, &["--transport", "zenoh", "--hosts", path.to_str().unwrap()]);
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    assert!(err.contains(expect), "expected {expect:?}:\n{}", describe_output(&o));
    assert!(!run.join("scenario.toml").exists(), "a refused launch prepared a run directory");
    assert!(processes_mentioning(run.to_str().unwrap()).is_empty());
}

const PLACEMENT: &str = "plant = true\nagents = [1, 2, 3, 4, 5, 6]\n";

#[test]
fn an_unreachable_daemon_or_one_of_another_build_is_refused_before_anything_starts() {
    use zenoh::Wait;
    let dir = scratch_dir("multihost-refused");
    // Nothing listens on this port (bound, then closed).
    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let unreachable = format!("[[hosts]]\nname = \"a\"\nendpoint = \"tcp/127.0.0.1:{port}\"\n{PLACEMENT}");
    assert_refused(&dir, &unreachable, "unreachable");

    // A "daemon" of another build: a zenoh queryable answering `info` with another build id.
    let loopback = std::net::Ipv4Addr::LOCALHOST.into();
    let (session, at) = cohort_wire::transport::zenoh::open_on_free_ports(&[loopback], &[]).unwrap();
    let at = at[0].clone();
    let _q = session
        .declare_queryable("cohort/host/a/info")
        .callback(|q| {
            let body = br#"{"name":"a","build_id":"some-other-build","pid":1}"#.to_vec();
            let _ = q.reply(q.key_expr().clone(), body).wait();
        })
        .wait()
        .unwrap();
    let other = format!("[[hosts]]\nname = \"a\"\nendpoint = \"{at}\"\n{PLACEMENT}");
    assert_refused(&dir, &other, "some-other-build");
    // The right build but another name: no daemon of that name answers.
    let misnamed = format!("[[hosts]]\nname = \"z\"\nendpoint = \"{at}\"\n{PLACEMENT}");
    assert_refused(&dir, &misnamed, "no daemon named \"z\"");
}

#[test]
fn fig1_across_three_loopback_daemons_is_bit_identical_to_the_reference() {
    let _g = heavy();
    // The fallback of machines without `ip netns`, tested on every machine: three daemons on
    // loopback ports of this one.
    let net = Net { tag: String::new(), namespaces: false, pumped: None };
    let daemons = Daemons::start(&net);
    let dir = scratch_dir("multihost-loopback");
    let hosts = hosts_file(&net, &dir);
    let (run, reference) = (dir.join("run"), dir.join("reference"));
    let o = launch_here(&run, &["--transport", "zenoh", "--hosts", hosts.to_str().unwrap()]);
    assert!(o.status.success(), "{}", describe_output(&o));
    let o = launch_here(&reference, &["--reference"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    assert_eq!(telemetry_bits(&run), telemetry_bits(&reference), "loopback multi-host telemetry differs");
    assert_nothing_left(&run, &[]);
    drop(daemons);
}

/// Issue 31: a lost gateway is its host lost. Host b's gateway killed mid-run (its daemon alive):
/// b's servicers are declared dead, the timeline's host-lost event names b and its gateway, the
/// run goes on to its end on the live graph, and b's daemon still cleans up (nothing left).
/// Three loopback daemons, so it runs on every machine.
#[test]
fn a_killed_gateway_is_its_host_lost() {
    let _g = heavy();
    let net = Net { tag: String::new(), namespaces: false, pumped: None };
    let daemons = Daemons::start(&net);
    let dir = scratch_dir("multihost-gateway-lost");
    let hosts = hosts_file(&net, &dir);
    let lost = dir.join("gateway-lost");
    let run = Command::new(bin_path("orchestrator"))
        .current_dir(repo_root())
        .args(["launch", "topologies/fig1.toml", "--no-plots", "--duration", "20", "--transport", "zenoh"])
        .args(["--step-timeout", "3", "--realtime", "--rate", "4", "--hosts", hosts.to_str().unwrap(), "--out"])
        .arg(&lost)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .expect("launch");
    // Host b is hosts[1]: its gateway is `gateway --host-index 2`, started with the run.
    let deadline = Instant::now() + Duration::from_secs(60);
    let gateway = loop {
        let found = processes_mentioning("gateway --host-index 2");
        if let Some((pid, _)) = found.first() {
            break *pid;
        }
        assert!(Instant::now() < deadline, "host b's gateway never started");
        std::thread::sleep(Duration::from_millis(50));
    };
    std::thread::sleep(Duration::from_millis(2500));
    // SAFETY: kill(2) on the gateway process this run started (found by its command line).
    unsafe { libc::kill(gateway as i32, libc::SIGKILL) };
    let o = cohort::finish_within(run, cohort::RUN_LIMIT, "fig1 in real time, host b's gateway killed");
    assert_eq!(o.status.code(), Some(1), "a lost host is an unplanned loss:\n{}", describe_output(&o));
    let s = summary(&lost);
    assert_eq!(s["status"], "degraded", "{}", describe_output(&o));
    let timeline = s["timeline"].as_array().unwrap();
    let host_lost = timeline.iter().find(|e| e["event"] == "host-lost").unwrap_or_else(|| panic!("{}", s["timeline"]));
    let detail = host_lost["detail"].as_str().unwrap();
    assert!(detail.contains("host b") && detail.contains("its gateway ended"), "{host_lost}");
    for a in [1, 3, 5] {
        assert!(timeline.iter().any(|e| e["event"] == "dead" && e["agent"] == a), "agent {a}: {}", s["timeline"]);
    }
    for a in [2, 4, 6] {
        assert!(!timeline.iter().any(|e| e["event"] == "dead" && e["agent"] == a), "agent {a}: {}", s["timeline"]);
    }
    assert_eq!(s["steps_completed"], 2000, "the run goes on to its end on the live graph");
    // b's daemon is alive: it ended b's processes and removed b's domain itself.
    assert_nothing_left(&lost, &[]);
    drop(daemons);
}

/// A 20-agent consensus ring over zenoh on one host, every process a zenoh peer, as text: many
/// sessions connecting at once is what deadlocked zenoh's `lowlatency` transport at start-up.
fn ring20_over_zenoh() -> String {
    let n = 20u32;
    let mut t = String::from(
        "[scenario]\nname = \"ring20-zenoh\"\nseed = 7\ndt_s = 0.01\nduration_s = 0.5\n\n[run]\n\
         transport = \"zenoh\"\nzenoh_links = \"peers\"\nstartup_timeout_s = 90.0\nstep_timeout_s = 30.0\n\n[plant]\n\
         kind = \"double-integrator\"\nposition_noise_std_m = 0.05\n\n[algorithm]\n\
         kind = \"consensus-formation\"\nformation_radius_m = 40.0\nkp_per_s2 = 0.5\nkd_per_s = 1.5\n\
         observer_l1_per_s = 6.0\nobserver_l2_per_s2 = 9.0\n",
    );
    for i in 1..=n {
        let a = std::f64::consts::TAU * f64::from(i) / f64::from(n);
        t.push_str(&format!(
            "\n[[agents]]\nid = {i}\nneighbours = [{}, {}]\nr0_m = [{:?}, {:?}, 0.0]\nv0_mps = [0.0, 0.0, 0.0]\n",
            (i + n - 2) % n + 1,
            i % n + 1,
            52.0 * a.cos(),
            28.0 * a.sin()
        ));
    }
    t
}

#[test]
fn twenty_agents_over_zenoh_start_every_time() {
    let (_g, dir) = heavy_scratch("zenoh-ring20");
    let file = dir.join("ring20.toml");
    std::fs::write(&file, ring20_over_zenoh()).unwrap();
    // With the lowlatency transport about half of these launches hung at start-up (and the
    // orchestrator with them): `timeout` turns a hang into a failure instead of a stuck suite.
    for k in 0..3 {
        let run = dir.join(format!("run-{k}"));
        let o = Command::new("timeout")
            .args(["-k", "10", "300"])
            .arg(bin_path("orchestrator"))
            .current_dir(repo_root())
            .args(["launch", "--no-plots", "--out"])
            .arg(&run)
            .arg(&file)
            .output()
            .expect("running the orchestrator");
        assert!(o.status.success(), "launch {k}: {}", describe_output(&o));
        assert_eq!(summary(&run)["status"], "ok", "launch {k}");
        let id = summary(&run)["run_id"].as_str().unwrap().to_string();
        assert!(processes_mentioning(&id).is_empty(), "{:?}", processes_mentioning(&id));
    }
}

/// Issue 36, item 9.4: a host daemon that stops (SIGTERM) leaves no empty per-host directory
/// (`<tmp>/cohort-<uid>-hosts/<name>/`, made at its start) behind, nor an empty base. Under its
/// own temp dir, so other daemons' directories are not in the way.
#[test]
fn a_stopped_host_daemon_leaves_no_empty_per_host_directory() {
    let dir = scratch_dir("multihost-hostdir");
    let port = 40_000 + (std::process::id() % 20_000) as u16;
    // Its own iceoryx2 base, short enough for a run root, so no concurrent test shares it.
    let run_base = PathBuf::from(format!("/tmp/cohort-tidy-{}", std::process::id()));
    let mut c = Command::new(bin_path("orchestrator"))
        .args(["host", "--listen", &format!("tcp/127.0.0.1:{port}"), "--name", "tidy"])
        .env("TMPDIR", &dir)
        .env(cohort_wire::transport::iox::BASE_ENV, &run_base)
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start a host daemon");
    let mut err = std::io::BufReader::new(c.stderr.take().expect("piped"));
    let mut line = String::new();
    std::io::BufRead::read_line(&mut err, &mut line).expect("the daemon's first line");
    assert!(line.contains("listening on"), "daemon: {line}");
    let base = std::fs::read_dir(&dir)
        .unwrap()
        .flatten()
        .map(|e| e.path())
        .find(|p| p.file_name().is_some_and(|n| n.to_string_lossy().ends_with("-hosts")))
        .unwrap_or_else(|| panic!("no per-user hosts base under {}", dir.display()));
    assert!(base.join("tidy").is_dir(), "the daemon's directory while it runs");
    // SAFETY: kill(2) on a child of this test.
    unsafe { libc::kill(c.id() as i32, libc::SIGTERM) };
    let status = c.wait().unwrap();
    assert!(status.code().is_some(), "the daemon ends by itself on SIGTERM, not by the signal: {status:?}");
    assert!(!base.join("tidy").exists(), "{} left behind", base.join("tidy").display());
    assert!(!base.exists(), "{} left behind, empty", base.display());
    // The daemon sweeps stale runs as it starts and ends; a sweep never makes the base.
    assert!(!run_base.exists(), "{} made by a sweep and left", run_base.display());
}

/// A zenoh run on one host (its gateway and the orchestrator sweep stale runs after the
/// gateway ends) leaves no empty base directory: each such run left `/dev/shm/cohort-<uid>`.
#[test]
fn a_zenoh_run_on_one_host_leaves_no_base_directory() {
    let (_g, dir) = heavy_scratch("zenoh-no-base");
    let run_base = PathBuf::from(format!("/tmp/cohort-zb-{}", std::process::id()));
    let o = Command::new(bin_path("orchestrator"))
        .args(["launch", "topologies/fig1.toml", "--duration", DURATION, "--transport", "zenoh", "--no-plots", "-q"])
        .arg("--out")
        .arg(dir.join("run"))
        .env(cohort_wire::transport::iox::BASE_ENV, &run_base)
        .output()
        .expect("launch");
    assert!(o.status.success(), "{}", describe_output(&o));
    assert!(dir.join("run/logs/gateway-0.log").is_file(), "the run went through its gateway");
    assert!(!run_base.exists(), "{} left behind", run_base.display());
}

/// `launch --live` of a run whose every process is on a host daemon: the view asks the daemons
/// for their processes' rows while the run goes on (their journals never reach this machine
/// before the end), and every row a client gets equals the run's Parquet row bit for bit, once
/// per step, in step order.
#[test]
fn a_live_view_shows_the_rows_of_processes_on_other_hosts() {
    let _g = heavy();
    let net = Net { tag: String::new(), namespaces: false, pumped: None };
    let daemons = Daemons::start(&net);
    let dir = scratch_dir("multihost-live");
    let hosts = hosts_file(&net, &dir);
    let run = dir.join("run");
    let port = crate::live::free_port();
    let child = cohort::orchestrator_command()
        .args(["launch", "topologies/fig1.toml", "--no-plots", "--duration", "6", "--realtime"])
        .args(["--transport", "zenoh", "--hosts", hosts.to_str().unwrap(), "--live"])
        .arg(format!("127.0.0.1:{port}"))
        .arg("--out")
        .arg(&run)
        .stdout(Stdio::piped())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let client = std::thread::spawn(move || crate::live::client(port, Duration::from_secs(120)));
    let out = cohort::finish_within(child, cohort::RUN_LIMIT, "orchestrator launch --live across hosts");
    assert!(out.status.success(), "{}", describe_output(&out));
    let got = client.join().unwrap();
    for (topic, stem) in
        [("/telemetry/plant", "plant"), ("/telemetry/agent-2", "agent-2"), ("/telemetry/agent-3", "agent-3")]
    {
        let table = cohort::telemetry_table(&run, stem);
        let msgs = got.get(topic).map(Vec::as_slice).unwrap_or_default();
        // 6 s of sim time at 20 rows per sim second, in real time: ≈ 120; a loaded machine's
        // daemons may answer late, so ask for a third.
        assert!(msgs.len() >= 40, "{topic}: {} rows live; got topics {:?}", msgs.len(), got.keys());
        let times: Vec<u64> = msgs.iter().map(|m| m.0).collect();
        assert!(times.windows(2).all(|w| w[0] < w[1]), "{topic}: log times not increasing: {times:?}");
        for (_, payload) in msgs {
            let row = crate::live::json_numbers(payload);
            let r = table.k.iter().position(|&x| x == row["k"] as u64).expect("a step of the run");
            for c in &table.columns {
                assert_eq!(row[&c.name].to_bits(), c.values[r].to_bits(), "{topic} step {}: {}", row["k"], c.name);
            }
        }
    }
    assert!(got.get("/scene").is_some_and(|m| m.len() >= 40), "too few scenes: {:?}", got.get("/scene").map(Vec::len));
    assert_nothing_left(&run, &[]);
    drop(daemons);
}
