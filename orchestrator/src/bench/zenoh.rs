//! The zenoh rows (issue 20): their cases (on one host and across the namespace lab), the round
//! trips they are read against (one host, the lab without and with delay, a veth lab for the
//! pump's own latency) and their Markdown section.

use std::fmt::Write as _;
use std::path::Path;
use std::time::Duration;

use cohort_runtime::paper::Setup;
use cohort_scenario::Overrides;
use cohort_supervisor::netlab::{Lab, Links, NAMES};
use serde::Serialize;

use super::report::f0;
use super::ring::{RING, RingRun, ring};
use super::types::{Aggregate, Case};

/// The lab's "1 ms" rows: every namespace delays what it sends by 1 ms.
const DELAY_1MS: Duration = Duration::from_millis(1);

/// Loads a zenoh-row scenario: (transport, zenoh links, hosts file) → the setup.
type LoadFn = dyn Fn(&str, &str, Option<&Path>) -> Result<Setup, String>;

/// The zenoh rows: the headline shortened to 2 000 steps and the ring at N = 6 and 20, over
/// iceoryx2 and zenoh on one host, and over zenoh across the lab (when there is one), without and
/// with 1 ms delay.
pub(super) fn zenoh_cases(
    quick: bool,
    repo: &Path,
    lab_dir: Option<&Path>,
    only: Option<&str>,
) -> Result<Vec<Case>, String> {
    let steps: u64 = if quick { 500 } else { 2000 };
    let mut out = Vec::new();
    let mut push = |label: String, n: u32, variant: &str, scenario: Setup, lab: Option<Duration>| {
        let key = format!("zenoh/{label}/N={n}/{variant}");
        out.push(Case {
            key,
            group: "zenoh",
            n,
            variant: variant.into(),
            label,
            scenario,
            reference: false,
            hogs: false,
            lab,
            live: None,
        });
    };
    // (label, N, the lab hosts its agents are dealt to, loader).
    let mut sets: Vec<(String, u32, usize, Box<LoadFn>)> = Vec::new();
    // Quick (a smoke run): the 6-agent ring only.
    let headlines =
        if quick { Vec::new() } else { cohort_registry::HOSTS.iter().flat_map(|h| h.bench_scenarios()).collect() };
    for file in headlines {
        let path = repo.join(file);
        let probe = crate::load(&path, &Overrides::default()).map_err(|e| e.to_string())?;
        let duration = steps as f64 * probe.scenario.dt_s;
        let load = move |transport: &str, links: &str, hosts: Option<&Path>| {
            let hosts = hosts.map(cohort_scenario::hosts::HostsFile::load).transpose().map_err(|e| e.to_string())?;
            let o = Overrides {
                duration_s: Some(duration),
                transport: Some(transport.into()),
                zenoh_links: (transport == "zenoh").then(|| links.to_string()),
                hosts,
                ..Default::default()
            };
            crate::load(&path, &o).map_err(|e| e.to_string())
        };
        // The headline's servicers on b and c, its plant on a (the placement).
        sets.push((probe.scenario.name.clone(), probe.n_agents(), HEADLINE_AGENT_HOSTS, Box::new(load)));
    }
    for n in if quick { &[6u32][..] } else { &[6u32, 20][..] } {
        let n = *n;
        let load = move |transport: &str, links: &str, hosts: Option<&Path>| {
            let transport: &'static str = if transport == "zenoh" { "zenoh" } else { "iceoryx2" };
            ring(n, steps, RingRun { transport, zenoh_links: links, hosts, ..RING })
        };
        sets.push(("ring".into(), n, RING_AGENT_HOSTS, Box::new(load)));
    }
    for (label, n, spread, load) in &sets {
        push(label.clone(), *n, "iceoryx2", load("iceoryx2", "gateway", None)?, None);
        let hosts = lab_dir.map(|dir| Lab::hosts_file(dir, *n, *spread)).transpose().map_err(|e| e.to_string())?;
        // Each zenoh row through the hosts' gateways (the default), then with every process a peer.
        for (links, suffix) in [("gateway", ""), ("peers", "-peers")] {
            push(label.clone(), *n, &format!("zenoh{suffix}"), load("zenoh", links, None)?, None);
            let Some(hosts) = &hosts else { continue };
            for (delayed, delay) in [(false, Duration::ZERO), (true, DELAY_1MS)] {
                let variant = format!("{}{suffix}", lab_variant(*spread, delayed));
                push(label.clone(), *n, &variant, load("zenoh", links, Some(hosts))?, Some(delay));
            }
        }
    }
    // A thousand agent processes across the lab's four namespaces through the gateways, 200 steps:
    // minutes on two cores, so only when asked for by name (`--only zenoh/ring/N=1000`).
    if let Some(dir) = lab_dir.filter(|_| only.is_some_and(|o| o.starts_with("zenoh/ring/N=1000"))) {
        let hosts = Lab::hosts_file(dir, 1000, RING_AGENT_HOSTS).map_err(|e| e.to_string())?;
        let s = ring(1000, 200, RingRun { transport: "zenoh", hosts: Some(&hosts), ..RING })?;
        push("ring".into(), 1000, &lab_variant(RING_AGENT_HOSTS, false), s, Some(Duration::ZERO));
    }
    Ok(out)
}

