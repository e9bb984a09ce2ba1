//! A three-machine lab on this one for `orchestrator bench`: network namespaces a, b and c joined
//! by veth pairs to a bridge (198.18.77.0/24, the benchmarking range; the bridge itself is
//! 198.18.77.254, so this process reaches them), a host daemon in each, and `tc netem` on their
//! links. Needs root (CAP_NET_ADMIN); everything is removed when the lab is dropped.

use std::path::PathBuf;
use std::process::{Child, Command, Stdio};

pub const NAMES: [&str; 3] = ["a", "b", "c"];
const BRIDGE_ADDR: &str = "198.18.77.254";

fn sh(args: &[&str]) -> Result<(), String> {
    let o = Command::new(args[0]).args(&args[1..]).output().map_err(|e| format!("{}: {e}", args.join(" ")))?;
    if o.status.success() {
        Ok(())
    } else {
        Err(format!("{}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr).trim()))
    }
}

pub struct Lab {
    tag: String,
    daemons: Vec<Child>,
}

impl Lab {
    fn ns(&self, x: &str) -> String {
        format!("cbl{}{x}", self.tag)
    }
    fn bridge(&self) -> String {
        format!("cblb{}", self.tag)
    }
    fn veth(&self, x: &str) -> String {
        format!("cblv{}{x}", self.tag)
    }
    pub fn addr(k: usize) -> String {
        format!("198.18.77.{}", k + 1)
    }
    pub fn endpoint(k: usize) -> String {
        format!("tcp/{}:7447", Self::addr(k))
    }

    /// Make the namespaces and start a daemon in each (from this executable).
    pub fn start() -> Result<Self, String> {
        let tag = format!("{:05}", std::process::id() % 100_000);
        let mut lab = Lab { tag, daemons: Vec::new() };
        lab.build().inspect_err(|_| lab.teardown())?;
        let me = std::env::current_exe().map_err(|e| e.to_string())?;
        for (k, x) in NAMES.iter().enumerate() {
            let child = lab
                .command(x, &me)
                .args(["host", "--listen", &Self::endpoint(k), "--name", x])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::null())
                .spawn()
                .map_err(|e| format!("cannot start the daemon of host {x}: {e}"))?;
            lab.daemons.push(child);
        }
        // Wait until every daemon answers.
        let hosts: Vec<cohort_scenario::HostSpec> = NAMES
            .iter()
            .enumerate()
            .map(|(k, x)| cohort_scenario::HostSpec { name: (*x).into(), endpoint: Self::endpoint(k) })
            .collect();
        let until = std::time::Instant::now() + std::time::Duration::from_secs(20);
        while let Err(e) = crate::remote::preflight(&hosts) {
            if std::time::Instant::now() > until {
                return Err(format!("the lab's daemons did not come up: {e}"));
            }
            std::thread::sleep(std::time::Duration::from_millis(200));
        }
        Ok(lab)
    }

    fn build(&self) -> Result<(), String> {
        let br = self.bridge();
        sh(&["ip", "link", "add", &br, "type", "bridge"])?;
        sh(&["ip", "addr", "add", &format!("{BRIDGE_ADDR}/24"), "dev", &br])?;
        sh(&["ip", "link", "set", &br, "up"])?;
        for (k, x) in NAMES.iter().enumerate() {
            let (ns, v, peer) = (self.ns(x), self.veth(x), format!("{}p", self.veth(x)));
            sh(&["ip", "netns", "add", &ns])?;
            sh(&["ip", "link", "add", &v, "type", "veth", "peer", "name", &peer])?;
            sh(&["ip", "link", "set", &peer, "netns", &ns])?;
            sh(&["ip", "link", "set", &v, "master", &br])?;
            sh(&["ip", "link", "set", &v, "up"])?;
            sh(&["ip", "-n", &ns, "addr", "add", &format!("{}/24", Self::addr(k)), "dev", &peer])?;
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

    /// `program` run inside host `x`'s namespace.
    pub fn command(&self, x: &str, program: &std::path::Path) -> Command {
        let mut c = Command::new("ip");
        c.args(["netns", "exec", &self.ns(x)]).arg(program);
        c
    }

    /// netem on every namespace's own end of its link (each direction of a namespace-to-namespace
    /// hop is delayed once); `None` removes it.
    pub fn netem(&self, args: Option<&[&str]>) -> Result<(), String> {
        for x in NAMES {
            let ns = self.ns(x);
            let peer = format!("{}p", self.veth(x));
            match args {
                Some(a) => {
                    let mut cmd =
                        vec!["ip", "netns", "exec", &ns, "tc", "qdisc", "replace", "dev", &peer, "root", "netem"];
                    cmd.extend_from_slice(a);
                    sh(&cmd)?;
                }
                None => {
                    let _ = sh(&["ip", "netns", "exec", &ns, "tc", "qdisc", "del", "dev", &peer, "root"]);
                }
            }
        }
        Ok(())
    }

    /// A hosts file: the plant on a, agents alternately on b and c.
    pub fn hosts_file(dir: &std::path::Path, n: u32) -> Result<PathBuf, String> {
        let b: Vec<String> = (1..=n).filter(|i| i % 2 == 1).map(|i| i.to_string()).collect();
        let c: Vec<String> = (1..=n).filter(|i| i % 2 == 0).map(|i| i.to_string()).collect();
        let text = format!(
            "[[hosts]]\nname = \"a\"\nendpoint = \"{}\"\nplant = true\n\n[[hosts]]\nname = \"b\"\nendpoint = \"{}\"\n\
             agents = [{}]\n\n[[hosts]]\nname = \"c\"\nendpoint = \"{}\"\nagents = [{}]\n",
            Self::endpoint(0),
            Self::endpoint(1),
            b.join(", "),
            Self::endpoint(2),
            c.join(", ")
        );
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        let path = dir.join(format!("hosts-{n}.toml"));
        std::fs::write(&path, text).map_err(|e| format!("{}: {e}", path.display()))?;
        Ok(path)
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        for d in &mut self.daemons {
            // SAFETY: kill(2) on a daemon this lab started; SIGTERM makes it stop its children.
            unsafe { libc::kill(d.id() as libc::pid_t, libc::SIGTERM) };
            let _ = d.wait();
        }
        self.teardown();
    }
}
