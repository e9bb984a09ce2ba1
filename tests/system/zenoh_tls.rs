//! zenoh security of multi-host runs (docs/multihost.md "Security", issue 36 item 10), with real
//! processes across a network namespace: the host daemon, and the plant and agents it starts,
//! run in namespace `ctls<pid>` at 198.18.79.2 (the benchmarking range, inside this test only),
//! joined by a veth pair to this namespace's 198.18.79.1, where the test and the orchestrator run.
//! Where `ip netns` is refused (no root, no CAP_NET_ADMIN) the daemon runs on a loopback port
//! instead, and the test says so (as `multihost.rs` does).
//!
//! - A daemon given certificates of the test CA (mutual TLS) and a user/password dictionary
//!   serves an orchestrator with the same CA and credentials: fig1 with `run.authenticate` (its
//!   per-run key sent over TLS) runs 500 steps with no process lost, bit-identical to
//!   `--reference`. Before the patched TLS link (vendor/README.md) such runs lost an agent within
//!   a few hundred steps: a write that met a read on one rustls connection failed and closed the
//!   link (3 of 4 150-step runs on one host, 2026-12-04).
//! - The daemon refuses, before anything starts, an orchestrator whose certificate another CA
//!   signed, one with the right certificate but a wrong password, one speaking plain TCP to its
//!   TLS port, and a zenoh session that trusts the CA but presents no certificate (while the same
//!   session with the certificate is let in, so the refusal is the certificate's). Bad security
//!   files are refused with exit 2 naming the flag, the file and the reason.
//!
//! The CA and certificates are made at test time with the `openssl` command line (the test fails,
//! saying so, where it is missing).

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

use cohort::{
    OutputWithin, QUICK_LIMIT, RUN_LIMIT, Scratch, bin_path, describe_output, heavy, processes_mentioning, repo_root,
    scratch_dir, sh, summary, telemetry_bits,
};

/// 500 lockstep steps of fig1: long enough that the unpatched TLS link lost an agent in nearly
/// every run, short enough for CI.
const DURATION: &str = "5";
const OUR_ADDR: &str = "198.18.79.1";
const DAEMON_ADDR: &str = "198.18.79.2";

/// The daemon's namespace and its veth pair, or nothing (the loopback fallback).
struct Lab {
    tag: String,
    namespaced: bool,
}

impl Lab {
    fn make(test: &str) -> Self {
        let mut lab = Lab { tag: format!("{:05}{test}", std::process::id() % 100_000), namespaced: true };
        if let Err(e) = lab.try_namespace() {
            lab.teardown();
            println!("ip netns refused ({e}): the daemon runs on a loopback port of this namespace instead");
            lab.namespaced = false;
        }
        lab
    }
    fn ns(&self) -> String {
        format!("ctls{}", self.tag)
    }
    fn veth(&self) -> String {
        format!("ctlsv{}", self.tag)
    }
    fn try_namespace(&self) -> Result<(), String> {
        let (ns, v, peer) = (self.ns(), self.veth(), format!("{}p", self.veth()));
        sh(&["ip", "netns", "add", &ns])?;
        sh(&["ip", "link", "add", &v, "type", "veth", "peer", "name", &peer])?;
        sh(&["ip", "link", "set", &peer, "netns", &ns])?;
        sh(&["ip", "addr", "add", &format!("{OUR_ADDR}/24"), "dev", &v])?;
        sh(&["ip", "link", "set", &v, "up"])?;
        sh(&["ip", "-n", &ns, "addr", "add", &format!("{DAEMON_ADDR}/24"), "dev", &peer])?;
        sh(&["ip", "-n", &ns, "link", "set", &peer, "up"])?;
        sh(&["ip", "-n", &ns, "link", "set", "lo", "up"])
    }
    fn teardown(&self) {
        let _ = sh(&["ip", "netns", "del", &self.ns()]);
        let _ = sh(&["ip", "link", "del", &self.veth()]);
    }
    /// The daemon's endpoint with `scheme` (`tls`, `tcp`): its own namespace's port 7447, or a
    /// free loopback port.
    fn daemon_endpoint(&self, scheme: &str, port: u16) -> String {
        let addr = if self.namespaced { DAEMON_ADDR } else { "127.0.0.1" };
        format!("{scheme}/{addr}:{port}")
    }
    fn daemon_port(&self) -> u16 {
        if self.namespaced {
            7447
        } else {
            std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
        }
    }
    /// `program` run in the daemon's namespace.
    fn command(&self, program: &Path) -> Command {
        if self.namespaced {
            let mut c = Command::new("ip");
            c.args(["netns", "exec", &self.ns()]).arg(program);
            c
        } else {
            Command::new(program)
        }
    }
}

