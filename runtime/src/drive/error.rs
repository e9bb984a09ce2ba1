//! How a driver's run ends in error, and the report's form of it.

use cohort_wire::transport::TransportError;

#[derive(Debug, thiserror::Error)]
pub enum RunError {
    #[error("timeout at step {step}: no {what} from {from} for {after_s:.1} s")]
    Timeout { step: u64, from: String, what: &'static str, after_s: f64 },
    /// `waiting`: what the wait the stop ended was for (" while waiting for …"), or empty.
    #[error("stopped at step {step} on request ({why}){waiting}")]
    Stopped { step: u64, why: &'static str, waiting: String },
    #[error("transport: {0}")]
    Transport(#[from] TransportError),
    #[error("writing {what}: {source}")]
    Io { what: String, source: std::io::Error },
    /// The algorithm produced a non-finite number (it diverged). Sending it would only have it
    /// rejected by every reader and the run end later as a silent peer; fail here, naming it.
    #[error("{who} produced a non-finite {what} at step {step} (t = {t_s} s): it diverged")]
    Diverged { step: u64, t_s: f64, who: &'static str, what: String },
    /// The model's own code failed (a Python exception, a wrong return): see
    /// [`PlantModel::take_failure`].
    #[error("{who} failed at step {step} (t = {t_s} s): {what}")]
    Model { step: u64, t_s: f64, who: &'static str, what: String },
}

/// A model's failure since the driver last asked ([`PlantModel::take_failure`]), as the error
/// that ends the run at step `step`.
pub(super) fn failed(what: Option<String>, who: &'static str, step: u64, t_s: f64) -> Result<(), RunError> {
    what.map_or(Ok(()), |what| Err(RunError::Model { step, t_s, who, what }))
}

impl RunError {
    /// The report's form of this error.
    pub fn to_report(&self) -> crate::record::ProcessError {
        use crate::record::ErrorKind;
        let kind = match self {
            RunError::Timeout { .. } => ErrorKind::Timeout,
            RunError::Stopped { .. } => ErrorKind::Stopped,
            RunError::Transport(_) => ErrorKind::Transport,
            RunError::Io { .. } => ErrorKind::Io,
            RunError::Diverged { .. } => ErrorKind::Diverged,
            RunError::Model { .. } => ErrorKind::Model,
        };
        let e = crate::record::ProcessError::new(kind, self.to_string());
        match self {
            RunError::Diverged { t_s, .. } | RunError::Model { t_s, .. } => e.at(*t_s),
            _ => e,
        }
    }
}

pub(super) fn io(what: impl Into<String>) -> impl FnOnce(std::io::Error) -> RunError {
    let what = what.into();
    move |source| RunError::Io { what, source }
}
