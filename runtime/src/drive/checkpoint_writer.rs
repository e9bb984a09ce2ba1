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
//!
//! The thread gets the checkpoint a few steps after it was encoded ([`stagger`]: by agent id,
//! at most 64 steps): a hundred writer threads woken at the same step still took the cores from
//! the lockstep at once, and contended for the directory's lock while doing it (7.7 % of a
//! 100-agent ring's CPU samples were theirs, mostly spinning on that lock in the kernel), and
//! those steps were among a run's slowest (README, "Where a 100-agent step's worst cases come
//! from"). The encoded bytes wait in the agent meanwhile; [`CheckpointWriter::wait`] hands them
//! over first.
//!
//! The bytes come back with the write's outcome and are freed by the agent's own thread, as the
//! telemetry writers' buffers are (see `parquet_out::ParquetWriter`): a `free` on this nice-19
//! thread would take the lock of the agent's main allocation arena, and the step thread's next
//! `malloc` would wait for as long as this thread, preempted, held it.

use std::path::PathBuf;
use std::sync::mpsc::{Receiver, Sender, channel};
use std::thread::JoinHandle;

/// Writes one agent's checkpoint file (always the same path) from encoded checkpoints.
pub(super) struct CheckpointWriter {
    /// Encoded checkpoints to write, oldest first.
    jobs: Option<Sender<Vec<u8>>>,
    /// Each write's outcome, with its bytes.
    done: Receiver<(std::io::Result<()>, Vec<u8>)>,
    thread: Option<JoinHandle<()>>,
    /// Jobs handed over and not yet answered.
    pending: usize,
    /// An encoded checkpoint not handed over yet, and the step it goes at.
    held: Option<(u64, Vec<u8>)>,
}

/// How many steps after its own step agent `id`'s checkpoint goes to the writer thread, with one
/// every `every` steps: spread over at most a quarter of the interval and at most 64 steps, so a
/// held checkpoint always goes before the next is encoded.
pub(super) fn stagger(id: u32, every: u64) -> u64 {
    let spread = (every / 4).clamp(1, 64);
    u64::from(id) % spread
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
                if tx.send((crate::checkpoint::write_encoded(&path, &bytes), bytes)).is_err() {
                    break;
                }
            }
        })?;
        Ok(Self { jobs: Some(jobs), done, thread: Some(thread), pending: 0, held: None })
    }

    /// Keep a checkpoint to hand over at step `at` ([`Self::release_due`]); one still held goes
    /// now.
    pub(super) fn hold(&mut self, bytes: Vec<u8>, at: u64) -> std::io::Result<()> {
        self.hand_over_held()?;
        self.held = Some((at, bytes));
        Ok(())
    }

    /// At step `k`: hand over the held checkpoint if its step has come.
    pub(super) fn release_due(&mut self, k: u64) -> std::io::Result<()> {
        if self.held.as_ref().is_some_and(|(at, _)| *at <= k) { self.hand_over_held() } else { Ok(()) }
    }

    /// Hand over the held checkpoint, if any, whatever its step.
    fn hand_over_held(&mut self) -> std::io::Result<()> {
        match self.held.take() {
            Some((_, bytes)) => self.submit(bytes),
            None => Ok(()),
        }
    }

    /// Hand a checkpoint over; reports a failed earlier write, if any has come back since.
    pub(super) fn submit(&mut self, bytes: Vec<u8>) -> std::io::Result<()> {
        while let Ok((r, _bytes)) = self.done.try_recv() {
            self.pending -= 1;
            r?;
        }
        let jobs = self.jobs.as_ref().ok_or_else(|| std::io::Error::other("the checkpoint writer has ended"))?;
        jobs.send(bytes).map_err(|_| std::io::Error::other("the checkpoint writer thread has ended"))?;
        self.pending += 1;
        Ok(())
    }

    /// Hand over a held checkpoint, then block until every checkpoint is on the file system; the
    /// first failure.
    pub(super) fn wait(&mut self) -> std::io::Result<()> {
        let mut first = self.hand_over_held();
        while self.pending > 0 {
            let r = self
                .done
                .recv()
                .map_or_else(|_| Err(std::io::Error::other("the checkpoint writer thread ended")), |(r, _bytes)| r);
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

    /// A held checkpoint reaches the file only at its step, or when the agent waits (before a
    /// fault, at its end); a newer one hands the older over first. Agents' steps spread over at
    /// most 64 steps and stay short of the next checkpoint.
    #[test]
    fn a_held_checkpoint_goes_at_its_step_or_when_waited_for() {
        let dir = std::env::temp_dir().join(format!("cohort-ckh-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let path = dir.join("checkpoints").join("a.ckpt");
        let mut w = CheckpointWriter::new("test", path.clone()).unwrap();
        w.hold(vec![1; 64], 7).unwrap();
        w.release_due(6).unwrap();
        std::thread::sleep(std::time::Duration::from_millis(50));
        assert!(!path.exists(), "written before its step");
        w.release_due(7).unwrap();
        w.hold(vec![2; 64], 20).unwrap();
        w.hold(vec![3; 64], 30).unwrap();
        let mut back = Vec::new();
        while w.pending > 0 {
            let (r, bytes) = w.done.recv().unwrap();
            r.unwrap();
            back.push(bytes);
            w.pending -= 1;
        }
        // The bytes come back, to be freed by the agent's thread.
        assert_eq!(back, [vec![1u8; 64], vec![2u8; 64]]);
        assert_eq!(std::fs::read(&path).unwrap(), vec![2u8; 64], "the older held one went when the newer came");
        w.wait().unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), vec![3u8; 64], "wait hands over the held one");
        w.finish().unwrap();
        std::fs::remove_dir_all(&dir).unwrap();

        let at: Vec<u64> = (1..=100).map(|id| stagger(id, 500)).collect();
        assert_eq!((at.iter().min(), at.iter().max()), (Some(&0), Some(&63)));
        assert!((1..=1000).all(|id| stagger(id, 500) < 64 && stagger(id, 8) < 2 && stagger(id, 1) == 0));
    }
}
