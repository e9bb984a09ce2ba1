//! Waiting for a test's process with a limit, and saying what was waited for when it runs out.
//!
//! `Command::output()` waits forever: a run that hangs (a lost peer, a stuck daemon) hangs the
//! whole suite with no word of which test or what it was doing. [`OutputWithin::output_within`]
//! waits at most `limit`, then ends the command's whole process group (SIGTERM, then SIGKILL after
//! a grace, so an orchestrator can still clean up its children and shared memory) and fails the
//! test naming what it waited for, how long, and what the command had printed by then.

use std::io::Read;
use std::os::unix::process::CommandExt;
use std::process::{Child, Command, Output, Stdio};
use std::time::{Duration, Instant};

/// How long an ended command's process group gets between SIGTERM and SIGKILL.
const GRACE: Duration = Duration::from_secs(10);

/// [`Command::output`] with a limit.
pub trait OutputWithin {
    /// Runs the command to its end and returns its output, or panics if it has not ended within
    /// `limit`, naming `what` (e.g. "fig1 launched across three hosts") and the output so far.
    fn output_within(&mut self, limit: Duration, what: &str) -> Output;
}

impl OutputWithin for Command {
    fn output_within(&mut self, limit: Duration, what: &str) -> Output {
        // Its own process group, so that a hung command's children end with it.
        let child = self
            .stdout(Stdio::piped())
            .stderr(Stdio::piped())
            .process_group(0)
            .spawn()
            .unwrap_or_else(|e| panic!("{what}: cannot start {:?}: {e}", self.get_program()));
        finish_within(child, limit, &format!("{what}\ncommand: {}", command_line(self)))
    }
}

/// [`Child::wait_with_output`] with a limit: the output of a child a test spawned (and perhaps
/// signalled), or a panic naming `what` if it has not ended within `limit` (then it, and its
/// process group if it leads one, is ended).
pub fn finish_within(mut child: Child, limit: Duration, what: &str) -> Output {
    // Readers drain the pipes meanwhile: a command that prints more than a pipe holds would
    // otherwise block on its writes and look hung.
    let out = drain(child.stdout.take());
    let err = drain(child.stderr.take());
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("waiting for a test's command") {
            break Some(status);
        }
        if started.elapsed() > limit {
            end(&mut child);
            break None;
        }
        std::thread::sleep(Duration::from_millis(20));
    };
    let (stdout, stderr) = (out.join().unwrap_or_default(), err.join().unwrap_or_default());
    match status {
        Some(status) => Output { status, stdout, stderr },
        None => panic!(
            "{what}\nstill running after {limit:?}, ended (SIGTERM, SIGKILL after {GRACE:?})\n\
             --- stdout so far ---\n{}\n--- stderr so far ---\n{}",
            String::from_utf8_lossy(&stdout),
            String::from_utf8_lossy(&stderr)
        ),
    }
}

/// The command as a user would type it (program and arguments), for the failure message.
fn command_line(cmd: &Command) -> String {
    let mut line = cmd.get_program().to_string_lossy().into_owned();
    for a in cmd.get_args() {
        line.push(' ');
        line.push_str(&a.to_string_lossy());
    }
    line
}

fn drain(pipe: Option<impl Read + Send + 'static>) -> std::thread::JoinHandle<Vec<u8>> {
    std::thread::spawn(move || {
        let mut buf = Vec::new();
        if let Some(mut p) = pipe {
            let _ = p.read_to_end(&mut buf);
        }
        buf
    })
}

/// SIGTERM to the child (to its process group if it leads one), SIGKILL after [`GRACE`], and
/// the child reaped.
fn end(child: &mut Child) {
    let pid = child.id() as libc::pid_t;
    // SAFETY: getpgid(2) on a child of this test.
    let target = if unsafe { libc::getpgid(pid) } == pid { -pid } else { pid };
    // SAFETY: signalling a child of this test, or the process group it leads.
    unsafe { libc::kill(target, libc::SIGTERM) };
    let deadline = Instant::now() + GRACE;
    while Instant::now() < deadline {
        if matches!(child.try_wait(), Ok(Some(_))) {
            break;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    // SAFETY: as above; whatever is left is killed.
    unsafe { libc::kill(target, libc::SIGKILL) };
    let _ = child.wait();
}
