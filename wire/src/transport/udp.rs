//! UDP-loopback transport, kept as the baseline iceoryx2 is measured against (`orchestrator
//! bench`). Measurements and shares travel as datagrams holding the same `#[repr(C)]` payloads;
//! run control (start, stop, status) stays on the iceoryx2 control services, so only the data
//! path differs between the two transports.
//!
//! Rendezvous: every process binds 127.0.0.1:0, writes its port to `<run dir>/udp/<proc>.port`
//! ([`UdpData::bind`]), and waits until every other process of the run has done the same
//! ([`UdpBound::rendezvous`]). A datagram's source address tells who sent it (the driver checks
//! it against the header's sender).

use std::net::{Ipv4Addr, SocketAddr, SocketAddrV4, UdpSocket};
use std::os::fd::AsRawFd;
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use super::iox::{IoxControl, IoxRun};
use super::{DataPath, Incoming, Proc, Split, Topology, TransportError, bytes_of, monotonic_ns, read_payload};
use crate::msg::{Measurement, PLANT_ID, Share};

/// Big enough for the largest payload, in u64 words so the buffer is 8-byte aligned.
const BUF_WORDS: usize = std::mem::size_of::<Share>().div_ceil(8) + 8;

/// A process's UDP endpoint: datagrams for the data path, iceoryx2 for run control.
pub type UdpTransport = Split<UdpData, IoxControl>;

/// The data path of one process over UDP loopback.
pub struct UdpData {
    me: Proc,
    socket: UdpSocket,
    /// Address of the plant (index 0) and of each agent (index i).
    addrs: Vec<SocketAddr>,
    /// Who gets this agent's share: the plant first, then its readers.
    share_to: Vec<SocketAddr>,
    buf: Box<[u64; BUF_WORDS]>,
}

/// A bound socket whose port is published, waiting for its peers' (see [`UdpBound::rendezvous`]).
pub struct UdpBound {
    me: Proc,
    socket: UdpSocket,
    dir: PathBuf,
}

fn port_file(dir: &Path, p: Proc) -> PathBuf {
    dir.join(format!("{}.port", p.name()))
}

fn io(what: &str) -> impl FnOnce(std::io::Error) -> TransportError + '_ {
    move |e| TransportError::Other(format!("udp {what}: {e}"))
}

/// A process's endpoint: bind, publish this process's port, wait for every peer's (up to
/// `rendezvous_timeout`), and open the run's iceoryx2 control ports.
pub fn open(
    run: &IoxRun,
    topo: &Topology,
    me: Proc,
    dir: &Path,
    rendezvous_timeout: Duration,
) -> Result<UdpTransport, TransportError> {
    let data = UdpData::bind(dir, me)?.rendezvous(topo, rendezvous_timeout)?;
    Ok(Split { data, control: IoxControl::open(run, me)? })
}

impl UdpData {
    /// Bind 127.0.0.1:0 and publish the port in `dir` (the run directory's `udp/`).
    pub fn bind(dir: &Path, me: Proc) -> Result<UdpBound, TransportError> {
        let socket = UdpSocket::bind(SocketAddrV4::new(Ipv4Addr::LOCALHOST, 0)).map_err(io("bind"))?;
        socket.set_nonblocking(true).map_err(io("set_nonblocking"))?;
        // The plant receives every agent's share (≈ 4 kB each) per step before it drains: at
        // N = 100 that is more than the default receive buffer, and UDP drops what overflows.
        let want: libc::c_int = 16 << 20;
        for opt in [libc::SO_RCVBUFFORCE, libc::SO_RCVBUF] {
            // SAFETY: setsockopt on our own socket with a c_int option value.
            let rc = unsafe {
                libc::setsockopt(
                    socket.as_raw_fd(),
                    libc::SOL_SOCKET,
                    opt,
                    (&want as *const libc::c_int).cast(),
                    std::mem::size_of::<libc::c_int>() as libc::socklen_t,
                )
            };
            if rc == 0 {
                break; // SO_RCVBUFFORCE needs CAP_NET_ADMIN; SO_RCVBUF is capped by rmem_max
            }
        }
        std::fs::create_dir_all(dir).map_err(io("rendezvous directory"))?;
        let port = socket.local_addr().map_err(io("local_addr"))?.port();
        let tmp = dir.join(format!(".{}.port.tmp", me.name()));
        std::fs::write(&tmp, port.to_string()).map_err(io("write port"))?;
        std::fs::rename(&tmp, port_file(dir, me)).map_err(io("publish port"))?;
        Ok(UdpBound { me, socket, dir: dir.to_path_buf() })
    }

