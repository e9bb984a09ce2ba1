//! Doorbells: how one process of a run on this host wakes another — per process a futex word
//! and a bitmap of who rang, all in one owner-only file of the run's root directory.
//!
//! A sender publishes its sample first, then rings: it sets its bit in the reader's bitmap and,
//! only when the reader has said it is about to sleep, wakes it with one `FUTEX_WAKE`. A reader
//! that spins (adaptive waiting at scale, `poll`) is never sent a system call; one that blocks
//! says so, looks at its bitmap once more and sleeps in `FUTEX_WAIT` on its word. With both
//! sides' steps sequentially consistent, either the reader sees the bit or the sender sees the
//! sleeper (the store-then-load pattern of Dekker's mutual exclusion), so a ring is never lost;
//! waits stay short and repeated anyway. The bitmap is also the reader's list of whom to drain:
//! a 1 000-agent plant reads the few senders that rang, not every subscriber.
//!
//! This replaced iceoryx2's event services (`wake/<p>`, a unix datagram socket per process):
//! every notification was a `sendto` whether the reader slept or not, every timed wait a
//! `fcntl`, a `setsockopt` and a `recvfrom`, and every process one more service to create and
//! open at start-up.
//!
//! The orchestrator (or the host's gateway relaying it) rings every process's doorbell after each
//! run-control notice it publishes, as sender N + 1, which no reader subscribes to: a process
//! waiting for its peers sees a stop, a resume or a roster change at once, so its waits need not
//! wake up every few milliseconds to look (`DataPath::woken_by_control`).
//!
//! Layout: slot `k` (the plant 0, agent i at i, the host's gateway at N + 1) is a 64-byte line
//! whose first `u32` is the futex word (1: about to sleep), then `⌈(N + 2)/64⌉` words of 64 bits,
//! bit `s` for sender id `s` (N + 1: run control), padded to a whole line; after the slots, one
//! line of run-wide words (the plant's waiting advice, `DataPath::wait_advice`). Nothing read
//! from the file is used as an index or bound: a reader maps bits to its own subscriptions and ignores the rest, so a
//! process of the same user scribbling on the file can cost wakeups, never memory safety.

use std::fs::OpenOptions;
use std::os::fd::AsRawFd;
use std::os::unix::fs::OpenOptionsExt;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU32, AtomicU64, Ordering::SeqCst};
use std::time::Duration;

use super::TransportError;

/// The file's name in a run's (or a domain's) root directory.
pub(crate) const FILE: &str = "doorbells";
const LINE: usize = 64;

/// One run's doorbells, mapped.
pub(crate) struct Doorbells {
    base: *mut u8,
    len: usize,
    /// Slots (processes) and bitmap words per slot.
    slots: usize,
    words: usize,
    slot_bytes: usize,
}

// SAFETY: the mapping is only reached through atomics; it lives as long as the value.
unsafe impl Send for Doorbells {}
unsafe impl Sync for Doorbells {}

impl Doorbells {
    /// The file's size for `n` agents: slots for the plant, the agents and a gateway; bits for
    /// those senders and run control.
    fn shape(n_agents: usize) -> (usize, usize, usize) {
        let slots = n_agents + 2;
        let words = (n_agents + 2).div_ceil(64);
        let slot_bytes = LINE + (words * 8).div_ceil(LINE) * LINE;
        (slots, words, slot_bytes)
    }

    pub(crate) fn path(root: &Path) -> PathBuf {
        root.join(FILE)
    }

    /// Make the run's file (mode 0600, zeroed) in `root`, which must exist, and map it.
    pub(crate) fn create(root: &Path, n_agents: usize) -> Result<Self, TransportError> {
        let path = Self::path(root);
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .create_new(true)
            .mode(0o600)
            .custom_flags(libc::O_NOFOLLOW)
            .open(&path)
            .map_err(|e| err(&path, e))?;
        let (slots, words, slot_bytes) = Self::shape(n_agents);
        file.set_len(file_len(slots, slot_bytes) as u64).map_err(|e| err(&path, e))?;
        Self::map(&path, &file, slots, words, slot_bytes)
    }

