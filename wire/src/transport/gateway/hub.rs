//! The gateway process's life: claim the host's domain, create its services, link to the other
//! hosts' gateways, relay run control, and clean up.

use std::path::PathBuf;
use std::sync::Arc;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use ::zenoh::Wait;
use ::zenoh::pubsub::Publisher;
use ::zenoh::sample::SampleKind;

use super::batch_key;
use super::carry::{Counts, Inbound, Shared, carry_out, destinations};
use crate::msg::{RunControl, SCHEMA_VERSION, Status};
use crate::transport::iox::{IoxRun, IoxServices};
use crate::transport::zenoh::{ZenohRun, err, matched, open_session, publisher, subscriber};
use crate::transport::{Topology, TransportError, bytes_of, read_payload};

/// The file a gateway writes in its domain's root directory once the domain's services exist:
/// whoever started it may start the host's processes.
pub const READY_MARKER: &str = "gateway.ready";

/// What a gateway needs to know.
pub struct GatewaySpec {
    /// The run, with this host's domain (`IoxRun::in_domain`) and the run's key.
    pub run: IoxRun,
    pub topo: Topology,
    /// Agent relaunches the fault plan may make (spare places in every service).
    pub spare: usize,
    /// zenoh endpoints: the orchestrator's to connect to, this host's to listen on.
    pub connect: Vec<String>,
    pub listen: Vec<String>,
}

/// What a gateway did, for its last log line.
#[derive(Debug, Clone, Default)]
pub struct GatewayEnd {
    pub batches_out: u64,
    pub messages_out: u64,
    pub batches_in: u64,
    pub messages_in: u64,
    /// Batches refused whole (see `batch::decode`).
    pub rejected_batches: u64,
    /// Why it ended: `None` when asked to (a signal, the orchestrator gone).
    pub failure: Option<String>,
}

/// Run a gateway until `stop` is set or the orchestrator's liveliness token goes; its domain's
/// resources are removed before it returns, whatever the outcome.
pub fn run(spec: GatewaySpec, stop: &AtomicBool) -> Result<GatewayEnd, TransportError> {
    let run = spec.run.clone();
    let domain = run.domain.clone().ok_or_else(|| TransportError::Other("a gateway needs a host's domain".into()))?;
    let claim = run.claim()?;
    let out = serve(spec, &domain, stop);
    run.remove_all_resources();
    drop(claim);
    out
}

fn serve(
    spec: GatewaySpec,
    domain: &crate::transport::iox::Domain,
    stop: &AtomicBool,
) -> Result<GatewayEnd, TransportError> {
    let run = &spec.run;
    let services = IoxServices::create(run, &spec.topo, spec.spare)?;
    let zrun = ZenohRun::new(run.run_id).with_key(run.key);
    let session = open_session(&spec.listen, &spec.connect)?;
    let prefix = zrun.prefix();
    let mut pubs = Vec::new();
    for h in destinations(domain, &spec.topo) {
        pubs.push((h, Arc::new(publisher(&session, batch_key(&prefix, h, domain.here))?)));
    }
    let links: Vec<Arc<Publisher<'static>>> = pubs.iter().map(|(_, p)| Arc::clone(p)).collect();
    let control = subscriber(&session, zrun.control_key())?;
    let status = publisher(&session, zrun.status_key())?;
    let orchestrator_gone = Arc::new(AtomicBool::new(false));
    let flag = Arc::clone(&orchestrator_gone);
    let _watch = session
        .liveliness()
        .declare_subscriber(zrun.orchestrator_token())
        .history(true)
        .callback(move |s| {
            if s.kind() == SampleKind::Delete {
                flag.store(true, Ordering::SeqCst);
            }
        })
        .wait()
        .map_err(err("watch the orchestrator"))?;

    let counts = Arc::new(Counts::default());
    let quit = Arc::new(AtomicBool::new(false));
    let failure = Arc::new(std::sync::Mutex::new(None));
    let shared = || Shared {
        run: run.clone(),
        topo: spec.topo.clone(),
        quit: Arc::clone(&quit),
        counts: Arc::clone(&counts),
        failure: Arc::clone(&failure),
    };
    // The in side first: batches may arrive as soon as its subscriber is declared.
    let inbound = Arc::new(Inbound::open(shared())?);
    let _inbox = session
        .declare_subscriber(format!("{prefix}/g/{:x}/*", domain.here))
        .callback(move |sample| inbound.on_batch(&sample))
        .wait()
        .map_err(err("subscriber for batches"))?;
    let (tx, rx) = std::sync::mpsc::channel();
    let sh = shared();
    let out = std::thread::Builder::new()
        .name("gateway-out".into())
        .spawn(move || carry_out(sh, pubs, tx))
        .map_err(|e| TransportError::Other(format!("cannot start a gateway thread: {e}")))?;
    let opened =
        rx.recv().unwrap_or_else(|_| Err(TransportError::Other("the gateway's out thread ended at start".into())));
    let relayed = opened.and_then(|()| {
        mark_ready(run)?;
        relay(&services, &control, &status, &links, run, stop, &orchestrator_gone, &quit)
    });
    quit.store(true, Ordering::SeqCst);
    let _ = out.join();
    relayed?;
    let failure = failure.lock().unwrap_or_else(|p| p.into_inner()).take();
    let c = &counts;
    Ok(GatewayEnd {
        batches_out: c.batches_out.load(Ordering::Relaxed),
        messages_out: c.messages_out.load(Ordering::Relaxed),
        batches_in: c.batches_in.load(Ordering::Relaxed),
        messages_in: c.messages_in.load(Ordering::Relaxed),
        rejected_batches: c.rejected.load(Ordering::Relaxed),
        failure,
    })
}

