//! Security of Cohort's zenoh links (`orchestrator host` and `launch --hosts`, see
//! docs/multihost.md "Security"): zenoh's TLS with mutual authentication, and its user/password
//! authentication, the same for every session of a run.
//!
//! - TLS (`--tls-ca FILE --tls-cert FILE --tls-key FILE`): every endpoint is `tls/<address>:<port>`;
//!   each session presents the certificate both when it listens and when it connects, and accepts
//!   a peer only if the peer's certificate is signed by the CA (`transport.link.tls.enable_mtls`).
//!   TLS is always mutual here: every Cohort session both listens and connects (peers, gossip), and
//!   the daemon's queryable must not answer a client that proves nothing.
//! - User/password (`--auth-file FILE`): a zenoh dictionary of `<user>:<password>` lines; a session
//!   connects as the first line and accepts a peer that names any line
//!   (`transport.auth.usrpwd`). It authenticates, but does not encrypt: use it with TLS.
//!
//! A process passes its settings to the processes it starts through environment variables
//! ([`Security::to_env`]; file paths only, never a key or password), so the plant and agents of a
//! run use the same settings as the orchestrator or daemon that started them. A process installs
//! its settings once ([`install`]) before it opens a session; a process that installed none reads
//! them from its environment ([`current`]).

use std::path::{Path, PathBuf};
use std::sync::OnceLock;

/// Environment variables that carry the settings to the processes a session's owner starts.
pub const ENV_TLS_CA: &str = "COHORT_ZENOH_TLS_CA";
pub const ENV_TLS_CERT: &str = "COHORT_ZENOH_TLS_CERT";
pub const ENV_TLS_KEY: &str = "COHORT_ZENOH_TLS_KEY";
pub const ENV_AUTH_FILE: &str = "COHORT_ZENOH_AUTH_FILE";

/// TLS files: the CA that signs every certificate of the run, and this machine's certificate
/// and private key (PEM).
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TlsFiles {
    pub ca: PathBuf,
    pub cert: PathBuf,
    pub key: PathBuf,
}

/// The security settings of every zenoh session of this process.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Security {
    pub tls: Option<TlsFiles>,
    /// A zenoh user/password dictionary (`<user>:<password>` lines).
    pub auth_file: Option<PathBuf>,
    /// The first line's user and password (read from `auth_file` at validation).
    user_password: Option<(String, String)>,
}

/// Why the security settings cannot be used ([`Security::new`], [`Security::from_env`],
/// [`current`]): which flag (or environment variable) names which file, and what is wrong with it.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum SecurityConfigError {
    #[error("{flag} {}: {problem}", path.display())]
    File { flag: String, path: PathBuf, problem: FileProblem },
    #[error("{ca}, {cert} and {key} go together: give all three or none")]
    TlsIncomplete { ca: String, cert: String, key: String },
}

/// What is wrong with one security file.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum FileProblem {
    #[error("no such file")]
    NotFound,
    #[error("cannot be read (permission denied)")]
    PermissionDenied,
    #[error("cannot be read: {0}")]
    Unreadable(String),
    #[error("not PEM (not text)")]
    NotText,
    #[error("not PEM (no -----BEGIN {label}----- block)")]
    NoPemBlock { label: &'static str },
    #[error("is empty (expected <user>:<password> lines)")]
    EmptyDictionary,
    #[error("first line is not <user>:<password>")]
    NotUserPassword,
}

/// What was wrong with a file: the flag (or variable), the path, the reason.
fn bad(flag: &str, path: &Path, problem: FileProblem) -> SecurityConfigError {
    SecurityConfigError::File { flag: flag.to_string(), path: path.to_path_buf(), problem }
}

fn read(flag: &str, path: &Path) -> Result<String, SecurityConfigError> {
    let bytes = std::fs::read(path).map_err(|e| match e.kind() {
        std::io::ErrorKind::NotFound => bad(flag, path, FileProblem::NotFound),
        std::io::ErrorKind::PermissionDenied => bad(flag, path, FileProblem::PermissionDenied),
        _ => bad(flag, path, FileProblem::Unreadable(e.to_string())),
    })?;
    String::from_utf8(bytes).map_err(|_| bad(flag, path, FileProblem::NotText))
}

/// The file holds a PEM block whose label ends with `label` (`CERTIFICATE`, `PRIVATE KEY`).
fn check_pem(flag: &str, path: &Path, label: &'static str) -> Result<(), SecurityConfigError> {
    let text = read(flag, path)?;
    let found = text.lines().any(|l| {
        l.trim().strip_prefix("-----BEGIN ").and_then(|r| r.strip_suffix("-----")).is_some_and(|l| l.ends_with(label))
    });
    if found { Ok(()) } else { Err(bad(flag, path, FileProblem::NoPemBlock { label })) }
}