impl Drop for Lab {
    fn drop(&mut self) {
        if self.namespaced {
            self.teardown();
        }
    }
}

fn openssl(dir: &Path, args: &[&str]) {
    let o = Command::new("openssl").current_dir(dir).args(args).output().unwrap_or_else(|e| {
        panic!("this test makes its CA with the openssl command line, which cannot be run ({e}): install openssl")
    });
    assert!(o.status.success(), "openssl {}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr));
}

/// A CA `<ca>-ca.pem` and one certificate `<ca>-cert.pem` / `<ca>-key.pem` it signs (EC P-256),
/// naming every address a process of the test listens on.
fn make_ca_and_cert(dir: &Path, ca: &str) {
    let (ca_key, ca_pem) = (format!("{ca}-ca-key.pem"), format!("{ca}-ca.pem"));
    let (key, csr, cert, ext) =
        (format!("{ca}-key.pem"), format!("{ca}.csr"), format!("{ca}-cert.pem"), format!("{ca}.ext"));
    let san = format!("subjectAltName = IP:{OUR_ADDR}, IP:{DAEMON_ADDR}, IP:127.0.0.1, DNS:localhost\n");
    std::fs::write(dir.join(&ext), san).unwrap();
    openssl(dir, &["ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", &ca_key]);
    let subject = format!("/CN={ca} CA");
    openssl(
        dir,
        &["req", "-x509", "-new", "-key", &ca_key, "-sha256", "-days", "2", "-subj", &subject, "-out", &ca_pem],
    );
    openssl(dir, &["genpkey", "-algorithm", "EC", "-pkeyopt", "ec_paramgen_curve:P-256", "-out", &key]);
    openssl(dir, &["req", "-new", "-key", &key, "-subj", "/CN=cohort test", "-out", &csr]);
    openssl(
        dir,
        &[
            "x509",
            "-req",
            "-in",
            &csr,
            "-CA",
            &ca_pem,
            "-CAkey",
            &ca_key,
            "-CAcreateserial",
            "-days",
            "2",
            "-sha256",
            "-extfile",
            &ext,
            "-out",
            &cert,
        ],
    );
}

/// The test's files: CAs `good` and `rogue`, the dictionary and a wrong one.
struct Pki {
    dir: Scratch,
}

impl Pki {
    fn make(tag: &str) -> Self {
        let dir = scratch_dir(tag);
        make_ca_and_cert(&dir, "good");
        make_ca_and_cert(&dir, "rogue");
        std::fs::write(dir.join("auth.txt"), "cohort:s3cret-run-pass\n").unwrap();
        std::fs::write(dir.join("wrong-auth.txt"), "cohort:not-the-password\n").unwrap();
        Pki { dir }
    }
    fn path(&self, f: &str) -> String {
        self.dir.join(f).to_string_lossy().into_owned()
    }
    /// TLS flags trusting CA `trust`, presenting the certificate CA `ca` signed, and the
    /// dictionary `auth`.
    fn flags(&self, trust: &str, ca: &str, auth: &str) -> Vec<String> {
        [
            ("--tls-ca", format!("{trust}-ca.pem")),
            ("--tls-cert", format!("{ca}-cert.pem")),
            ("--tls-key", format!("{ca}-key.pem")),
            ("--auth-file", auth.to_string()),
        ]
        .into_iter()
        .flat_map(|(flag, f)| [flag.to_string(), self.path(&f)])
        .collect()
    }
    fn good(&self) -> Vec<String> {
        self.flags("good", "good", "auth.txt")
    }
    /// One host `a` at `endpoint` with the plant and all six servicers.
    fn hosts_file(&self, endpoint: &str) -> PathBuf {
        let path = self.dir.join(format!("hosts-{}.toml", endpoint.replace(['/', ':', '.'], "_")));
        let text =
            format!("[[hosts]]\nname = \"a\"\nendpoint = \"{endpoint}\"\nplant = true\nagents = [1, 2, 3, 4, 5, 6]\n");
        std::fs::write(&path, text).unwrap();
        path
    }
}

/// `orchestrator host` in the lab's namespace, with `flags`.
struct Daemon(Child);

impl Daemon {
    fn start(lab: &Lab, listen: &str, flags: &[String]) -> Self {
        let mut c = lab.command(&bin_path("orchestrator"));
        c.args(["host", "--listen", listen, "--name", "a"]).args(flags);
        c.stdin(Stdio::null()).stdout(Stdio::null()).stderr(Stdio::piped());
        let mut child = c.spawn().expect("start a host daemon");
        let mut err = std::io::BufReader::new(child.stderr.take().expect("piped"));
        let mut line = String::new();
        std::io::BufRead::read_line(&mut err, &mut line).expect("the daemon's first line");
        assert!(line.contains("listening on"), "the TLS daemon did not start: {line}");
        std::thread::spawn(move || std::io::copy(&mut err, &mut std::io::sink()));
        Daemon(child)
    }
}

impl Drop for Daemon {
    fn drop(&mut self) {
        // `ip netns exec` execs the daemon, so the pid is the daemon's.
        // SAFETY: kill(2) on a child of this test; SIGTERM makes it stop its children.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let _ = self.0.wait();
    }
}

/// fig1 over zenoh with the hosts file and the flags, from this namespace.
fn launch(run: &Path, hosts: &Path, flags: &[String], limit: std::time::Duration) -> Output {
    let mut c = Command::new(bin_path("orchestrator"));
    c.current_dir(repo_root())
        .args(["launch", "topologies/fig1.toml", "--no-plots", "--duration", DURATION, "--transport", "zenoh"])
        .arg("--hosts")
        .arg(hosts)
        .arg("--out")
        .arg(run)
        .args(flags);
    c.output_within(limit, "fig1 launched over zenoh with security flags")
}

/// Refused before anything starts: exit 2, every one of `expect` in the message, no run
/// directory, nothing left running.
fn assert_refused(pki: &Pki, hosts: &Path, flags: &[String], expect: &[&str]) {
    let run = pki.dir.join("refused");
    let o = launch(&run, hosts, flags, QUICK_LIMIT);
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    for e in expect {
        assert!(err.contains(e), "expected {e:?}:\n{}", describe_output(&o));
    }
    assert!(!run.join("scenario.toml").exists(), "a refused launch prepared a run directory");
    assert!(processes_mentioning(run.to_str().unwrap()).is_empty());
}

#[test]
fn fig1_over_a_tls_daemon_in_another_namespace_is_bit_identical_to_the_reference() {
    let _g = heavy();
    let lab = Lab::make("r");
    let pki = Pki::make("zenoh-tls-run");
    let tls_at = lab.daemon_endpoint("tls", lab.daemon_port());
    let _daemon = Daemon::start(&lab, &tls_at, &pki.good());
    let hosts = pki.hosts_file(&tls_at);

    let (run, reference) = (pki.dir.join("run"), pki.dir.join("reference"));
    let flags = [pki.good(), vec!["--authenticate".into()]].concat();
    let o = launch(&run, &hosts, &flags, RUN_LIMIT);
    assert!(o.status.success(), "a run over TLS lost a process or failed:\n{}", describe_output(&o));
    let o = cohort::launch_scenario(
        Path::new("topologies/fig1.toml"),
        &reference,
        &["--duration", DURATION, "--reference"],
    );
    assert!(o.status.success(), "{}", describe_output(&o));
    let bits = telemetry_bits(&run);
    assert!(bits.len() > 500, "the TLS run wrote {} telemetry values", bits.len());
    assert_eq!(bits, telemetry_bits(&reference), "telemetry across TLS differs from the reference");
    let id = summary(&run)["run_id"].as_str().unwrap().to_string();
    assert!(processes_mentioning(&id).is_empty(), "left running: {:?}", processes_mentioning(&id));
}

#[test]
fn a_tls_daemon_refuses_another_ca_no_certificate_plain_tcp_and_a_wrong_password() {
    let _g = heavy();
    let lab = Lab::make("x");
    let pki = Pki::make("zenoh-tls-refuse");
    let port = lab.daemon_port();
    let tls_at = lab.daemon_endpoint("tls", port);
    let _daemon = Daemon::start(&lab, &tls_at, &pki.good());
    let tls_hosts = pki.hosts_file(&tls_at);
    let host_a = format!("hosts[0] (a at {tls_at})");

    // A certificate another CA signed (the daemon's own checks out); the right certificate and a
    // wrong password; plain TCP to the TLS port; a session trusting the CA with no certificate.
    assert_refused(&pki, &tls_hosts, &pki.flags("good", "rogue", "auth.txt"), &[&host_a, "unreachable"]);
    assert_refused(&pki, &tls_hosts, &pki.flags("good", "good", "wrong-auth.txt"), &[&host_a, "unreachable"]);
    let tcp_hosts = pki.hosts_file(&lab.daemon_endpoint("tcp", port));
    assert_refused(&pki, &tcp_hosts, &[], &["hosts[0] (a at tcp/", "unreachable"]);
    assert!(raw_session(&pki, &tls_at, true).is_ok(), "the control session with a certificate was refused");
    assert!(raw_session(&pki, &tls_at, false).is_err(), "a session without a client certificate was let in");

    // Refused here, before any link: a tls/ endpoint without certificates, TLS flags with a
    // tcp/ endpoint, a missing file, a file that is not PEM.
    assert_refused(&pki, &tls_hosts, &[], &[&host_a, "needs --tls-ca"]);
    assert_refused(&pki, &tcp_hosts, &pki.good(), &["must be tls/<address>:<port>"]);
    let mut missing = pki.good();
    missing[1] = pki.path("absent-ca.pem");
    assert_refused(&pki, &tls_hosts, &missing, &["--tls-ca", "absent-ca.pem: no such file"]);
    let mut not_pem = pki.good();
    not_pem[3] = pki.path("auth.txt");
    assert_refused(&pki, &tls_hosts, &not_pem, &["--tls-cert", "auth.txt: not PEM"]);
    let o = Command::new(bin_path("orchestrator"))
        .args(["host", "--listen", "tls/127.0.0.1:1", "--name", "b"])
        .args(&missing)
        .output_within(QUICK_LIMIT, "a host daemon given a missing CA file");
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("absent-ca.pem: no such file"), "{}", describe_output(&o));
}