/// The marker's path (see [`READY_MARKER`]).
pub fn ready_marker(run: &IoxRun) -> PathBuf {
    run.root_dir().join(READY_MARKER)
}

fn mark_ready(run: &IoxRun) -> Result<(), TransportError> {
    let path = ready_marker(run);
    std::fs::write(&path, b"").map_err(|e| TransportError::Other(format!("{}: {e}", path.display())))
}

/// Relay run control until told to stop, the orchestrator goes, or a data thread fails:
/// requests in from zenoh onto the domain's `control`, statuses out (held until every batch
/// publisher reaches its gateway).
#[allow(clippy::too_many_arguments)]
fn relay(
    services: &IoxServices,
    control: &::zenoh::pubsub::Subscriber<::zenoh::handlers::FifoChannelHandler<::zenoh::sample::Sample>>,
    status: &Publisher<'static>,
    links: &[Arc<Publisher<'static>>],
    run: &IoxRun,
    stop: &AtomicBool,
    orchestrator_gone: &AtomicBool,
    quit: &AtomicBool,
) -> Result<(), TransportError> {
    let mut held: Vec<Status> = Vec::new();
    let mut linked = false;
    let mut last_check = Instant::now() - Duration::from_secs(1);
    while !stop.load(Ordering::SeqCst) && !orchestrator_gone.load(Ordering::SeqCst) && !quit.load(Ordering::SeqCst) {
        match control.recv_timeout(Duration::from_millis(1)) {
            Ok(Some(sample)) => {
                let bytes = sample.payload().to_bytes();
                if bytes.len() == std::mem::size_of::<RunControl>() {
                    let c: RunControl = read_payload(&bytes);
                    let tag_ok = run.key.as_ref().is_none_or(|k| k.check_control(&c));
                    if c.version == SCHEMA_VERSION && c.run_id == run.run_id && tag_ok {
                        services.forward_control(&c)?;
                    }
                }
            }
            Ok(None) => {}
            Err(e) => return Err(TransportError::Other(format!("zenoh control: {e}"))),
        }
        services.poll_status(|s| held.push(*s))?;
        if !linked && last_check.elapsed() > Duration::from_millis(2) {
            last_check = Instant::now();
            linked = links.iter().all(|p| matched(p)) && matched(status);
        }
        if linked {
            for s in held.drain(..) {
                // Best effort, like every status.
                let _ = status.put(bytes_of(&s).to_vec()).wait();
            }
        }
    }
    Ok(())
}
