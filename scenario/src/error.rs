//! Scenario errors: every problem names the file, the key path, the value when there is one, and
//! the reason.

use std::fmt;
use std::path::PathBuf;

#[derive(Debug, Clone, PartialEq)]
pub struct Problem {
    /// Dotted key path with indices, e.g. `agents[2].neighbours[0]`; `(file)` for problems with
    /// the file as a whole (unreadable, not TOML).
    pub path: String,
    /// The offending value as written, when there is one.
    pub value: Option<String>,
    pub reason: String,
    /// Line and column in the file (1-based), once located ([`ScenarioError::located`]).
    pub at: Option<(usize, usize)>,
    /// The command-line flag that set the value (`--duration`), when one did: the problem is
    /// then cited by the flag, not by a line of the file the value did not come from.
    pub flag: Option<&'static str>,
}

impl Problem {
    pub fn new(path: impl Into<String>, value: Option<String>, reason: impl Into<String>) -> Self {
        Self { path: path.into(), value, reason: reason.into(), at: None, flag: None }
    }
}

impl fmt::Display for Problem {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match &self.value {
            Some(v) => write!(f, "{} = {}: {}", self.path, v, self.reason),
            None => write!(f, "{}: {}", self.path, self.reason),
        }
    }
}

/// All problems found in one scenario file.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub struct ScenarioError {
    pub file: PathBuf,
    pub problems: Vec<Problem>,
}

impl ScenarioError {
    /// Every problem given its line and column in `text` (the file's contents), where its key
    /// path is found.
    pub fn located(mut self, text: &str) -> Self {
        for p in &mut self.problems {
            if p.at.is_none() && p.flag.is_none() {
                p.at = crate::locate::locate(text, &p.path);
            }
        }
        self
    }
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let n = self.problems.len();
        write!(f, "{}: invalid scenario ({n} problem{})", self.file.display(), if n == 1 { "" } else { "s" })?;
        for p in &self.problems {
            match (p.flag, p.at) {
                (Some(flag), _) => write!(f, "\n  {flag} (command line): {p}")?,
                (None, Some((line, col))) => write!(f, "\n  {}:{line}:{col}: {p}", self.file.display())?,
                (None, None) => write!(f, "\n  {}: {p}", self.file.display())?,
            }
            // A problem spanning several lines (a TOML syntax error's caret) stays indented.
        }
        Ok(())
    }
}
