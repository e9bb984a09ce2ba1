//! A four-machine lab on this one for `orchestrator bench`: network namespaces a, b, c and d joined
//! to a bridge (198.18.77.0/24, the benchmarking range; the bridge itself is 198.18.77.254, so
//! this process reaches them), a host daemon in each, and a delay each namespace adds to what it
//! sends. Needs root (CAP_NET_ADMIN); everything is removed when the lab is dropped.
//!
//! Each namespace's link to the bridge is one of ([`Links`]):
//! - a veth pair, delayed by the kernel's `tc netem` on the namespace's end, where the kernel
//!   has netem ([`netem_probe`]);
//! - otherwise a TAP pair with the user-space pump of [`crate::linkemu`] between its ends, which
//!   delays the frames the namespace sends. The pump is on every link, also when no delay is
//!   set, so that a lab's rows with and without delay differ by the delay alone; its own latency
//!   (against a veth) is what a caller measures apart (the bench does, with a second, veth lab).
//!
//! Either way a hop between two namespaces is delayed once per direction, so a delay d adds 2 d
//! to a round trip between namespaces, and d to one between a namespace and this process.

use std::fmt::Write as _;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use crate::linkemu;

/// The lab's hosts: the plant goes on `a`, agents on the others (the four namespaces; fig1
/// uses b and c for its servicers, a ring spreads over all three).
pub const NAMES: [&str; 4] = ["a", "b", "c", "d"];
const BRIDGE_ADDR: &str = "198.18.77.254";
/// How many campaign cases each daemon of the lab runs at once (`orchestrator host --workers`).
pub const CASE_WORKERS: u32 = 2;

/// Why the lab (or a change to it) could not be made.
#[derive(Debug, thiserror::Error)]
pub enum LabError {
    /// A command (`ip`, `tc`) could not run or failed; `reason` is its error or its stderr.
    #[error("{command}: {reason}")]
    Command { command: String, reason: String },
    #[error(transparent)]
    Tap(#[from] linkemu::TapError),
    #[error("cannot start the daemon of host {host}: {source}")]
    Daemon { host: &'static str, source: std::io::Error },
    #[error("the lab's daemons did not come up: {0}")]
    NotUp(String),
    #[error("{}: {source}", path.display())]
    File { path: PathBuf, source: std::io::Error },
}

fn sh(args: &[&str]) -> Result<(), LabError> {
    let failed = |reason: String| LabError::Command { command: args.join(" "), reason };
    let o = Command::new(args[0]).args(&args[1..]).output().map_err(|e| failed(e.to_string()))?;
    if o.status.success() { Ok(()) } else { Err(failed(String::from_utf8_lossy(&o.stderr).trim().to_string())) }
}

/// What the lab's links are, and so what delays them.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Links {
    /// veth pairs; delay by the kernel's netem.
    Veth,
    /// TAP pairs with the user-space pump between their ends; delay in the pump.
    Pumped,
}

impl Links {
    /// As the bench's rows name it.
    pub fn describe(self) -> &'static str {
        match self {
            Links::Veth => "veth, kernel netem",
            Links::Pumped => "TAP pair, user-space pump",
        }
    }
}

/// Whether the kernel will put a netem qdisc on a device: tried on the loopback of a scratch
/// namespace (so no real device is touched). `Err` says why not (e.g. no `sch_netem`).
pub fn netem_probe() -> Result<(), LabError> {
    let ns = format!("cblq{:05}", std::process::id() % 100_000);
    sh(&["ip", "netns", "add", &ns])?;
    let r = sh(&["ip", "netns", "exec", &ns, "tc", "qdisc", "add", "dev", "lo", "root", "netem", "delay", "1ms"]);
    let _ = sh(&["ip", "netns", "del", &ns]);
    r
}

pub struct Lab {
    tag: String,
    links: Links,
    daemons: Vec<Child>,
    /// The pumps of a `Pumped` lab, in the order of [`NAMES`].
    pumps: Vec<linkemu::Link>,
}

impl Lab {
    fn ns(&self, x: &str) -> String {
        format!("cbl{}{x}", self.tag)
    }
    fn bridge(&self) -> String {
        format!("cblb{}", self.tag)
    }
    /// Host `x`'s link: (its end on the bridge, its end in the namespace).
    fn ends(&self, x: &str) -> (String, String) {
        match self.links {
            Links::Veth => (format!("cblv{}{x}", self.tag), format!("cblv{}{x}p", self.tag)),
            Links::Pumped => (format!("cblt{}{x}o", self.tag), format!("cblt{}{x}", self.tag)),
        }
    }
    pub fn addr(k: usize) -> String {
        format!("198.18.77.{}", k + 1)
    }
    pub fn endpoint(k: usize) -> String {
        format!("tcp/{}:7447", Self::addr(k))
    }