fn first_user_password(flag: &str, path: &Path) -> Result<(String, String), SecurityConfigError> {
    let text = read(flag, path)?;
    let line = text
        .lines()
        .map(str::trim)
        .find(|l| !l.is_empty())
        .ok_or_else(|| bad(flag, path, FileProblem::EmptyDictionary))?;
    match line.split_once(':') {
        Some((u, p)) if !u.is_empty() && !p.is_empty() => Ok((u.to_string(), p.to_string())),
        _ => Err(bad(flag, path, FileProblem::NotUserPassword)),
    }
}

impl Security {
    /// Check the files (present, readable, PEM; the dictionary's first line) and build the
    /// settings. `names` are how the caller calls the three TLS files and the dictionary, for
    /// the messages (`--tls-ca`, or an environment variable's name).
    pub fn new(
        ca: Option<PathBuf>,
        cert: Option<PathBuf>,
        key: Option<PathBuf>,
        auth_file: Option<PathBuf>,
        names: [&str; 4],
    ) -> Result<Self, SecurityConfigError> {
        let tls = match (ca, cert, key) {
            (None, None, None) => None,
            (Some(ca), Some(cert), Some(key)) => {
                check_pem(names[0], &ca, "CERTIFICATE")?;
                check_pem(names[1], &cert, "CERTIFICATE")?;
                check_pem(names[2], &key, "PRIVATE KEY")?;
                Some(TlsFiles { ca, cert, key })
            }
            _ => {
                return Err(SecurityConfigError::TlsIncomplete {
                    ca: names[0].into(),
                    cert: names[1].into(),
                    key: names[2].into(),
                });
            }
        };
        let user_password = auth_file.as_deref().map(|p| first_user_password(names[3], p)).transpose()?;
        Ok(Self { tls, auth_file, user_password })
    }

    /// The settings in this process's environment (see the `ENV_*` names).
    pub fn from_env() -> Result<Self, SecurityConfigError> {
        let var = |n: &str| std::env::var_os(n).filter(|v| !v.is_empty()).map(PathBuf::from);
        Self::new(
            var(ENV_TLS_CA),
            var(ENV_TLS_CERT),
            var(ENV_TLS_KEY),
            var(ENV_AUTH_FILE),
            [ENV_TLS_CA, ENV_TLS_CERT, ENV_TLS_KEY, ENV_AUTH_FILE],
        )
    }

    /// The environment that gives a child these settings (every variable, set or emptied, so a
    /// child never inherits other settings from this process's own environment).
    pub fn to_env(&self) -> Vec<(&'static str, std::ffi::OsString)> {
        let p = |x: Option<&PathBuf>| x.map(|p| absolute(p).into_os_string()).unwrap_or_default();
        let t = self.tls.as_ref();
        vec![
            (ENV_TLS_CA, p(t.map(|t| &t.ca))),
            (ENV_TLS_CERT, p(t.map(|t| &t.cert))),
            (ENV_TLS_KEY, p(t.map(|t| &t.key))),
            (ENV_AUTH_FILE, p(self.auth_file.as_ref())),
        ]
    }

    pub fn is_tls(&self) -> bool {
        self.tls.is_some()
    }

    /// The link protocol of every endpoint: `tls` or `tcp`.
    pub fn scheme(&self) -> &'static str {
        if self.is_tls() { "tls" } else { "tcp" }
    }

    /// Why `endpoint` (named `what`) cannot be used with these settings: a `tcp/` endpoint when
    /// TLS is on (it would carry the run, and `run.authenticate`'s key, in the clear), a `tls/`
    /// one when it is off.
    pub fn endpoint_problem(&self, what: &str, endpoint: &str) -> Option<String> {
        let scheme = endpoint.split('/').next().unwrap_or("");
        match (self.is_tls(), scheme) {
            (true, "tls") | (false, "tcp") => None,
            (true, _) => Some(format!(
                "{what} {endpoint}: TLS is configured (--tls-ca/--tls-cert/--tls-key), so every endpoint must be \
                 tls/<address>:<port>; a plain tcp/ link would carry the run and its keys unencrypted"
            )),
            (false, "tls") => Some(format!(
                "{what} {endpoint}: a tls/ endpoint needs --tls-ca, --tls-cert and --tls-key (see docs/multihost.md)"
            )),
            (false, _) => None,
        }
    }

    /// Add these settings to a zenoh configuration as `(key, json5 value)` pairs.
    pub fn config_entries(&self) -> Vec<(&'static str, String)> {
        let s = |p: &Path| json_string(&absolute(p).to_string_lossy());
        let mut v = Vec::new();
        if let Some(t) = &self.tls {
            v.extend([
                ("transport/link/tls/root_ca_certificate", s(&t.ca)),
                ("transport/link/tls/listen_certificate", s(&t.cert)),
                ("transport/link/tls/listen_private_key", s(&t.key)),
                ("transport/link/tls/connect_certificate", s(&t.cert)),
                ("transport/link/tls/connect_private_key", s(&t.key)),
                ("transport/link/tls/enable_mtls", "true".to_string()),
                ("transport/link/tls/verify_name_on_connect", "true".to_string()),
            ]);
        }
        if let (Some(f), Some((u, p))) = (&self.auth_file, &self.user_password) {
            v.extend([
                ("transport/auth/usrpwd/user", json_string(u)),
                ("transport/auth/usrpwd/password", json_string(p)),
                ("transport/auth/usrpwd/dictionary_file", s(f)),
            ]);
        }
        v
    }
}

