//! A user-space stand-in for `tc netem` on one Ethernet link, for kernels built without
//! `sch_netem` (`CONFIG_NET_SCH_NETEM` unset, as on the machines this project is tested on). The
//! bench's network lab ([`crate::netlab`]) and the multi-host test use it in place of veth pairs.
//!
//! Two TAP devices (`inner`, `outer`) are opened here; the caller moves `inner` into a network
//! namespace and enslaves `outer` to a bridge, so the pair replaces a veth pair. A pump carries
//! every Ethernet frame from one device to the other, after a delay (fixed plus uniform jitter)
//! or not at all (loss with a probability). Each direction has its own [`Impairment`]:
//! [`Link::from_inner`] is what the namespace sends (netem on the namespace's end of a veth),
//! [`Link::to_inner`] what it receives (netem on the bridge's end). Whole frames are carried, so
//! ARP, TCP's retransmissions and everything above them behave as they would behind netem. Where
//! it departs from netem:
//! - jitter never reorders frames (a frame waits for the one before it; netem reorders unless a
//!   rate is set), so the delay distribution is slightly skewed upwards;
//! - the pump itself adds latency per frame, even with no impairment set: a thread wake-up, a
//!   read and a write in user space (with a delay, also a channel hand-off to a second thread
//!   and its wake-up): tens of µs, more on a loaded machine, since the pump's threads wait for a
//!   core like any other (`orchestrator bench` measures it: docs/multihost.md);
//! - the delay is a thread's sleep, so it overshoots by the timer slack and the wake-up latency;
//! - the loss draw is a xorshift stream seeded by the caller, not the kernel's.
//!
//! The devices are not persistent: they vanish when the `Link` is dropped (its file descriptors
//! close), wherever they were moved to.

