//! The `live` rows: fig1-like headlines (those whose paper declares a 3-D scene) served live
//! (`--live`) with one client that reads every message, with one that subscribes and never reads,
//! and without `--live`, in the same bench run; the table gives steps/s and the ratio to "off"
//! (issue goal: within 5 %).

use cohort_report::markdown::{Align, MdTable};
use cohort_runtime::paper::Setup;

use super::report::f0;
use super::types::{Aggregate, Case};

/// The client of a `live` row.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) enum LiveClient {
    /// No `--live` at all (the row the others are compared with).
    Off,
    /// `--live` and one client that reads every message.
    Reader,
    /// `--live` and one client that subscribes and then never reads.
    Stalled,
}

/// The `live` rows' variants, by name.
const VARIANTS: [(&str, LiveClient); 3] =
    [("off", LiveClient::Off), ("one-client", LiveClient::Reader), ("stalled-client", LiveClient::Stalled)];

/// The live rows of a headline scenario `s` (none when its papers declare no scene).
pub(super) fn cases(name: &str, s: &Setup) -> Vec<Case> {
    if cohort_registry::hooks_of(s).iter().all(|(_, h)| h.scene(s).is_empty()) {
        return Vec::new();
    }
    let n = s.n_agents();
    VARIANTS
        .iter()
        .map(|&(variant, client)| Case {
            key: format!("live/N={n}/{variant}"),
            group: "live",
            n,
            variant: variant.into(),
            label: name.into(),
            scenario: s.clone(),
            reference: false,
            hogs: false,
            lab: None,
            live: Some(client),
        })
        .collect()
}

/// Before a run: the live server on (started on a free port at the first `live` row) with the
/// row's client connected, or off.
pub(super) fn clients(live: Option<LiveClient>) -> Result<Vec<crate::live::client::Client>, String> {
    let on = matches!(live, Some(LiveClient::Reader | LiveClient::Stalled));
    let server = match crate::live::started() {
        Some(s) => s,
        None if on => crate::live::start(crate::live::Options { addr: "127.0.0.1:0".into(), rate_hz: 20.0 })
            .map_err(|e| e.to_string())?,
        None => return Ok(Vec::new()),
    };
    server.set_enabled(on);
    let reads = match live {
        Some(LiveClient::Reader) => true,
        Some(LiveClient::Stalled) => false,
        _ => return Ok(Vec::new()),
    };
    Ok(vec![crate::live::client::Client::start(server.port(), reads)?])
}

/// The `live` rows: steps/s with `--live` and one client (reading, or never reading) against the
/// same scenario without `--live`, in the same bench run.
pub(super) fn markdown(a: &[Aggregate]) -> String {
    let rows: Vec<&Aggregate> = a.iter().filter(|x| x.group == "live").collect();
    let Some(off) = rows.iter().find(|x| x.variant == "off").copied() else { return String::new() };
    let mut t = (1..5)
        .fold(MdTable::new(["variant", "steps/s (median)", "min", "max", "vs off"]), |t, c| t.align(c, Align::Right));
    for r in rows {
        t.row([
            r.variant.clone(),
            f0(r.steps_per_s_median),
            f0(r.steps_per_s_min),
            f0(r.steps_per_s_max),
            format!("{:.3}", r.steps_per_s_median / off.steps_per_s_median),
        ]);
    }
    format!("\n## Live view (`launch --live`), {}\n\n{t}", off.label)
}
