//! zenoh security of multi-host runs (docs/multihost.md "Security"): a host daemon given TLS
//! certificates (mutual TLS) and a user/password dictionary serves an orchestrator with the same
//! CA and credentials, bit-identically to `--reference`, and refuses, before anything starts, one
//! that speaks plain TCP, has a certificate of another CA, no client certificate, or a wrong
//! password; bad security files are refused with exit 2 naming the file. Loopback ports of this
//! machine (separate processes), so no network namespace is needed. The test CA and certificates
//! are made at test time with the openssl command line.

use std::path::{Path, PathBuf};
use std::process::{Child, Command, Output, Stdio};

use cohort::{bin_path, describe_output, heavy, processes_mentioning, scratch_dir, summary, telemetry_bits};

fn openssl(dir: &Path, args: &[&str]) {
    let o = Command::new("openssl")
        .current_dir(dir)
        .args(args)
        .output()
        .unwrap_or_else(|e| panic!("this test makes its certificates with the openssl command line: {e}"));
    assert!(o.status.success(), "openssl {}: {}", args.join(" "), String::from_utf8_lossy(&o.stderr));
}

/// A CA `<ca>-ca.pem` and a certificate `<ca>-cert.pem` / `<ca>-key.pem` it signs for
/// 127.0.0.1 (EC P-256).
fn make_ca_and_cert(dir: &Path, ca: &str) {
    let (ca_key, ca_pem) = (format!("{ca}-ca-key.pem"), format!("{ca}-ca.pem"));
    let (key, csr, cert) = (format!("{ca}-key.pem"), format!("{ca}.csr"), format!("{ca}-cert.pem"));
    let ext = format!("{ca}.ext");
    std::fs::write(dir.join(&ext), "subjectAltName = IP:127.0.0.1, DNS:localhost\n").unwrap();
    openssl(dir, &["ecparam", "-name", "prime256v1", "-genkey", "-noout", "-out", &ca_key]);
    openssl(
        dir,
        &[
            "req",
            "-x509",
            "-new",
            "-key",
            &ca_key,
            "-sha256",
            "-days",
            "2",
            "-subj",
            &format!("/CN={ca} CA"),
            "-out",
            &ca_pem,
        ],
    );
    openssl(dir, &["genpkey", "-algorithm", "EC", "-pkeyopt", "ec_paramgen_curve:P-256", "-out", &key]);
    openssl(dir, &["req", "-new", "-key", &key, "-subj", "/CN=127.0.0.1", "-out", &csr]);
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

/// The TLS flags of CA `ca`'s certificate (the CA checked against is `trust`'s).
fn tls_flags(dir: &Path, trust: &str, ca: &str) -> Vec<String> {
    let p = |f: String| dir.join(f).to_string_lossy().into_owned();
    vec![
        "--tls-ca".into(),
        p(format!("{trust}-ca.pem")),
        "--tls-cert".into(),
        p(format!("{ca}-cert.pem")),
        "--tls-key".into(),
        p(format!("{ca}-key.pem")),
    ]
}

struct Daemon(Child);

impl Daemon {
    fn start(listen: &str, flags: &[String]) -> Self {
        let mut c = Command::new(bin_path("orchestrator"));
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
        // SAFETY: kill(2) on a child of this test; SIGTERM makes it stop its children.
        unsafe { libc::kill(self.0.id() as i32, libc::SIGTERM) };
        let _ = self.0.wait();
    }
}

fn launch(run: &Path, hosts: &Path, flags: &[String]) -> Output {
    let mut extra: Vec<&str> = vec!["--duration", "1.5", "--transport", "zenoh", "--hosts", hosts.to_str().unwrap()];
    extra.extend(flags.iter().map(String::as_str));
    cohort::launch_scenario(Path::new("topologies/fig1.toml"), run, &extra)
}

fn hosts_file(dir: &Path, endpoint: &str) -> PathBuf {
    let path = dir.join(format!("hosts-{}.toml", endpoint.replace(['/', ':', '.'], "_")));
    let text =
        format!("[[hosts]]\nname = \"a\"\nendpoint = \"{endpoint}\"\nplant = true\nagents = [1, 2, 3, 4, 5, 6]\n");
    std::fs::write(&path, text).unwrap();
    path
}

/// Refused before anything starts: exit 2, `expect` in the message, no run directory.
fn assert_refused(dir: &Path, hosts: &Path, flags: &[String], expect: &[&str]) {
    let run = dir.join("refused");
    let o = launch(&run, hosts, flags);
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    let err = String::from_utf8_lossy(&o.stderr);
    for e in expect {
        assert!(err.contains(e), "expected {e:?}:\n{}", describe_output(&o));
    }
    assert!(!run.join("scenario.toml").exists(), "a refused launch prepared a run directory");
    assert!(processes_mentioning(run.to_str().unwrap()).is_empty());
}

#[test]
fn a_tls_daemon_serves_its_own_ca_bit_identically_and_refuses_everyone_else() {
    let _g = heavy();
    let dir = scratch_dir("zenoh-tls");
    make_ca_and_cert(&dir, "good");
    make_ca_and_cert(&dir, "rogue");
    std::fs::write(dir.join("auth.txt"), "cohort:s3cret-run-pass\n").unwrap();
    std::fs::write(dir.join("wrong-auth.txt"), "cohort:not-the-password\n").unwrap();
    let auth = |f: &str| vec!["--auth-file".to_string(), dir.join(f).to_string_lossy().into_owned()];
    let good = [tls_flags(&dir, "good", "good"), auth("auth.txt")].concat();

    let port = std::net::TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port();
    let tls_at = format!("tls/127.0.0.1:{port}");
    let daemon = Daemon::start(&tls_at, &good);
    let tls_hosts = hosts_file(&dir, &tls_at);

    // The same CA and password: the run (with run.authenticate's key, sent over TLS) matches
    // the reference bit for bit.
    let (run, reference) = (dir.join("run"), dir.join("reference"));
    let o = launch(&run, &tls_hosts, &[good.clone(), vec!["--authenticate".into()]].concat());
    assert!(o.status.success(), "{}", describe_output(&o));
    let o =
        cohort::launch_scenario(Path::new("topologies/fig1.toml"), &reference, &["--duration", "1.5", "--reference"]);
    assert!(o.status.success(), "{}", describe_output(&o));
    assert_eq!(telemetry_bits(&run), telemetry_bits(&reference), "telemetry across TLS differs from the reference");
    let id = summary(&run)["run_id"].as_str().unwrap().to_string();
    assert!(processes_mentioning(&id).is_empty(), "{:?}", processes_mentioning(&id));

    let host_a = format!("hosts[0] (a at {tls_at})");
    // A certificate of another CA; the right certificate but a wrong password.
    let rogue = [tls_flags(&dir, "good", "rogue"), auth("auth.txt")].concat();
    assert_refused(&dir, &tls_hosts, &rogue, &[&host_a, "unreachable"]);
    let wrong = [tls_flags(&dir, "good", "good"), auth("wrong-auth.txt")].concat();
    assert_refused(&dir, &tls_hosts, &wrong, &[&host_a, "unreachable"]);
    // Plain TCP to the TLS port; a tls/ endpoint without certificates; TLS flags with a tcp/ one.
    let tcp_hosts = hosts_file(&dir, &format!("tcp/127.0.0.1:{port}"));
    assert_refused(&dir, &tcp_hosts, &[], &["hosts[0] (a at tcp/127.0.0.1", "unreachable"]);
    assert_refused(&dir, &tls_hosts, &[], &[&host_a, "needs --tls-ca"]);
    assert_refused(&dir, &tcp_hosts, &good, &["must be tls/<address>:<port>"]);
    no_client_certificate_is_refused(&dir, &tls_at);

    // Bad files: named, with the reason, exit 2.
    let mut missing = good.clone();
    missing[1] = dir.join("absent-ca.pem").to_string_lossy().into_owned();
    assert_refused(&dir, &tls_hosts, &missing, &["--tls-ca", "absent-ca.pem: no such file"]);
    let mut not_pem = good.clone();
    not_pem[3] = dir.join("auth.txt").to_string_lossy().into_owned();
    assert_refused(&dir, &tls_hosts, &not_pem, &["--tls-cert", "auth.txt: not PEM"]);
    let o = Command::new(bin_path("orchestrator"))
        .args(["host", "--listen", &tls_at, "--name", "b"])
        .args(&missing)
        .output()
        .unwrap();
    assert_eq!(o.status.code(), Some(2), "{}", describe_output(&o));
    assert!(String::from_utf8_lossy(&o.stderr).contains("absent-ca.pem: no such file"), "{}", describe_output(&o));

    drop(daemon);
    let _ = std::fs::remove_dir_all(&dir);
}

/// A zenoh client that trusts the CA but presents no certificate cannot open a session to the
/// daemon (mutual TLS).
fn no_client_certificate_is_refused(dir: &Path, tls_at: &str) {
    use zenoh::Wait;
    let mut c = zenoh::Config::default();
    let ca = dir.join("good-ca.pem").to_string_lossy().into_owned();
    for (k, v) in [
        ("mode", "\"peer\"".to_string()),
        ("scouting/multicast/enabled", "false".to_string()),
        ("connect/endpoints", format!("[\"{tls_at}\"]")),
        ("connect/timeout_ms", "3000".to_string()),
        ("connect/exit_on_failure", "true".to_string()),
        ("transport/link/tls/root_ca_certificate", format!("\"{ca}\"")),
    ] {
        c.insert_json5(k, &v).unwrap();
    }
    let r = zenoh::open(c).wait();
    assert!(r.is_err(), "a session without a client certificate was let in");
}
