//! A host's gateway process (`orchestrator gateway`, started by the orchestrator on its own
//! machine and by each host daemon on its own, before the host's plant and agents) and its
//! supervision ([`Gateways`]). What a gateway does is `cohort_wire::transport::gateway`'s.
//!
//! Exit codes as a child's ([`cohort_runtime::exit`]): 0 when asked to stop (SIGTERM, the
//! orchestrator gone), 1 failed, 2 bad input, 3 another build.

mod kids;

use std::process::ExitCode;
use std::sync::Arc;
use std::sync::atomic::AtomicBool;

use cohort_runtime::exit::{BUILD_MISMATCH, FAILED, INVALID, OK};
use cohort_runtime::paper::Paper;
use cohort_scenario::faults::FaultPlan;
use cohort_wire::auth::MacKey;
use cohort_wire::transport::gateway::{self, GatewaySpec};
use cohort_wire::transport::iox::IoxRun;

pub(crate) use kids::Gateways;

/// `orchestrator gateway`'s arguments (the orchestrator and the daemons give them): a child's
/// (its `--step-timeout-s` unused: a gateway waits for no step) and the host it serves.
#[derive(clap::Args, Debug)]
pub struct GatewayArgs {
    #[command(flatten)]
    pub common: cohort_runtime::process::CommonArgs,
    /// This host's index in the run's placement (0: the orchestrator's machine, k: hosts[k-1]).
    #[arg(long)]
    pub host_index: u16,
}

/// The name of host k's gateway process (its log file, its daemon's process name).
pub fn proc_name(host: u16) -> String {
    format!("gateway-{host}")
}

/// The host index a gateway's process name carries.
pub fn host_of_name(name: &str) -> Option<u16> {
    name.strip_prefix("gateway-")?.parse().ok()
}

/// Wait until host `k`'s gateway of run `run_id` has made its domain's services (its ready
/// marker exists), or fail: `ended` gives the reason once the gateway has ended, and after
/// `timeout` it is reported not ready (the caller ends it).
pub(crate) fn wait_until_ready(
    run_id: u64,
    k: u16,
    timeout: std::time::Duration,
    mut ended: impl FnMut() -> Option<String>,
) -> Result<(), String> {
    let marker = gateway::ready_marker(&IoxRun::new(run_id).in_domain(Default::default(), k));
    let until = std::time::Instant::now() + timeout;
    while !marker.exists() {
        if let Some(why) = ended() {
            return Err(format!("{} ended before it was ready: {why}", proc_name(k)));
        }
        if std::time::Instant::now() > until {
            return Err(format!("{} was not ready within {:.0} s", proc_name(k), timeout.as_secs_f64()));
        }
        std::thread::sleep(std::time::Duration::from_millis(5));
    }
    Ok(())
}

/// Run one gateway to its end (see the module docs for the exit codes).
pub fn main(args: GatewayArgs, papers: &[&'static dyn Paper]) -> ExitCode {
    cohort_runtime::process::die_with_parent();
    cohort_runtime::logging::init_child(&proc_name(args.host_index));
    match start(&args, papers) {
        Ok(spec) => {
            let stop = Arc::new(AtomicBool::new(false));
            for signal in [signal_hook::consts::SIGTERM, signal_hook::consts::SIGHUP, signal_hook::consts::SIGINT] {
                if let Err(e) = signal_hook::flag::register(signal, Arc::clone(&stop)) {
                    tracing::error!("cannot install the handler of signal {signal}: {e}");
                    return ExitCode::from(FAILED);
                }
            }
            match gateway::run(spec, &stop) {
                Ok(end) => {
                    let line = format!(
                        "out: {} messages in {} batches; in: {} messages in {} batches; {} batches refused",
                        end.messages_out, end.batches_out, end.messages_in, end.batches_in, end.rejected_batches
                    );
                    match end.failure {
                        None => {
                            tracing::info!("done: {line}");
                            ExitCode::from(OK)
                        }
                        Some(f) => {
                            tracing::error!("{f} ({line})");
                            ExitCode::from(FAILED)
                        }
                    }
                }
                Err(e) => {
                    tracing::error!("{e}");
                    ExitCode::from(FAILED)
                }
            }
        }
        Err((code, e)) => {
            tracing::error!("{e}");
            ExitCode::from(code)
        }
    }
}

/// From the arguments to a gateway's specification: the handshake checks, the scenario, the key.
fn start(g: &GatewayArgs, papers: &[&'static dyn Paper]) -> Result<GatewaySpec, (u8, String)> {
    let args = &g.common;
    if args.build_id != cohort_wire::build_id() {
        return Err((
            BUILD_MISMATCH,
            format!(
                "refusing to run: built from {} but the orchestrator is {} — rebuild the workspace",
                cohort_wire::build_id(),
                args.build_id
            ),
        ));
    }
    let run_id = u64::from_str_radix(&args.run_id, 16)
        .map_err(|_| (INVALID, format!("--run-id {:?}: not a hexadecimal run id", args.run_id)))?;
    cohort_runtime::paper::skip_deep_checks();
    let s = cohort_runtime::paper::load_run(
        &cohort_runtime::record::RunDirs::new(&args.run_dir),
        &Default::default(),
        papers,
    )
    .map_err(|e| (INVALID, e.to_string()))?;
    let placement = s.placement();
    if !placement.hosts().contains(&g.host_index) {
        return Err((INVALID, format!("--host-index {}: no process of the run is placed there", g.host_index)));
    }
    let key = match (args.key_fd, s.run.authenticate) {
        (Some(fd), _) => Some(
            MacKey::read_from_fd(fd)
                .map_err(|e| (INVALID, format!("--key-fd {fd}: cannot read the run's key: {e}")))?,
        ),
        (None, true) => return Err((INVALID, "run.authenticate is on but no --key-fd was given".into())),
        (None, false) => None,
    };
    let spare = FaultPlan::from_scenario(&s).faults.iter().filter(|f| f.spec.kind == "restart").count();
    Ok(GatewaySpec {
        run: IoxRun::new(run_id).with_key(key).in_domain(Arc::new(placement), g.host_index),
        topo: s.topology(),
        spare,
        connect: args.zenoh_connect.clone(),
        listen: args.zenoh_listen.clone(),
    })
}

#[cfg(test)]
mod tests {
    #[test]
    fn gateway_names_carry_their_host() {
        assert_eq!(super::proc_name(3), "gateway-3");
        assert_eq!(super::host_of_name("gateway-3"), Some(3));
        assert_eq!(super::host_of_name("agent-3"), None);
        assert_eq!(super::host_of_name("gateway-x"), None);
    }
}