fn absolute(p: &Path) -> PathBuf {
    std::path::absolute(p).unwrap_or_else(|_| p.to_path_buf())
}

fn json_string(s: &str) -> String {
    let mut out = String::from("\"");
    for c in s.chars() {
        match c {
            '"' => out.push_str("\\\""),
            '\\' => out.push_str("\\\\"),
            c if (c as u32) < 0x20 => out.push_str(&format!("\\u{:04x}", c as u32)),
            c => out.push(c),
        }
    }
    out.push('"');
    out
}

static INSTALLED: OnceLock<Security> = OnceLock::new();

/// Set this process's settings (from its command line), before it opens any session. Settings
/// installed already (a second call) are kept; the call says whether these were taken.
pub fn install(s: Security) -> bool {
    INSTALLED.set(s).is_ok()
}

/// This process's settings: those installed, else those of its environment (checked once).
pub fn current() -> Result<&'static Security, SecurityConfigError> {
    static FROM_ENV: OnceLock<Result<Security, SecurityConfigError>> = OnceLock::new();
    if let Some(s) = INSTALLED.get() {
        return Ok(s);
    }
    FROM_ENV.get_or_init(Security::from_env).as_ref().map_err(Clone::clone)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// This test process's scratch directory (removed at the test's end).
    fn key_dir() -> PathBuf {
        std::env::temp_dir().join(format!("cohort-zsec-{}", std::process::id()))
    }

    fn tmp(name: &str, text: &str) -> PathBuf {
        let d = key_dir();
        std::fs::create_dir_all(&d).unwrap();
        let p = d.join(name);
        std::fs::write(&p, text).unwrap();
        p
    }
    const NAMES: [&str; 4] = ["--tls-ca", "--tls-cert", "--tls-key", "--auth-file"];

    #[test]
    fn files_are_checked_and_named() {
        let cert = tmp("c.pem", "-----BEGIN CERTIFICATE-----\nAA==\n-----END CERTIFICATE-----\n");
        let key = tmp("k.pem", "-----BEGIN PRIVATE KEY-----\nAA==\n-----END PRIVATE KEY-----\n");
        let junk = tmp("junk.pem", "hello\n");
        let missing = PathBuf::from("/nonexistent/ca.pem");
        let e =
            Security::new(Some(missing), Some(cert.clone()), Some(key.clone()), None, NAMES).unwrap_err().to_string();
        assert!(e.contains("--tls-ca /nonexistent/ca.pem: no such file"), "{e}");
        let e = Security::new(Some(cert.clone()), Some(junk.clone()), Some(key.clone()), None, NAMES)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--tls-cert ") && e.contains("not PEM (no -----BEGIN CERTIFICATE----- block)"), "{e}");
        let e = Security::new(Some(cert.clone()), Some(cert.clone()), Some(cert.clone()), None, NAMES)
            .unwrap_err()
            .to_string();
        assert!(e.starts_with("--tls-key ") && e.contains("PRIVATE KEY"), "{e}");
        let e = Security::new(Some(cert.clone()), None, None, None, NAMES).unwrap_err().to_string();
        assert!(e.contains("go together"), "{e}");
        let e = Security::new(None, None, None, Some(junk), NAMES).unwrap_err().to_string();
        assert!(e.contains("--auth-file") && e.contains("<user>:<password>"), "{e}");
        let ok = Security::new(Some(cert.clone()), Some(cert), Some(key), Some(tmp("d", "u:p w\nv:q\n")), NAMES);
        let ok = ok.unwrap();
        let cfg = ok.config_entries();
        assert!(cfg.iter().any(|(k, v)| *k == "transport/link/tls/enable_mtls" && v == "true"));
        assert!(cfg.iter().any(|(k, v)| *k == "transport/auth/usrpwd/password" && v == "\"p w\""));
        let mut c = ::zenoh::Config::default();
        for (k, v) in cfg {
            c.insert_json5(k, &v).unwrap_or_else(|e| panic!("{k} = {v}: {e}"));
        }
        let _ = std::fs::remove_dir_all(key_dir());
    }

    #[test]
    fn endpoints_follow_the_scheme() {
        let plain = Security::default();
        assert!(plain.endpoint_problem("--listen", "tcp/127.0.0.1:7447").is_none());
        assert!(plain.endpoint_problem("--listen", "tls/127.0.0.1:7447").unwrap().contains("needs --tls-ca"));
        let tls = Security {
            tls: Some(TlsFiles { ca: "a".into(), cert: "b".into(), key: "c".into() }),
            ..Default::default()
        };
        assert!(tls.endpoint_problem("hosts[0]", "tcp/127.0.0.1:7447").unwrap().contains("must be tls/"));
        assert!(tls.endpoint_problem("hosts[0]", "tls/127.0.0.1:7447").is_none());
    }
}