    fn sender_of(&self, addr: &SocketAddr) -> Option<u32> {
        self.addrs.iter().position(|a| a == addr).map(|i| i as u32)
    }
}

impl UdpBound {
    /// Wait until every process of `topo` has published its port (up to `rendezvous_timeout`).
    pub fn rendezvous(self, topo: &Topology, rendezvous_timeout: Duration) -> Result<UdpData, TransportError> {
        let (me, socket, dir) = (self.me, self.socket, self.dir.as_path());
        let procs: Vec<Proc> = std::iter::once(Proc::Plant).chain((1..=topo.n_agents()).map(Proc::Agent)).collect();
        let started = Instant::now();
        let mut addrs = Vec::with_capacity(procs.len());
        for p in &procs {
            let port = loop {
                if let Some(port) = std::fs::read_to_string(port_file(dir, *p)).ok().and_then(|t| t.trim().parse().ok())
                {
                    break port;
                }
                if started.elapsed() > rendezvous_timeout {
                    return Err(TransportError::Other(format!(
                        "udp rendezvous: no port from {} after {:.0} s",
                        p.name(),
                        rendezvous_timeout.as_secs_f64()
                    )));
                }
                std::thread::sleep(Duration::from_millis(2));
            };
            addrs.push(SocketAddr::V4(SocketAddrV4::new(Ipv4Addr::LOCALHOST, port)));
        }
        let share_to = match me {
            Proc::Plant => Vec::new(),
            Proc::Agent(i) => {
                std::iter::once(addrs[0]).chain(topo.readers_of(i).into_iter().map(|j| addrs[j as usize])).collect()
            }
        };
        Ok(UdpData { me, socket, addrs, share_to, buf: Box::new([0; BUF_WORDS]) })
    }
}

impl DataPath for UdpData {
    fn send_measurement(&mut self, to: u32, m: &Measurement) -> Result<(), TransportError> {
        let Some(addr) = self.addrs.get(to as usize).filter(|_| to > 0) else {
            return Err(TransportError::Other(format!("{} cannot send a measurement to agent {to}", self.me.name())));
        };
        let mut m = *m;
        m.header.sent_wall_ns = monotonic_ns();
        self.socket.send_to(bytes_of(&m), addr).map_err(io("send measurement"))?;
        Ok(())
    }

    fn send_share(&mut self, s: &Share) -> Result<(), TransportError> {
        if self.me == Proc::Plant {
            return Err(TransportError::Other("the plant has no share to send".into()));
        }
        let mut s = *s;
        s.header.sent_wall_ns = monotonic_ns();
        for addr in &self.share_to {
            self.socket.send_to(bytes_of(&s), addr).map_err(io("send share"))?;
        }
        Ok(())
    }

    fn drain(&mut self, f: &mut dyn FnMut(Incoming<'_>)) -> Result<(), TransportError> {
        loop {
            // SAFETY: viewing the u64 buffer as bytes (same memory, u8 has no alignment).
            let bytes = unsafe { std::slice::from_raw_parts_mut(self.buf.as_mut_ptr().cast::<u8>(), BUF_WORDS * 8) };
            let (len, from) = match self.socket.recv_from(bytes) {
                Ok(x) => x,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return Ok(()),
                Err(e) => return Err(io("receive")(e)),
            };
            let sender = self.sender_of(&from);
            let data = &bytes[..len];
            if len == std::mem::size_of::<Measurement>() && sender == Some(PLANT_ID) {
                let m: Measurement = read_payload(data);
                f(Incoming::Measurement(&m));
            } else if len == std::mem::size_of::<Share>() {
                let s: Share = read_payload(data);
                // An unknown source gets an id no agent has: the driver rejects it as a wrong
                // sender and counts it.
                f(Incoming::Share { from: sender.unwrap_or(u32::MAX), share: &s });
            }
            // Any other datagram (wrong size) is not one of ours; there is no payload to count.
        }
    }

    fn wait(&mut self, timeout: Duration) -> Result<(), TransportError> {
        let mut pfd = libc::pollfd { fd: self.socket.as_raw_fd(), events: libc::POLLIN, revents: 0 };
        let ts = libc::timespec {
            tv_sec: timeout.as_secs() as libc::time_t,
            tv_nsec: timeout.subsec_nanos() as libc::c_long,
        };
        // SAFETY: one valid pollfd, a valid timespec, no signal mask change.
        let rc = unsafe { libc::ppoll(&mut pfd, 1, &ts, std::ptr::null()) };
        if rc < 0 {
            let e = std::io::Error::last_os_error();
            if e.kind() != std::io::ErrorKind::Interrupted {
                return Err(io("poll")(e));
            }
        }
        Ok(())
    }
}