use std::fs::File;
use std::io::{Read, Write};
use std::os::fd::AsRawFd;
use std::sync::atomic::{AtomicBool, AtomicU32, AtomicU64, Ordering};
use std::sync::{Arc, mpsc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

// <linux/if_tun.h>
const TUNSETIFF: libc::c_ulong = 0x4004_54ca;
const IFF_TAP: libc::c_short = 0x0002;
const IFF_NO_PI: libc::c_short = 0x1000;

/// `struct ifreq` as TUNSETIFF reads it: the name, then the flags (the rest of the union unused).
#[repr(C)]
struct IfReq {
    name: [u8; libc::IFNAMSIZ],
    flags: libc::c_short,
    _pad: [u8; 22],
}

/// What the pump does to every frame of one direction; changed at any time, read per frame.
#[derive(Default)]
pub struct Impairment {
    delay_ns: AtomicU64,
    jitter_ns: AtomicU64,
    loss_ppm: AtomicU32,
}

impl Impairment {
    /// netem's `delay D J loss L%`: each frame waits D ± U(J) (never before the previous one) and
    /// is dropped with probability `loss`. Jitter is capped at the delay (no negative wait).
    pub fn set(&self, delay: Duration, jitter: Duration, loss: f64) {
        self.delay_ns.store(delay.as_nanos() as u64, Ordering::Relaxed);
        self.jitter_ns.store(jitter.as_nanos().min(delay.as_nanos()) as u64, Ordering::Relaxed);
        self.loss_ppm.store((loss.clamp(0.0, 1.0) * 1e6).round() as u32, Ordering::Relaxed);
    }

    /// When a frame read at `now` goes out (`None`: dropped), given when the frame ahead of it
    /// goes out; `rng` is the direction's xorshift state, advanced once per frame.
    pub fn due(&self, now: Instant, last_due: Instant, rng: &mut u64) -> Option<Instant> {
        *rng ^= *rng << 13;
        *rng ^= *rng >> 7;
        *rng ^= *rng << 17;
        if ((*rng >> 11) % 1_000_000) < u64::from(self.loss_ppm.load(Ordering::Relaxed)) {
            return None;
        }
        let (d, j) = (self.delay_ns.load(Ordering::Relaxed), self.jitter_ns.load(Ordering::Relaxed));
        // Uniform in [d − j, d + j]; never before the frame ahead of it.
        let wait = if j == 0 { d } else { d - j + (*rng >> 3) % (2 * j + 1) };
        Some((now + Duration::from_nanos(wait)).max(last_due))
    }
}

/// Frames carried and dropped, both directions together.
#[derive(Default)]
pub struct Counts {
    pub carried: AtomicU64,
    pub dropped: AtomicU64,
}

/// One emulated link: two TAP devices and the pump between them (two threads per direction).
pub struct Link {
    /// Frames the namespace sends (inner → outer).
    pub from_inner: Arc<Impairment>,
    /// Frames the namespace receives (outer → inner).
    pub to_inner: Arc<Impairment>,
    pub counts: Arc<Counts>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

/// Why a TAP device could not be made.
#[derive(Debug, thiserror::Error)]
pub enum TapError {
    #[error("TAP name {name:?} is longer than {} bytes", libc::IFNAMSIZ - 1)]
    NameTooLong { name: String },
    #[error("/dev/net/tun: {0}")]
    Clone(std::io::Error),
    #[error("TUNSETIFF {name}: {source}")]
    SetInterface { name: String, source: std::io::Error },
}

fn open_tap(name: &str) -> Result<File, TapError> {
    if name.len() >= libc::IFNAMSIZ {
        return Err(TapError::NameTooLong { name: name.into() });
    }
    let tun = std::fs::OpenOptions::new().read(true).write(true).open("/dev/net/tun").map_err(TapError::Clone)?;
    let mut req = IfReq { name: [0; libc::IFNAMSIZ], flags: IFF_TAP | IFF_NO_PI, _pad: [0; 22] };
    req.name[..name.len()].copy_from_slice(name.as_bytes());
    // SAFETY: TUNSETIFF reads and writes one `struct ifreq`, which `req` is laid out as.
    let rc = unsafe { libc::ioctl(tun.as_raw_fd(), TUNSETIFF as _, &mut req) };
    if rc != 0 {
        return Err(TapError::SetInterface { name: name.into(), source: std::io::Error::last_os_error() });
    }
    Ok(tun)
}

/// Whether `fd` has a frame to read within `timeout_ms`.
fn readable(fd: &File, timeout_ms: i32) -> bool {
    let mut p = libc::pollfd { fd: fd.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    // SAFETY: one valid pollfd.
    unsafe { libc::poll(&mut p, 1, timeout_ms) > 0 && p.revents & libc::POLLIN != 0 }
}

/// Send one frame on; a write fails only while the device is down (set-up, teardown): that frame
/// is lost.
fn write_frame(to: &File, frame: &[u8], counts: &Counts) {
    let mut to = to;
    if to.write(frame).is_ok() {
        counts.carried.fetch_add(1, Ordering::Relaxed);
    }
}

impl Link {
    /// Create TAP devices `inner` and `outer` and start pumping frames between them (no
    /// impairment until one is set). `seed` starts the loss and jitter draws.
    pub fn start(inner: &str, outer: &str, seed: u64) -> Result<Link, TapError> {
        let a = Arc::new(open_tap(inner)?);
        let b = Arc::new(open_tap(outer)?);
        let mut link = Link {
            from_inner: Arc::new(Impairment::default()),
            to_inner: Arc::new(Impairment::default()),
            counts: Arc::new(Counts::default()),
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::new(),
        };
        link.direction(a.clone(), b.clone(), link.from_inner.clone(), seed | 1);
        link.direction(b, a, link.to_inner.clone(), seed.rotate_left(17) | 1);
        Ok(link)
    }

    /// The same impairment in both directions (netem on both ends of a veth).
    pub fn set_both(&self, delay: Duration, jitter: Duration, loss: f64) {
        self.from_inner.set(delay, jitter, loss);
        self.to_inner.set(delay, jitter, loss);
    }

    /// One direction: a reader that stamps each frame with its due time (or drops it) and a
    /// writer that sends it on when due. A frame already due with none queued ahead of it (no
    /// delay set) the reader writes itself: that saves a thread wake-up per frame, and the order
    /// holds, since the writer has nothing left to write.
    fn direction(&mut self, from: Arc<File>, to: Arc<File>, imp: Arc<Impairment>, mut rng: u64) {
        let (tx, rx) = mpsc::channel::<(Instant, Vec<u8>)>();
        // Frames handed to the writer and not yet written.
        let queued = Arc::new(AtomicU64::new(0));
        let (stop, counts, to_w, queued_w) = (self.stop.clone(), self.counts.clone(), to.clone(), queued.clone());
        self.threads.push(std::thread::spawn(move || {
            let mut buf = vec![0u8; 65_536];
            let mut last_due = Instant::now();
            while !stop.load(Ordering::Relaxed) {
                if !readable(&from, 50) {
                    continue;
                }
                let Ok(n) = (&*from).read(&mut buf) else { continue };
                let now = Instant::now();
                let Some(due) = imp.due(now, last_due, &mut rng) else {
                    counts.dropped.fetch_add(1, Ordering::Relaxed);
                    continue;
                };
                last_due = due;
                if due <= now && queued.load(Ordering::Acquire) == 0 {
                    write_frame(&to, &buf[..n], &counts);
                    continue;
                }
                queued.fetch_add(1, Ordering::AcqRel);
                if tx.send((due, buf[..n].to_vec())).is_err() {
                    break;
                }
            }
        }));
        let (stop, counts) = (self.stop.clone(), self.counts.clone());
        self.threads.push(std::thread::spawn(move || {
            while !stop.load(Ordering::Relaxed) {
                let Ok((due, frame)) = rx.recv_timeout(Duration::from_millis(50)) else { continue };
                let now = Instant::now();
                if due > now {
                    std::thread::sleep(due - now);
                }
                write_frame(&to_w, &frame, &counts);
                queued_w.fetch_sub(1, Ordering::AcqRel);
            }
        }));
    }
}

impl Drop for Link {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        for t in self.threads.drain(..) {
            let _ = t.join();
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const MS: Duration = Duration::from_millis(1);

    #[test]
    fn frames_wait_the_delay_within_the_jitter_and_never_overtake() {
        let imp = Impairment::default();
        imp.set(2 * MS, MS / 2, 0.0);
        let (t0, mut rng, mut last) = (Instant::now(), 0x5eed_u64, Instant::now());
        for k in 0..10_000u32 {
            let now = t0 + Duration::from_micros(u64::from(k) * 10);
            let due = imp.due(now, last, &mut rng).expect("no loss set");
            assert!(due >= last, "frame {k} overtook the one ahead");
            // At most 2.5 ms after it arrived, unless it waits for the frame ahead.
            assert!(due - now <= 2 * MS + MS / 2 || due == last, "frame {k}: {:?}", due - now);
            assert!(due - now >= 2 * MS - MS / 2, "frame {k}: {:?}", due - now);
            last = due;
        }
    }

    #[test]
    fn no_impairment_sends_at_once_and_loss_drops_about_its_share() {
        let imp = Impairment::default();
        let (now, mut rng) = (Instant::now(), 7_u64);
        assert_eq!(imp.due(now, now, &mut rng), Some(now));
        imp.set(Duration::ZERO, Duration::ZERO, 0.01);
        let dropped = (0..100_000).filter(|_| imp.due(now, now, &mut rng).is_none()).count();
        assert!((800..1200).contains(&dropped), "{dropped} of 100 000 dropped at 1 %");
        imp.set(MS, 2 * MS, 0.0);
        // The jitter is capped at the delay: no frame goes out before it came in.
        assert!((0..1000).all(|_| imp.due(now, now, &mut rng).is_some_and(|d| d >= now)));
    }
}