    /// Map the run's file made by [`Self::create`] for `n_agents`; a file of another size is
    /// refused with both sizes named.
    pub(crate) fn open(root: &Path, n_agents: usize) -> Result<Self, TransportError> {
        let path = Self::path(root);
        let file = OpenOptions::new()
            .read(true)
            .write(true)
            .custom_flags(libc::O_NOFOLLOW)
            .open(&path)
            .map_err(|e| err(&path, e))?;
        let (slots, words, slot_bytes) = Self::shape(n_agents);
        let len = file.metadata().map_err(|e| err(&path, e))?.len();
        if len != file_len(slots, slot_bytes) as u64 {
            return Err(TransportError::Other(format!(
                "{}: {len} bytes, not the {} of a run of {n_agents} agents",
                path.display(),
                file_len(slots, slot_bytes)
            )));
        }
        Self::map(&path, &file, slots, words, slot_bytes)
    }

    fn map(
        path: &Path,
        file: &std::fs::File,
        slots: usize,
        words: usize,
        slot_bytes: usize,
    ) -> Result<Self, TransportError> {
        let len = file_len(slots, slot_bytes);
        // SAFETY: a fresh shared mapping of the whole file; the descriptor may close after it.
        let base = unsafe {
            libc::mmap(
                std::ptr::null_mut(),
                len,
                libc::PROT_READ | libc::PROT_WRITE,
                libc::MAP_SHARED,
                file.as_raw_fd(),
                0,
            )
        };
        if base == libc::MAP_FAILED {
            return Err(err(path, std::io::Error::last_os_error()));
        }
        Ok(Self { base: base.cast(), len, slots, words, slot_bytes })
    }

    /// The slot of the host's gateway.
    pub(crate) fn gateway_slot(&self) -> usize {
        self.slots - 1
    }

    fn word(&self, slot: usize) -> &AtomicU32 {
        assert!(slot < self.slots, "doorbell slot {slot} of {}", self.slots);
        // SAFETY: in the mapping, aligned to a line, only ever accessed atomically.
        unsafe { &*self.base.add(slot * self.slot_bytes).cast::<AtomicU32>() }
    }

    fn bits(&self, slot: usize) -> &[AtomicU64] {
        assert!(slot < self.slots, "doorbell slot {slot} of {}", self.slots);
        // SAFETY: as above; `words` words follow the slot's first line.
        unsafe { std::slice::from_raw_parts(self.base.add(slot * self.slot_bytes + LINE).cast(), self.words) }
    }

    /// The sender id of run control: N + 1, which no reader subscribes to.
    pub(crate) fn control_sender(&self) -> usize {
        self.slots - 1
    }

    /// Run control rings every process's slot (not the gateway's: it reads no control) after
    /// publishing a notice.
    pub(crate) fn ring_processes(&self) {
        (0..self.gateway_slot()).for_each(|to| self.ring(to, self.control_sender()));
    }

    /// The run-wide line's first word: the plant's waiting advice (0: none yet), on a line of
    /// its own so that reading it never contends with a futex word.
    fn advice_word(&self) -> &AtomicU64 {
        // SAFETY: the line after the last slot, in the mapping, aligned, only accessed atomically.
        unsafe { &*self.base.add(self.slots * self.slot_bytes).cast::<AtomicU64>() }
    }

    /// Publish `advice` (non-zero) for every process of the host; a store only when it changes.
    pub(crate) fn set_advice(&self, advice: u64) {
        let w = self.advice_word();
        if w.load(SeqCst) != advice {
            w.store(advice, SeqCst);
        }
    }

    /// The latest advice, 0 when none was published.
    pub(crate) fn advice(&self) -> u64 {
        self.advice_word().load(SeqCst)
    }