/// The lab hosts a headline's agents go to (b, c) and a ring's (b, c, d).
const HEADLINE_AGENT_HOSTS: usize = 2;
const RING_AGENT_HOSTS: usize = 3;

/// A lab row's variant: `zenoh-<namespaces used>ns`, `-1ms` when delayed (fig1 `zenoh-3ns`,
/// a ring `zenoh-4ns`).
fn lab_variant(agent_hosts: usize, delayed: bool) -> String {
    format!("zenoh-{}ns{}", agent_hosts + 1, if delayed { "-1ms" } else { "" })
}

/// A lab row's namespaces and whether it is delayed, from its variant (`zenoh-4ns-1ms-peers` →
/// (4, true)); none for a row outside the lab.
fn lab_row(variant: &str) -> Option<(usize, bool)> {
    let v = variant.strip_suffix("-peers").unwrap_or(variant).strip_prefix("zenoh-")?;
    let (v, delayed) = v.strip_suffix("-1ms").map_or((v, false), |v| (v, true));
    Some((v.strip_suffix("ns")?.parse().ok()?, delayed))
}

/// The round trip a row is read against: `zenoh` (one host), `lab` or `lab-1ms` (see
/// [`lab_rtts`]); a peers row goes with its gateway row's.
fn rtt_place(variant: &str) -> &str {
    match lab_row(variant) {
        Some((_, false)) => "lab",
        Some((_, true)) => "lab-1ms",
        None => variant.strip_suffix("-peers").unwrap_or(variant),
    }
}

/// Where a lab row's processes ran: "plant on a, agents on b and c", or "a / b / c" when delayed.
fn lab_placement(namespaces: usize, delayed: bool) -> String {
    let used = &NAMES[..namespaces.clamp(2, NAMES.len())];
    if delayed {
        return used.join(" / ");
    }
    let agents = match used[1..].split_last() {
        Some((last, [])) => last.to_string(),
        Some((last, rest)) => format!("{} and {last}", rest.join(", ")),
        None => String::new(),
    };
    format!("plant on a, agents on {agents}")
}

/// Round trips measured in this bench run: (where, p50 µs, p99 µs).
#[derive(Debug, Clone, Serialize)]
pub(super) struct Rtt {
    place: String,
    /// The rows this round trip goes with (see [`rtt_place`]: `zenoh`, `lab`, `lab-1ms`; none: a
    /// reference row).
    variant: Option<&'static str>,
    p50_us: f64,
    p99_us: f64,
    max_ms: f64,
}

