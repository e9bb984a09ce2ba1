//! `campaign FILE --hosts HOSTS`: the cases go to the host daemons of a hosts file, each running
//! as many at once as its `--workers`, in-process there as here, so the rows (and the table) are
//! the one-machine campaign's. A host lost mid-campaign gives its unanswered cases to the others
//! ([`cohort_supervisor::farm`]).

use std::path::Path;

use cohort_host::CommandError;
use cohort_scenario::HostSpec;
use cohort_scenario::hosts::HostsFile;
use cohort_supervisor::farm::{CaseRequest, Farm, FarmCaseError};
use cohort_supervisor::supervise::SIGNALLED;

use cohort_runtime::record::write_atomic;

use super::CaseError;
use super::plan::Plan;
use super::row::Outcome;
use super::serve::Done;

/// The campaign's farm and what every request of it carries.
pub struct Hosts {
    pub farm: Farm,
    campaign_id: u64,
    /// The scenario file, absolute (the daemons resolve its relative paths against it).
    file: String,
}

impl Hosts {
    /// Read the hosts file (names and endpoints only: a campaign places cases, not processes)
    /// and open the farm (every daemon reachable, named, this build).
    pub fn open(
        hosts_file: &Path,
        plan: &Plan,
        security: &crate::security_args::SecurityArgs,
    ) -> Result<Self, CommandError> {
        security.install().map_err(|e| CommandError::invalid(e.to_string()))?;
        let h = HostsFile::load(hosts_file).map_err(|e| CommandError::invalid(e.to_string()))?;
        if let Some((k, _)) = h.hosts.iter().enumerate().find(|(_, e)| e.plant || !e.agents.is_empty()) {
            return Err(CommandError::invalid(format!(
                "{}: hosts[{k}]: a campaign sends whole cases to each host (every process of a case runs \
                 there, in-process); remove `plant` and `agents`",
                hosts_file.display()
            )));
        }
        let specs: Vec<HostSpec> =
            h.hosts.iter().map(|e| HostSpec { name: e.name.clone(), endpoint: e.endpoint.clone() }).collect();
        let farm = Farm::open(&specs).map_err(|e| {
            let code = cohort_runtime::exit::ToExitCode::exit_code(&e);
            let what = format!("{}: {e}", hosts_file.display());
            if code == cohort_runtime::exit::INVALID { CommandError::invalid(what) } else { CommandError::failed(what) }
        })?;
        let file = std::path::absolute(&plan.file)
            .map_err(|e| CommandError::invalid(format!("{}: {e}", plan.file.display())))?;
        Ok(Self { farm, campaign_id: crate::launcher::new_run_id(), file: file.display().to_string() })
    }
}

/// Case `i` on a host: its drawn values, outcome and the host that ran it. The case's directory
/// here gets its resolved scenario and the run's summary, as a local case's.
pub fn run_case(
    hosts: &Hosts,
    plan: &Plan,
    i: u64,
    dir: &Path,
) -> Result<(Vec<toml::Value>, Outcome, String), CaseError> {
    let (values, scenario_text, setup) = plan.case_and_text(i).map_err(CaseError::Invalid)?;
    let io = |what: &str, e: &dyn std::fmt::Display| CaseError::Io(format!("{}: {e}", dir.join(what).display()));
    let resolved = setup.to_toml().map_err(|e| io("scenario.toml", &e))?;
    let _ = std::fs::remove_dir_all(dir);
    std::fs::create_dir_all(dir).map_err(|e| io("", &e))?;
    write_atomic(&dir.join("scenario.toml"), resolved.as_bytes()).map_err(|e| io("scenario.toml", &e))?;
    let req = CaseRequest {
        build_id: cohort_wire::build_id().into(),
        campaign_id: hosts.campaign_id,
        case: i,
        file: hosts.file.clone(),
        scenario_text,
        duration_s: plan.overrides.duration_s,
    };
    let stop = || SIGNALLED.load(std::sync::atomic::Ordering::SeqCst) != 0;
    match hosts.farm.run(&req, &stop) {
        Ok((v, host)) => {
            let done: Done = serde_json::from_value(v)
                .map_err(|e| CaseError::Io(format!("case {i}: host {host} sent an outcome that is not one: {e}")))?;
            if let Some(text) = done.summary {
                write_atomic(&dir.join("summary.json"), text.as_bytes()).map_err(|e| io("summary.json", &e))?;
            }
            Ok((values, done.outcome, host))
        }
        Err(FarmCaseError::Interrupted) => Err(CaseError::Interrupted),
        Err(e) => Err(CaseError::Io(e.to_string())),
    }
}