    /// Sender `from` rings slot `to` (after publishing what it rings for).
    pub(crate) fn ring(&self, to: usize, from: usize) {
        let Some(w) = self.bits(to).get(from / 64) else { return };
        w.fetch_or(1 << (from % 64), SeqCst);
        let word = self.word(to);
        if word.load(SeqCst) == 1 && word.swap(0, SeqCst) == 1 {
            futex_wake(word);
        }
    }

    /// Clear slot `me`'s bitmap, calling `f` with every sender id that had rung (call it before
    /// draining: a ring after it is seen by the next wait).
    pub(crate) fn take(&self, me: usize, mut f: impl FnMut(usize)) {
        for (k, w) in self.bits(me).iter().enumerate() {
            if w.load(SeqCst) == 0 {
                continue;
            }
            let mut b = w.swap(0, SeqCst);
            while b != 0 {
                f(k * 64 + b.trailing_zeros() as usize);
                b &= b - 1;
            }
        }
    }

    /// Sleep until slot `me` is rung or `timeout` passes (or a signal arrives); at once when it
    /// has been rung since the last [`Self::take`]. Whether a ring is waiting now.
    pub(crate) fn wait(&self, me: usize, timeout: Duration) -> bool {
        let word = self.word(me);
        word.store(1, SeqCst);
        if !self.rung(me) {
            futex_wait(word, timeout);
        }
        word.store(0, SeqCst);
        self.rung(me)
    }

    /// Whether slot `me` has been rung since the last [`Self::take`] (its bitmap's line only).
    pub(crate) fn rung(&self, me: usize) -> bool {
        self.bits(me).iter().any(|w| w.load(SeqCst) != 0)
    }
}

impl Drop for Doorbells {
    fn drop(&mut self) {
        // SAFETY: the mapping made in `map`, unmapped once.
        unsafe { libc::munmap(self.base.cast(), self.len) };
    }
}

/// The slots, then one line of run-wide words (the plant's waiting advice).
fn file_len(slots: usize, slot_bytes: usize) -> usize {
    slots * slot_bytes + LINE
}

fn err(path: &Path, e: std::io::Error) -> TransportError {
    TransportError::Other(format!("doorbells {}: {e}", path.display()))
}

/// `FUTEX_WAIT` while `word` is 1 (a shared futex: the word is in a file mapping), at most
/// `timeout`; a timeout, a signal or a word already changed all just return.
fn futex_wait(word: &AtomicU32, timeout: Duration) {
    let ts = libc::timespec {
        tv_sec: timeout.as_secs().min(i64::MAX as u64) as libc::time_t,
        tv_nsec: libc::c_long::from(timeout.subsec_nanos() as i32),
    };
    // SAFETY: a valid word and timespec for the call's duration.
    unsafe {
        libc::syscall(
            libc::SYS_futex,
            word.as_ptr(),
            libc::FUTEX_WAIT,
            1u32,
            &ts as *const libc::timespec,
            0usize,
            0u32,
        )
    };
}

