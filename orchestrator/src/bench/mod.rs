//! `orchestrator bench`: what the multi-process run costs, measured in one invocation with
//! interleaved repetitions (the machine is shared and noisy: medians, min–max, and ratios taken
//! within the same invocation). Writes `results.json` and `results.md` to `--out`, by default
//! `bench/` for a whole run and `target/bench-partial/` for a quick or `--only` one.
//!
//! Cases: each paper's headline scenario (`PaperHost::bench_scenarios`, e.g. the Lb-DNN
//! servicing case, 360 s) multi-process vs in-process reference; the consensus ring at
//! N = 6, 20, 50, 100 agent processes with each waiting strategy (event, poll+yield, adaptive),
//! with a one-step link delay, and as a null round (same processes and message sizes, no
//! computation); the UDP-loopback transport at N = 6 and 50; N = 100 over 10 000 steps (the
//! no-stall target); agents idling behind a plant paced at 10 Hz (their CPU share); the N = 6 ring
//! with two busy-loop hogs the bench starts and stops itself ("loaded": `event` against the
//! default, goal ≤ 1.2× the time of `event`); the cost of `run.authenticate` (the N = 6 ring
//! with it, and ns to seal and check one share); and zenoh (issue 20): the round trip between two
//! processes, and steps/s of the headline (shortened to 2 000 steps) and the ring at N = 6 and 20
//! over zenoh against iceoryx2 on one host, and over zenoh across the four-namespace network lab
//! ([`cohort_supervisor::netlab`], when this runs as root) with no delay and with 1 ms each way, each
//! reported as steps/s × round trip (1.0: one round trip per step). The lab's links are veth pairs
//! delayed by the kernel's netem where the kernel has it, else TAP pairs with the user-space pump
//! of [`cohort_supervisor::linkemu`] (the rows say which); with the pump, the bench also measures
//! the round trip across a veth lab, so the pump's own latency can be read off. And `orchestrator
//! campaign`'s cases per second on fig1 with 1 and 2 workers, in-process and as processes. And
//! after the cases, at every N of the idle ring and scale rows, the machine's wake floor
//! ([`floor`]: the ring's wake graph among as many processes doing nothing else), so that what
//! the ring reaches is read against what this machine allows.
//!
//! The module's parts: `types` (a case, a sample, an aggregate), `ring` (the consensus ring
//! as scenario text), `cases` (every case), one module per kind of row that needs more than a
//! ring (`zenoh`, `loaded`, `mac`, `python`, `live`), `floor` (the wake floor), `sample` (what a run measured),
//! `run` (the campaign: choose, run interleaved, aggregate, write) and `report` (the
//! Markdown of the rows every bench has).

mod campaign;
mod cases;
mod floor;
mod live;
mod loaded;
mod mac;
mod python;
mod report;
mod ring;
pub(crate) use ring::{RING, ring_text};
mod run;
mod sample;
mod types;
mod zenoh;

pub use run::run;

use std::path::PathBuf;

/// Where the bench writes without `--out`: the committed tables (`bench/`) only for a whole run;
/// a quick or `--only` run's partial tables go under `target/`, where they replace nothing kept.
pub fn default_out(quick: bool, only: Option<&str>) -> PathBuf {
    if quick || only.is_some() { PathBuf::from("target/bench-partial") } else { PathBuf::from("bench") }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn only_a_whole_run_writes_the_committed_tables_by_default() {
        assert_eq!(default_out(false, None), PathBuf::from("bench"));
        for (quick, only) in [(true, None), (false, Some("ring/")), (true, Some("scale/N=1000"))] {
            let out = default_out(quick, only);
            assert!(out.starts_with("target"), "--quick {quick}, --only {only:?}: {}", out.display());
        }
    }
}
