//! The settings both drivers run with, from a configured scenario or plain (tests, benchmarks).

use std::sync::Arc;
use std::sync::atomic::AtomicBool;
use std::time::{Duration, Instant};

use cohort_scenario::faults::FaultPlan;
use cohort_wire::auth::MacKey;

use super::wait::SpinPolicy;
use crate::record::RunDirs;

/// Settings shared by both drivers.
#[derive(Clone)]
pub struct DriveParams {
    pub run_id: u64,
    pub n_steps: u64,
    pub dt_s: f64,
    pub step_timeout: Duration,
    pub dirs: RunDirs,
    /// Set by SIGTERM (or by the reference run's supervisor): stop at the next wait.
    pub terminate: Arc<AtomicBool>,
    /// When the process started (for the start-up time in its report).
    pub process_start: Instant,
    /// How a wait spins (draining and yielding the CPU) before it blocks on the event; see [`spin_budget`].
    pub spin: SpinPolicy,
    /// 1: agents advance with their neighbours' shares of the previous step (`run.link_delay_steps`).
    pub link_delay_steps: u32,
    /// `run.realtime_rate`: the plant paces steps by the wall clock.
    pub realtime_rate: Option<f64>,
    /// The run's fault plan (empty: none), shared by every process.
    pub faults: Arc<FaultPlan>,
    /// `run.on_agent_loss = "degrade"`: a dead or silent agent is dropped from the roster and
    /// the run goes on; otherwise it ends the run.
    pub degrade: bool,
    /// `run.checkpoint_every_steps` (0: none).
    pub checkpoint_every: u64,
    /// `run.telemetry_every_steps` (≥ 1): see [`DriveParams::writes_row`].
    pub telemetry_every: u64,
    /// `run.telemetry`: the format of the telemetry files.
    pub telemetry: cohort_scenario::TelemetryFormat,
    /// The agent's algorithm kind (names checkpoints).
    pub algorithm_kind: String,
    /// How long a hold for the orchestrator (a process fault) may take, at most.
    pub hold_timeout: Duration,
    /// `run.authenticate`: the run's MAC key; every message sent is sealed with it and every
    /// message received must carry its tag.
    pub key: Option<MacKey>,
    /// Processes of the run (the plant and every agent): the telemetry writers share a memory
    /// budget for the rows they hold back ([`crate::parquet_out::defer_budget`]).
    pub processes: u32,
    /// `[links]` model `geometric` (None: ideal links): what the plant's link model needs.
    pub links: Option<Arc<crate::links::LinkSetup>>,
}

impl DriveParams {
    /// Plain settings for `n_steps` of `dt_s` with no faults (tests, benchmarks).
    pub fn basic(run_id: u64, n_steps: u64, dt_s: f64, step_timeout: Duration, dirs: RunDirs) -> Self {
        Self {
            run_id,
            n_steps,
            dt_s,
            step_timeout,
            dirs,
            terminate: Arc::new(AtomicBool::new(false)),
            process_start: Instant::now(),
            spin: SpinPolicy::Fixed(Duration::ZERO),
            link_delay_steps: 0,
            realtime_rate: None,
            faults: Arc::new(FaultPlan::default()),
            degrade: true,
            checkpoint_every: 0,
            telemetry_every: 1,
            telemetry: cohort_scenario::TelemetryFormat::default(),
            algorithm_kind: String::new(),
            hold_timeout: Duration::from_secs(60),
            key: None,
            processes: 1,
            links: None,
        }
    }

    /// The settings a configured scenario asks for.
    pub fn from_setup(
        setup: &crate::paper::Setup,
        run_id: u64,
        dirs: RunDirs,
        terminate: Arc<AtomicBool>,
        process_start: Instant,
    ) -> Self {
        let s = &setup.parsed;
        Self {
            run_id,
            n_steps: s.n_steps(),
            dt_s: s.scenario.dt_s,
            step_timeout: Duration::from_secs_f64(s.run.step_timeout_s),
            dirs,
            terminate,
            process_start,
            spin: spin_budget(&s.run),
            link_delay_steps: s.run.link_delay_steps,
            realtime_rate: s.run.realtime_rate,
            faults: Arc::new(FaultPlan::from_scenario(s)),
            degrade: s.run.on_agent_loss == cohort_scenario::OnAgentLoss::Degrade,
            checkpoint_every: s.run.checkpoint_every_steps,
            telemetry_every: s.run.telemetry_every_steps.max(1),
            telemetry: s.run.telemetry,
            algorithm_kind: setup.algorithm.kind().to_string(),
            hold_timeout: Duration::from_secs_f64(s.run.startup_timeout_s + 2.0 * s.run.step_timeout_s),
            key: None,
            processes: s.n_agents() + 1,
            links: s.links.is_geometric().then(|| Arc::new(crate::links::LinkSetup::from_scenario(s))),
        }
    }
}

/// Spin policy for `run.wait`.
pub fn spin_budget(run: &cohort_scenario::RunSettings) -> SpinPolicy {
    match run.wait {
        cohort_scenario::Wait::Event => SpinPolicy::Fixed(Duration::ZERO),
        cohort_scenario::Wait::Poll => SpinPolicy::Fixed(Duration::from_secs_f64(run.step_timeout_s)),
        cohort_scenario::Wait::Adaptive => match run.spin_us {
            Some(us) => SpinPolicy::Fixed(Duration::from_secs_f64(us * 1e-6)),
            None => SpinPolicy::Adaptive,
        },
    }
}

impl DriveParams {
    pub(super) fn t_s(&self, k: u64) -> f64 {
        // Sim time from the step index, never accumulated, so every process agrees exactly.
        k as f64 * self.dt_s
    }

    /// Whether step k gets a telemetry row: every `telemetry_every`-th step from 0, and the last.
    pub fn writes_row(&self, k: u64) -> bool {
        k.is_multiple_of(self.telemetry_every.max(1)) || k + 1 == self.n_steps
    }
}