/// The zenoh round trip between an echo process and a ping process, on one host or from lab
/// namespace a to b.
pub(super) fn measure_rtt(lab: Option<&Lab>, place: &str, variant: Option<&'static str>) -> Result<Rtt, String> {
    use std::process::Stdio;
    let me = std::env::current_exe().map_err(|e| e.to_string())?;
    let (listen, connect) = match lab {
        Some(_) => {
            let e = Lab::endpoint(1).replace(":7447", ":7500");
            (e.clone(), e)
        }
        None => {
            let port = std::net::TcpListener::bind("127.0.0.1:0")
                .and_then(|l| l.local_addr())
                .map_err(|e| e.to_string())?
                .port();
            (format!("tcp/127.0.0.1:{port}"), format!("tcp/127.0.0.1:{port}"))
        }
    };
    let cmd = |x: &str| match lab {
        Some(l) => l.command(x, &me),
        None => std::process::Command::new(&me),
    };
    let mut echo = cmd("b")
        .args(["zenoh-echo", "--listen", &listen])
        .stdin(Stdio::null())
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .spawn()
        .map_err(|e| format!("zenoh-echo: {e}"))?;
    std::thread::sleep(std::time::Duration::from_millis(300));
    let out = cmd("a").args(["zenoh-ping", "--connect", &connect]).output();
    // SAFETY: kill(2) on the echo this bench started.
    unsafe { libc::kill(echo.id() as libc::pid_t, libc::SIGKILL) };
    let _ = echo.wait();
    let out = out.map_err(|e| format!("zenoh-ping: {e}"))?;
    if !out.status.success() {
        return Err(format!("zenoh-ping ({place}): {}", String::from_utf8_lossy(&out.stderr).trim()));
    }
    let v: serde_json::Value = serde_json::from_slice(&out.stdout).map_err(|e| format!("zenoh-ping output: {e}"))?;
    let f = |k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    Ok(Rtt { place: place.into(), variant, p50_us: f("p50_us"), p99_us: f("p99_us"), max_ms: f("max_ms") })
}

/// The namespace lab (`None`: none can be made here, e.g. not root), with veth links where the
/// kernel has netem and pumped links where it has not. With pumped links, first the round trip
/// a → b across a veth lab made and removed for it (the two labs share names and addresses, so
/// one at a time): the pump's own latency is the difference from the pumped lab's undelayed row.
pub(super) fn start_lab() -> (Option<Lab>, Option<Rtt>) {
    let links = match cohort_supervisor::netlab::netem_probe() {
        Ok(()) => Links::Veth,
        Err(e) => {
            tracing::info!("no netem on this kernel ({e}): the lab's links are TAP pairs with a user-space pump");
            Links::Pumped
        }
    };
    let veth_rtt = (links == Links::Pumped)
        .then(|| {
            let veth = Lab::start_with(Links::Veth).map_err(|e| e.to_string())?;
            measure_rtt(Some(&veth), "namespace a → b across veth (no pump, no delay)", None)
        })
        .transpose()
        .unwrap_or_else(|e| {
            tracing::warn!("no veth lab for the pump's own latency: {e}");
            None
        });
    match Lab::start_with(links) {
        Ok(l) => (Some(l), veth_rtt),
        Err(e) => {
            tracing::warn!("no network-namespace lab (zenoh across namespaces not measured): {e}");
            (None, None)
        }
    }
}

/// The round trip from namespace a to b in the lab, without and with the 1 ms delay (places
/// `lab`, `lab-1ms`: every lab row, whichever namespaces it uses, is read against them).
pub(super) fn lab_rtts(l: &Lab) -> Result<Vec<Rtt>, String> {
    let how = l.links().describe();
    let plain = measure_rtt(Some(l), &format!("namespace a → b ({how}, no delay)"), Some("lab"))?;
    l.set_delay(DELAY_1MS).map_err(|e| e.to_string())?;
    let delayed = measure_rtt(Some(l), &format!("namespace a → b, 1 ms each way ({how})"), Some("lab-1ms"));
    l.set_delay(Duration::ZERO).map_err(|e| e.to_string())?;
    Ok(vec![plain, delayed?])
}