fn futex_wake(word: &AtomicU32) {
    // SAFETY: a valid word; waking no one is fine.
    unsafe { libc::syscall(libc::SYS_futex, word.as_ptr(), libc::FUTEX_WAKE, 1i32, 0usize, 0usize, 0u32) };
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Instant;

    fn scratch(tag: &str) -> PathBuf {
        let d = std::env::temp_dir().join(format!("cohort-doorbell-{tag}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&d);
        std::fs::create_dir_all(&d).unwrap();
        d
    }

    /// Rings are seen by a second mapping (another process's view), each sender once, and
    /// taking clears them.
    #[test]
    fn rings_reach_another_mapping_and_take_clears_them() {
        let d = scratch("take");
        let a = Doorbells::create(&d, 130).unwrap();
        let b = Doorbells::open(&d, 130).unwrap();
        for from in [0, 3, 64, 130, 3] {
            a.ring(0, from);
        }
        a.ring(7, 5);
        let mut got = Vec::new();
        b.take(0, |s| got.push(s));
        assert_eq!(got, vec![0, 3, 64, 130]);
        got.clear();
        b.take(0, |s| got.push(s));
        assert!(got.is_empty());
        b.take(7, |s| got.push(s));
        assert_eq!(got, vec![5]);
        // A sender id past the bitmap rings nothing.
        a.ring(1, 10_000);
        assert!(!b.rung(1));
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A sleeper is woken by a ring from another thread long before its timeout; without a ring
    /// it sleeps its timeout; rung already, it does not sleep.
    #[test]
    fn a_ring_wakes_a_sleeper_and_a_pending_one_keeps_it_awake() {
        let d = scratch("wait");
        let bells = std::sync::Arc::new(Doorbells::create(&d, 4).unwrap());
        let t0 = Instant::now();
        assert!(!bells.wait(2, Duration::from_millis(50)));
        assert!(t0.elapsed() >= Duration::from_millis(45), "{:?}", t0.elapsed());

        let other = std::sync::Arc::clone(&bells);
        let ringer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            other.ring(2, 1);
        });
        let t0 = Instant::now();
        assert!(bells.wait(2, Duration::from_secs(30)));
        assert!(t0.elapsed() < Duration::from_secs(20), "{:?}", t0.elapsed());
        ringer.join().unwrap();

        let t0 = Instant::now();
        assert!(bells.wait(2, Duration::from_secs(30)), "the ring is still there until taken");
        assert!(t0.elapsed() < Duration::from_secs(20));
        bells.take(2, |_| {});
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// Run control rings every process (plant and agents), with a sender id of its own that has
    /// a bit even when N + 1 starts a new bitmap word, and not the gateway; it wakes a sleeper.
    #[test]
    fn run_control_rings_every_process_but_the_gateway() {
        let d = scratch("control");
        let bells = std::sync::Arc::new(Doorbells::create(&d, 63).unwrap());
        assert_eq!(bells.control_sender(), 64);
        let other = std::sync::Arc::clone(&bells);
        let ringer = std::thread::spawn(move || {
            std::thread::sleep(Duration::from_millis(100));
            other.ring_processes();
        });
        let t0 = Instant::now();
        assert!(bells.wait(5, Duration::from_secs(30)), "the control ring woke the sleeper");
        assert!(t0.elapsed() < Duration::from_secs(20), "{:?}", t0.elapsed());
        ringer.join().unwrap();
        for slot in 0..=63 {
            let mut got = Vec::new();
            bells.take(slot, |s| got.push(s));
            assert_eq!(got, vec![64], "slot {slot}");
        }
        assert!(!bells.rung(bells.gateway_slot()), "the gateway reads no run control");
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// The plant's advice starts as none, reaches another mapping, and lies outside every slot.
    #[test]
    fn advice_reaches_another_mapping_and_touches_no_slot() {
        let d = scratch("advice");
        let a = Doorbells::create(&d, 64).unwrap();
        let b = Doorbells::open(&d, 64).unwrap();
        assert_eq!(b.advice(), 0);
        a.set_advice(u64::MAX);
        assert_eq!(b.advice(), u64::MAX);
        for slot in 0..a.slots {
            assert!(!b.rung(slot), "slot {slot}");
        }
        std::fs::remove_dir_all(&d).unwrap();
    }

    /// A file of another run's size is refused, naming it; a missing one names its path.
    #[test]
    fn a_file_of_the_wrong_size_or_none_is_refused_by_name() {
        let d = scratch("size");
        let missing = Doorbells::open(&d, 4).err().expect("no file").to_string();
        assert!(missing.contains("doorbells") && missing.contains(&d.display().to_string()), "{missing}");
        let _a = Doorbells::create(&d, 4).unwrap();
        let wrong = Doorbells::open(&d, 100).err().expect("another size").to_string();
        assert!(wrong.contains("not the") && wrong.contains("100 agents"), "{wrong}");
        assert!(Doorbells::create(&d, 4).is_err(), "an existing file is not made again");
        std::fs::remove_dir_all(&d).unwrap();
    }
}
