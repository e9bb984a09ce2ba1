//! zenoh round trip between two processes, for `orchestrator bench` (hidden subcommands
//! `zenoh-echo` and `zenoh-ping`): the echo side republishes every sample it gets, the ping side
//! times put → echoed sample, both through the same session configuration and receive path
//! (a FIFO channel drained by the application thread) as the zenoh transport.

use std::time::{Duration, Instant};

use cohort_wire::transport::zenoh::{matched, open_session};
use zenoh::Wait;
use zenoh::qos::CongestionControl;

const PING: &str = "cohort/bench-rtt/ping";
const PONG: &str = "cohort/bench-rtt/pong";
/// Payload bytes of one ping (the order of a measurement or a small share).
const PAYLOAD: usize = 256;

/// Why a round-trip measurement ([`echo`], [`ping`]) stopped (exit 1): the zenoh step that
/// failed, or the echo that did not come.
#[derive(Debug, thiserror::Error)]
pub enum RttError {
    /// The session on the endpoint cannot be opened.
    #[error("{0}")]
    Session(cohort_wire::transport::TransportError),
    /// A subscriber or publisher on `key` cannot be declared.
    #[error("{key}: {reason}")]
    Declare { key: &'static str, reason: String },
    /// A sample cannot be sent.
    #[error("{0}")]
    Put(String),
    #[error("no echo at {0}")]
    NoEchoAt(String),
    #[error("no echo from {0}")]
    NoEchoFrom(String),
    #[error("ping {0}: no echo within 10 s")]
    Timeout(u64),
}

impl cohort_runtime::exit::ToExitCode for RttError {
    fn exit_code(&self) -> u8 {
        cohort_runtime::exit::FAILED
    }
}

/// Echo every sample, listening on `listen`, until none comes for 60 s (or this is killed).
pub fn echo(listen: &str) -> Result<(), RttError> {
    let s = open_session(&[listen.to_string()], &[]).map_err(RttError::Session)?;
    let sub = s.declare_subscriber(PING).wait().map_err(|e| RttError::Declare { key: PING, reason: e.to_string() })?;
    let publ = s
        .declare_publisher(PONG)
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(|e| RttError::Declare { key: PONG, reason: e.to_string() })?;
    while let Ok(Some(sample)) = sub.recv_timeout(Duration::from_secs(60)) {
        publ.put(sample.payload().clone()).wait().map_err(|e| RttError::Put(e.to_string()))?;
    }
    Ok(())
}

/// Round trips to the echo at `connect`: `warmup` untimed, then `count` timed. Prints one JSON
/// line: p50 and p99 in µs, max in ms.
pub fn ping(connect: &str, warmup: u64, count: u64) -> Result<String, RttError> {
    let s = open_session(&[], &[connect.to_string()]).map_err(RttError::Session)?;
    let sub = s.declare_subscriber(PONG).wait().map_err(|e| RttError::Declare { key: PONG, reason: e.to_string() })?;
    let publ = s
        .declare_publisher(PING)
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(|e| RttError::Declare { key: PING, reason: e.to_string() })?;
    let until = Instant::now() + Duration::from_secs(20);
    while !matched(&publ) {
        if Instant::now() > until {
            return Err(RttError::NoEchoAt(connect.to_string()));
        }
        std::thread::sleep(Duration::from_millis(5));
    }
    // The echo's subscriber is known here, but this side's may not be known there yet: warm-up
    // pings whose echo does not come are sent again.
    let payload = vec![0x5au8; PAYLOAD];
    let mut warm = 0;
    while warm < warmup {
        publ.put(payload.clone()).wait().map_err(|e| RttError::Put(e.to_string()))?;
        if let Ok(Some(_)) = sub.recv_timeout(Duration::from_secs(1)) {
            warm += 1;
        } else if Instant::now() > until {
            return Err(RttError::NoEchoFrom(connect.to_string()));
        }
    }
    while sub.try_recv().is_ok_and(|s| s.is_some()) {}
    let mut rtt_ns = Vec::with_capacity(count as usize);
    for k in 0..count {
        let t0 = Instant::now();
        publ.put(payload.clone()).wait().map_err(|e| RttError::Put(e.to_string()))?;
        match sub.recv_timeout(Duration::from_secs(10)) {
            Ok(Some(_)) => {}
            _ => return Err(RttError::Timeout(k)),
        }
        rtt_ns.push(t0.elapsed().as_nanos() as f64);
    }
    rtt_ns.sort_by(f64::total_cmp);
    let q = |p: f64| rtt_ns[((rtt_ns.len() - 1) as f64 * p).round() as usize];
    Ok(serde_json::json!({
        "p50_us": q(0.5) / 1e3,
        "p99_us": q(0.99) / 1e3,
        "max_ms": rtt_ns.last().copied().unwrap_or(f64::NAN) / 1e6,
        "samples": rtt_ns.len(),
    })
    .to_string())
}