    /// The lab with veth links where the kernel has netem, else with pumped links.
    pub fn start() -> Result<Self, LabError> {
        Self::start_with(if netem_probe().is_ok() { Links::Veth } else { Links::Pumped })
    }

    /// Make the namespaces with `links` and start a daemon in each (from this executable).
    pub fn start_with(links: Links) -> Result<Self, LabError> {
        let tag = format!("{:05}", std::process::id() % 100_000);
        // Dropped on any error below: the daemons started so far stop, everything made goes.
        let mut lab = Lab { tag, links, daemons: Vec::new(), pumps: Vec::new() };
        lab.build()?;
        let me = std::env::current_exe().map_err(|source| LabError::File { path: "/proc/self/exe".into(), source })?;
        for (k, x) in NAMES.iter().enumerate() {
            let child = lab
                .command(x, &me)
                .args(["host", "--listen", &Self::endpoint(k), "--name", x, "--workers", &CASE_WORKERS.to_string()])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .map_err(|source| LabError::Daemon { host: x, source })?;
            lab.daemons.push(child);
        }
        // Wait until every daemon answers.
        let hosts: Vec<cohort_scenario::HostSpec> = NAMES
            .iter()
            .enumerate()
            .map(|(k, x)| cohort_scenario::HostSpec { name: (*x).into(), endpoint: Self::endpoint(k) })
            .collect();
        let until = std::time::Instant::now() + Duration::from_secs(20);
        while let Err(e) = crate::remote::preflight(&hosts) {
            if std::time::Instant::now() > until {
                return Err(LabError::NotUp(e.to_string()));
            }
            std::thread::sleep(Duration::from_millis(200));
        }
        Ok(lab)
    }

    pub fn links(&self) -> Links {
        self.links
    }

    fn build(&mut self) -> Result<(), LabError> {
        let br = self.bridge();
        sh(&["ip", "link", "add", &br, "type", "bridge"])?;
        sh(&["ip", "addr", "add", &format!("{BRIDGE_ADDR}/24"), "dev", &br])?;
        sh(&["ip", "link", "set", &br, "up"])?;
        for (k, x) in NAMES.iter().enumerate() {
            let (ns, (outer, inner)) = (self.ns(x), self.ends(x));
            sh(&["ip", "netns", "add", &ns])?;
            match self.links {
                Links::Veth => sh(&["ip", "link", "add", &outer, "type", "veth", "peer", "name", &inner])?,
                Links::Pumped => self.pumps.push(linkemu::Link::start(&inner, &outer, 0x5eed + k as u64)?),
            }
            sh(&["ip", "link", "set", &inner, "netns", &ns])?;
            sh(&["ip", "link", "set", &outer, "master", &br])?;
            sh(&["ip", "link", "set", &outer, "up"])?;
            sh(&["ip", "-n", &ns, "addr", "add", &format!("{}/24", Self::addr(k)), "dev", &inner])?;
            sh(&["ip", "-n", &ns, "link", "set", &inner, "up"])?;
            sh(&["ip", "-n", &ns, "link", "set", "lo", "up"])?;
        }
        Ok(())
    }

    fn teardown(&self) {
        for x in NAMES {
            let _ = sh(&["ip", "netns", "del", &self.ns(x)]);
            // A veth's other end (a TAP's goes with the pump, when it is dropped).
            let _ = sh(&["ip", "link", "del", &self.ends(x).0]);
        }
        let _ = sh(&["ip", "link", "del", &self.bridge()]);
    }

    /// `program` run inside host `x`'s namespace.
    pub fn command(&self, x: &str, program: &std::path::Path) -> Command {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", &self.ns(x)]).arg(program);
        c
    }

    /// Every namespace delays what it sends by `delay` (each direction of a namespace-to-namespace
    /// hop is delayed once); zero removes the delay. netem or the pump, as the lab's links are.
    pub fn set_delay(&self, delay: Duration) -> Result<(), LabError> {
        match self.links {
            Links::Pumped => {
                for p in &self.pumps {
                    p.from_inner.set(delay, Duration::ZERO, 0.0);
                }
                Ok(())
            }
            Links::Veth => {
                for x in NAMES {
                    let (ns, (_, inner)) = (self.ns(x), self.ends(x));
                    let tc = ["ip", "netns", "exec", &ns, "tc", "qdisc"];
                    if delay.is_zero() {
                        let _ = sh(&[&tc[..], &["del", "dev", &inner, "root"]].concat());
                    } else {
                        let us = format!("{}us", delay.as_micros());
                        sh(&[&tc[..], &["replace", "dev", &inner, "root", "netem", "delay", &us]].concat())?;
                    }
                }
                Ok(())
            }
        }
    }

