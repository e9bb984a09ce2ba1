//! The zenoh security flags of `orchestrator host` and `orchestrator launch` (TLS with mutual
//! authentication, user/password authentication; see `cohort_wire::transport::zenoh_security`
//! and docs/multihost.md "Security"). They are checked (files present, readable, PEM) before
//! anything starts, then installed for every session of this process and passed to every process
//! it starts.

use std::path::PathBuf;

use clap::Args;
use cohort_wire::transport::zenoh_security::{self, Security, SecurityConfigError};

#[derive(Args, Debug, Clone, Default)]
pub struct SecurityArgs {
    /// zenoh TLS: the CA certificate (PEM) that signs every certificate of the run. With
    /// --tls-cert and --tls-key; every endpoint is then tls/<address>:<port> and TLS is mutual.
    #[arg(long, value_name = "FILE")]
    pub tls_ca: Option<PathBuf>,
    /// zenoh TLS: this machine's certificate (PEM), signed by --tls-ca, naming the address(es)
    /// its sessions listen on.
    #[arg(long, value_name = "FILE")]
    pub tls_cert: Option<PathBuf>,
    /// zenoh TLS: the private key (PEM) of --tls-cert.
    #[arg(long, value_name = "FILE")]
    pub tls_key: Option<PathBuf>,
    /// zenoh user/password authentication: a file of <user>:<password> lines; sessions connect
    /// as the first line and accept any line. Not encryption: use it with TLS.
    #[arg(long, value_name = "FILE")]
    pub auth_file: Option<PathBuf>,
}

impl SecurityArgs {
    /// Check the files and install the settings for this process (and its children); the first
    /// problem, naming the flag, the file and the reason.
    pub fn install(&self) -> Result<(), SecurityConfigError> {
        let s = Security::new(
            self.tls_ca.clone(),
            self.tls_cert.clone(),
            self.tls_key.clone(),
            self.auth_file.clone(),
            ["--tls-ca", "--tls-cert", "--tls-key", "--auth-file"],
        )?;
        if *self == Self::default() {
            // No flag: the environment's settings (COHORT_ZENOH_*), checked here all the same.
            return zenoh_security::current().map(|_| ());
        }
        zenoh_security::install(s);
        Ok(())
    }
}

impl PartialEq for SecurityArgs {
    fn eq(&self, o: &Self) -> bool {
        (&self.tls_ca, &self.tls_cert, &self.tls_key, &self.auth_file)
            == (&o.tls_ca, &o.tls_cert, &o.tls_key, &o.auth_file)
    }
}
