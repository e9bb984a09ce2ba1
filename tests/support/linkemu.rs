//! A user-space stand-in for `tc netem` on one Ethernet link, for kernels built without
//! `sch_netem` (`CONFIG_NET_SCH_NETEM` unset, as on the machines this project is tested on).
//!
//! Two TAP devices (`inner`, `outer`) are opened here; the caller moves `inner` into a network
//! namespace and enslaves `outer` to a bridge, so the pair replaces a veth pair. A pump carries
//! every Ethernet frame from one device to the other, after a delay (fixed plus uniform jitter)
//! or not at all (loss with a probability), in both directions, like netem on both ends of a
//! veth. Whole frames are carried, so ARP, TCP's retransmissions and everything above them behave
//! as they would behind netem. Where it departs from netem:
//! - jitter never reorders frames (a frame waits for the one before it; netem reorders unless a
//!   rate is set), so the delay distribution is slightly skewed upwards;
//! - the pump itself adds a few tens of µs per frame (a read, a channel hand-off and a write in
//!   user space), even with no impairment set;
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

/// What the pump does to every frame; changed at any time, read per frame.
#[derive(Default)]
pub struct Impairment {
    delay_ns: AtomicU64,
    jitter_ns: AtomicU64,
    loss_ppm: AtomicU32,
}

impl Impairment {
    /// netem's `delay D J loss L%`: each frame waits D ± U(J) (never before the previous one) and
    /// is dropped with probability `loss`.
    pub fn set(&self, delay: Duration, jitter: Duration, loss: f64) {
        self.delay_ns.store(delay.as_nanos() as u64, Ordering::Relaxed);
        self.jitter_ns.store(jitter.as_nanos().min(delay.as_nanos()) as u64, Ordering::Relaxed);
        self.loss_ppm.store((loss.clamp(0.0, 1.0) * 1e6).round() as u32, Ordering::Relaxed);
    }
}

/// Frames carried and dropped, both directions together.
#[derive(Default)]
pub struct Counts {
    pub carried: AtomicU64,
    pub dropped: AtomicU64,
}

pub struct Link {
    pub impairment: Arc<Impairment>,
    pub counts: Arc<Counts>,
    stop: Arc<AtomicBool>,
    threads: Vec<JoinHandle<()>>,
}

fn open_tap(name: &str) -> Result<File, String> {
    if name.len() >= libc::IFNAMSIZ {
        return Err(format!("TAP name {name:?} is longer than {} bytes", libc::IFNAMSIZ - 1));
    }
    let tun = std::fs::OpenOptions::new()
        .read(true)
        .write(true)
        .open("/dev/net/tun")
        .map_err(|e| format!("/dev/net/tun: {e}"))?;
    let mut req = IfReq { name: [0; libc::IFNAMSIZ], flags: IFF_TAP | IFF_NO_PI, _pad: [0; 22] };
    req.name[..name.len()].copy_from_slice(name.as_bytes());
    // SAFETY: TUNSETIFF reads and writes one `struct ifreq`, which `req` is laid out as.
    let rc = unsafe { libc::ioctl(tun.as_raw_fd(), TUNSETIFF as _, &mut req) };
    if rc != 0 {
        return Err(format!("TUNSETIFF {name}: {}", std::io::Error::last_os_error()));
    }
    Ok(tun)
}

/// Whether `fd` has a frame to read within `timeout_ms`.
fn readable(fd: &File, timeout_ms: i32) -> bool {
    let mut p = libc::pollfd { fd: fd.as_raw_fd(), events: libc::POLLIN, revents: 0 };
    // SAFETY: one valid pollfd.
    unsafe { libc::poll(&mut p, 1, timeout_ms) > 0 && p.revents & libc::POLLIN != 0 }
}

impl Link {
    /// Create TAP devices `inner` and `outer` and start pumping frames between them (no
    /// impairment until `impairment.set`). `seed` starts the loss draws.
    pub fn start(inner: &str, outer: &str, seed: u64) -> Result<Link, String> {
        let a = Arc::new(open_tap(inner)?);
        let b = Arc::new(open_tap(outer)?);
        let mut link = Link {
            impairment: Arc::new(Impairment::default()),
            counts: Arc::new(Counts::default()),
            stop: Arc::new(AtomicBool::new(false)),
            threads: Vec::new(),
        };
        link.direction(a.clone(), b.clone(), seed | 1);
        link.direction(b, a, seed.rotate_left(17) | 1);
        Ok(link)
    }

    /// One direction: a reader that stamps each frame with its due time (or drops it) and a
    /// writer that sends it on when due.
    fn direction(&mut self, from: Arc<File>, to: Arc<File>, mut rng: u64) {
        let (tx, rx) = mpsc::channel::<(Instant, Vec<u8>)>();
        let (stop, imp, counts) = (self.stop.clone(), self.impairment.clone(), self.counts.clone());
        self.threads.push(std::thread::spawn(move || {
            let mut buf = vec![0u8; 65_536];
            let mut last_due = Instant::now();
            while !stop.load(Ordering::Relaxed) {
                if !readable(&from, 50) {
                    continue;
                }
                let Ok(n) = (&*from).read(&mut buf) else { continue };
                let now = Instant::now();
                rng ^= rng << 13;
                rng ^= rng >> 7;
                rng ^= rng << 17;
                if ((rng >> 11) % 1_000_000) < u64::from(imp.loss_ppm.load(Ordering::Relaxed)) {
                    counts.dropped.fetch_add(1, Ordering::Relaxed);
                    continue;
                }
                let (d, j) = (imp.delay_ns.load(Ordering::Relaxed), imp.jitter_ns.load(Ordering::Relaxed));
                // Uniform in [d − j, d + j]; never before the frame ahead of it.
                let wait = if j == 0 { d } else { d - j + (rng >> 3) % (2 * j + 1) };
                let due = (now + Duration::from_nanos(wait)).max(last_due);
                last_due = due;
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
                // A write fails only while the device is down (set-up, teardown): that frame is lost.
                if (&*to).write(&frame).is_ok() {
                    counts.carried.fetch_add(1, Ordering::Relaxed);
                }
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