    /// A hosts file of the lab's first `hosts` daemons (at most all), placing nothing (for
    /// `campaign --hosts`).
    pub fn bare_hosts_file(dir: &std::path::Path, hosts: usize) -> Result<PathBuf, LabError> {
        let text: String = NAMES
            .iter()
            .take(hosts)
            .enumerate()
            .map(|(k, x)| format!("[[hosts]]\nname = \"{x}\"\nendpoint = \"{}\"\n\n", Self::endpoint(k)))
            .collect();
        write_hosts(dir, "hosts-campaign.toml", &text)
    }

    /// A hosts file: the plant on a, agents 1..=n dealt in turn to the next `agent_hosts` hosts
    /// (b, c, …; at least one, at most the lab's three), so agent 1 is on b, agent 2 on c.
    pub fn hosts_file(dir: &std::path::Path, n: u32, agent_hosts: usize) -> Result<PathBuf, LabError> {
        write_hosts(dir, &format!("hosts-{n}-{agent_hosts}.toml"), &placement(n, agent_hosts))
    }
}

/// The hosts file's text of [`Lab::hosts_file`].
fn placement(n: u32, agent_hosts: usize) -> String {
    let m = agent_hosts.clamp(1, NAMES.len() - 1);
    let mut text = format!("[[hosts]]\nname = \"a\"\nendpoint = \"{}\"\nplant = true\n", Lab::endpoint(0));
    for (k, name) in NAMES.iter().enumerate().skip(1).take(m) {
        let ids: Vec<String> = (k as u32..=n).step_by(m).map(|i| i.to_string()).collect();
        let _ = write!(
            text,
            "\n[[hosts]]\nname = \"{name}\"\nendpoint = \"{}\"\nagents = [{}]\n",
            Lab::endpoint(k),
            ids.join(", ")
        );
    }
    text
}

fn write_hosts(dir: &std::path::Path, name: &str, text: &str) -> Result<PathBuf, LabError> {
    std::fs::create_dir_all(dir).map_err(|source| LabError::File { path: dir.into(), source })?;
    let path = dir.join(name);
    std::fs::write(&path, text).map_err(|source| LabError::File { path: path.clone(), source })?;
    Ok(path)
}

impl Drop for Lab {
    fn drop(&mut self) {
        for d in &mut self.daemons {
            // SAFETY: kill(2) on a daemon this lab started; SIGTERM makes it stop its children.
            unsafe { libc::kill(d.id() as libc::pid_t, libc::SIGTERM) };
            let _ = d.wait();
        }
        self.teardown();
        // The pumps (and their TAP devices) go after the namespaces, as the fields drop.
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Host name → its agents, from the hosts file `Lab::hosts_file` wrote and the scenario
    /// crate read back.
    fn placed(n: u32, agent_hosts: usize) -> Vec<(String, bool, Vec<u32>)> {
        let dir = std::env::temp_dir().join(format!("cohort-netlab-test-{}-{n}-{agent_hosts}", std::process::id()));
        let path = Lab::hosts_file(&dir, n, agent_hosts).unwrap();
        let h = cohort_scenario::hosts::HostsFile::load(&path).unwrap();
        let _ = std::fs::remove_dir_all(&dir);
        h.hosts.into_iter().map(|e| (e.name, e.plant, e.agents)).collect()
    }

    #[test]
    fn agents_are_dealt_in_turn_to_the_agent_hosts() {
        let three = placed(7, 3);
        assert_eq!(
            three,
            vec![
                ("a".into(), true, vec![]),
                ("b".into(), false, vec![1, 4, 7]),
                ("c".into(), false, vec![2, 5]),
                ("d".into(), false, vec![3, 6]),
            ]
        );
        let two = placed(6, 2);
        assert_eq!(two[1..], [("b".into(), false, vec![1, 3, 5]), ("c".into(), false, vec![2, 4, 6])]);
        // More agent hosts than the lab has are the lab's three.
        assert_eq!(placed(3, 9).len(), NAMES.len());
    }
}