/// The zenoh rows: steps/s and steps/s × the round trip of the same place; `links`: the lab's.
pub(super) fn zenoh_markdown(a: &[Aggregate], rtts: &[Rtt], links: Option<Links>) -> String {
    let mut md = String::from(
        "\n## zenoh (multi-host transport)\n\nRound trip between two processes (256 B, 5 000 pings after 200 warm-up):\n\n| where | p50 µs | p99 µs | max ms |\n|---|---|---|---|\n",
    );
    for r in rtts {
        let _ = writeln!(md, "| {} | {:.0} | {:.0} | {:.2} |", r.place, r.p50_us, r.p99_us, r.max_ms);
    }
    // A peers row goes with the round trip of its place, as its gateway row does.
    let rtt_of = |variant: &str| {
        let place = rtt_place(variant);
        rtts.iter().find(|r| r.variant == Some(place)).map(|r| r.p50_us)
    };
    if let (Some(veth), Some(pumped), Some(Links::Pumped)) =
        (rtts.iter().find(|r| r.variant.is_none()), rtt_of("zenoh-3ns"), links)
    {
        let _ = writeln!(
            md,
            "\nThe pump's own latency: {:.0} µs per round trip at p50 (pumped links with no delay against veth; a round \
             trip a → b → a passes four pumps).",
            pumped - veth.p50_us
        );
    }
    md.push_str(
        "\nThe step's legs: a measurement's latency from the plant's send to an agent's receipt, and that of the \
         last share the plant waited for in a step (medians; the lockstep's path is one of each, against one \
         round trip).\n\n| case | N | transport, placement | steps/s | RTT p50 µs | steps/s × RTT | plant → agent µs | \
         last share → plant µs |\n|---|---|---|---|---|---|---|---|\n",
    );
    let how = links.map_or("", Links::describe);
    for x in a.iter().filter(|x| x.group == "zenoh") {
        let (variant, links) = match x.variant.strip_suffix("-peers") {
            Some(v) => (v, "every process a zenoh peer"),
            None => (x.variant.as_str(), "through the hosts' gateways"),
        };
        let place = match variant {
            "iceoryx2" => "iceoryx2, one host".to_string(),
            "zenoh" => format!("zenoh, one host (TCP loopback), {links}"),
            other => match lab_row(other) {
                Some((k, false)) => format!("zenoh, {} ({how}, no delay), {links}", lab_placement(k, false)),
                Some((k, true)) => format!("zenoh, {}, 1 ms each way ({how}), {links}", lab_placement(k, true)),
                None => other.to_string(),
            },
        };
        let rtt = rtt_of(&x.variant);
        let ratio = rtt.map_or("–".to_string(), |r| format!("{:.2}", x.steps_per_s_median * r * 1e-6));
        let us = |v: Option<f64>| v.map_or("–".to_string(), |v| format!("{v:.0}"));
        let _ = writeln!(
            md,
            "| {} | {} | {place} | {} [{}–{}] | {} | {ratio} | {} | {} |",
            x.label,
            x.n,
            f0(x.steps_per_s_median),
            f0(x.steps_per_s_min),
            f0(x.steps_per_s_max),
            us(rtt),
            us(x.median_of(|s| s.meas_latency_us)),
            us(x.median_of(|s| s.share_latency_max_us)),
        );
    }
    md
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_lab_row_and_its_peers_row_is_read_against_the_lab_round_trip() {
        assert_eq!(lab_variant(2, false), "zenoh-3ns");
        assert_eq!(lab_variant(3, true), "zenoh-4ns-1ms");
        for (variant, place) in [
            ("zenoh-3ns", "lab"),
            ("zenoh-4ns-peers", "lab"),
            ("zenoh-3ns-1ms", "lab-1ms"),
            ("zenoh-4ns-1ms-peers", "lab-1ms"),
            ("zenoh", "zenoh"),
            ("zenoh-peers", "zenoh"),
            ("iceoryx2", "iceoryx2"),
        ] {
            assert_eq!(rtt_place(variant), place, "{variant}");
        }
        assert_eq!(lab_placement(3, false), "plant on a, agents on b and c");
        assert_eq!(lab_placement(4, false), "plant on a, agents on b, c and d");
        assert_eq!(lab_placement(4, true), "a / b / c / d");
    }
}
