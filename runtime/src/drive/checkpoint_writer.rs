//! An agent's checkpoints written off the step path, by a thread of their own.
//!
//! Every agent checkpoints at the same steps, and creating and renaming a file on the run
//! directory's file system costs each a few hundred µs, more when a hundred processes do it at
//! once: in a 100-agent ring those steps took 16–116 ms against a 1–4 ms median (four runs), the
//! run's slowest; written here, 1.4–19 ms.
//! The agent encodes its state at the step (so the file holds exactly that step's state) and this
//! thread writes it (atomically, as before) while the lockstep goes on. Whoever reads a
//! checkpoint reads it after the agent waited for the writes: before a process fault the agent
//! is held for ([`CheckpointWriter::wait`] comes before it reports idle) and at the agent's end.
//! An agent that dies unplanned between the step and the write leaves its previous checkpoint,
//! whole, as a death just before the step would.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

/// Writes one agent's checkpoint file (always the same path) from encoded checkpoints.
pub(super) struct CheckpointWriter {
    /// Encoded checkpoints to write, oldest first.
    jobs: Option<Sender<Vec<u8>>>,
    done: Receiver<std::io::Result<()>>,
    thread: Option<JoinHandle<()>>,
    /// Jobs handed over and not yet answered.
    pending: usize,
}

impl CheckpointWriter {
    /// A writer of `path` (the agent's `checkpoint::path_for`), its thread named for `name`.
    pub(super) fn new(name: &str, path: PathBuf) -> std::io::Result<Self> {
        let (jobs, rx) = channel::<Vec<u8>>();
        let (tx, done) = channel();
        let thread = std::thread::Builder::new().name(format!("checkpoint {name}")).spawn(move || {
            // Like the telemetry writers: the time the lockstep's processes leave.
            crate::parquet_out::lower_this_threads_priority();
            for bytes in rx {
                if tx.send(crate::checkpoint::write_encoded(&path, &bytes)).is_err() {
                    break;
                }
            }
        })?;
        Ok(Self { jobs: Some(jobs), done, thread: Some(thread), pending: 0 })
    }

    /// Hand a checkpoint over; reports a failed earlier write, if any has come back since.
    pub(super) fn submit(&mut self, bytes: Vec<u8>) -> std::io::Result<()> {
        while let Ok(r) = self.done.try_recv() {
            self.pending -= 1;
            r?;
        }
        let jobs = self.jobs.as_ref().ok_or_else(|| std::io::Error::other("the checkpoint writer has ended"))?;
        jobs.send(bytes).map_err(|_| std::io::Error::other("the checkpoint writer thread has ended"))?;
        self.pending += 1;
        Ok(())
    }

    /// Block until every checkpoint handed over is on the file system; the first failure.
    pub(super) fn wait(&mut self) -> std::io::Result<()> {
        let mut first = Ok(());
        while self.pending > 0 {
            let r =
                self.done.recv().unwrap_or_else(|_| Err(std::io::Error::other("the checkpoint writer thread ended")));
            self.pending -= 1;
            if first.is_ok() {
                first = r;
            }
        }
        first
    }

    /// Wait for every write and end the thread.
    pub(super) fn finish(&mut self) -> std::io::Result<()> {
        let r = self.wait();
        self.jobs = None;
        if let Some(t) = self.thread.take() {
            let _ = t.join();
        }
        r
    }
}

impl Drop for CheckpointWriter {
    fn drop(&mut self) {
        let _ = self.finish();
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Every checkpoint handed over is on disk, whole, once `wait` returns; a write that fails is
    /// reported, naming the file.
    #[test]
    fn waits_for_every_write_and_reports_a_failure() {
        let dir = std::env::temp_dir().join(format!("cohort-ckw-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let mut w = CheckpointWriter::new("test", dir.join("checkpoints").join("a.ckpt")).unwrap();
        for i in 0..20u8 {
            w.submit(vec![i; 4096]).unwrap();
        }
        w.wait().unwrap();
        assert_eq!(std::fs::read(dir.join("checkpoints/a.ckpt")).unwrap(), vec![19u8; 4096], "the last one, whole");
        // A path under a regular file cannot be written.
        std::fs::write(dir.join("file"), b"x").unwrap();
        w.finish().unwrap();
        let mut w = CheckpointWriter::new("test", dir.join("file").join("b.ckpt")).unwrap();
        w.submit(vec![1]).unwrap();
        let e = w.wait().unwrap_err();
        assert!(e.to_string().contains("b.ckpt"), "{e}");
        w.finish().unwrap();
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