/// A zenoh session to the daemon that trusts the good CA and gives the right user and password,
/// presenting the good certificate or (`with_cert` false) none: mutual TLS must refuse it then.
fn raw_session(pki: &Pki, tls_at: &str, with_cert: bool) -> Result<zenoh::Session, zenoh::Error> {
    use zenoh::Wait;
    let q = |s: String| format!("\"{s}\"");
    let mut entries = vec![
        ("mode", q("peer".into())),
        ("scouting/multicast/enabled", "false".to_string()),
        ("connect/endpoints", format!("[\"{tls_at}\"]")),
        ("connect/timeout_ms", "3000".to_string()),
        ("connect/exit_on_failure", "true".to_string()),
        ("transport/link/tls/root_ca_certificate", q(pki.path("good-ca.pem"))),
        ("transport/auth/usrpwd/user", q("cohort".into())),
        ("transport/auth/usrpwd/password", q("s3cret-run-pass".into())),
    ];
    if with_cert {
        entries.extend([
            ("transport/link/tls/enable_mtls", "true".to_string()),
            ("transport/link/tls/connect_certificate", q(pki.path("good-cert.pem"))),
            ("transport/link/tls/connect_private_key", q(pki.path("good-key.pem"))),
        ]);
    }
    let mut c = zenoh::Config::default();
    for (k, v) in entries {
        c.insert_json5(k, &v).unwrap_or_else(|e| panic!("{k} = {v}: {e}"));
    }
    zenoh::open(c).wait()
}
