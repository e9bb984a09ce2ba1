//! The two traits every paper method and every plant model implements. They never see the
//! transport: a driver feeds them, so each is testable in a unit test with no processes.

use rand_chacha::ChaCha8Rng;

/// The truth of every body, the sensors, and the commands' effect. Advanced by the plant driver.
pub trait PlantModel: Send {
    /// Telemetry columns after `k,t_s` (units in the names).
    fn columns(&self) -> Vec<String>;
    /// Agent `agent`'s sensor readings at the current time (noise drawn from `rng`, in agent
    /// order, so the sequence is the same in every run mode).
    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>);
    /// The command agent `agent` sent for the current step, held over it (zero-order hold).
    /// Missing entries (an empty command: an agent dead before it ever sent one) mean zero.
    fn apply_command(&mut self, agent: u32, command: &[f64]);
    /// Integrate the truth by `dt_s` with the commands held.
    fn advance(&mut self, dt_s: f64);
    /// Each agent's spacecraft position now, m, in agent order, in a frame whose origin is the
    /// centre of the body that can occult the inter-satellite links (`[links]` model
    /// `geometric`). False: this plant has no positions (attitude only), so only ideal links.
    fn positions_m(&self, _out: &mut Vec<[f64; 3]>) -> bool {
        false
    }
    /// Telemetry values at the current time, matching [`PlantModel::columns`].
    fn row(&self, out: &mut Vec<f64>);
    /// Headline metrics for `summary.json`, computed at the end of the run.
    fn metrics(&self) -> Vec<(String, f64)>;
    /// Sim-time outputs kept apart from the per-step rows, as (file name, text), written to the
    /// run's `snapshots/` when the run ends (also after an error): e.g. every node of a net at a
    /// few times, far too wide for a row of every step. Deterministic like the rows.
    fn extra_telemetry(&self) -> Vec<(String, String)> {
        Vec::new()
    }
    /// An error the model hit in one of the calls since the last time the driver asked (a user's
    /// Python method raised, or returned the wrong thing), in words naming the method and what
    /// went wrong; the driver then fails the run at this step, naming it. A model that cannot fail
    /// (every Rust one) keeps the default.
    fn take_failure(&mut self) -> Option<String> {
        None
    }
}

/// What an agent's algorithm gets from its own sensors at step k.
#[derive(Debug, Clone, Copy)]
pub struct AgentInput<'a> {
    pub k: u64,
    pub t_s: f64,
    pub readings: &'a [f64],
}

/// What the agent owes at step k: the command the plant applies, and the values its neighbours
/// read.
#[derive(Debug, Clone, Default)]
pub struct ShareOut {
    pub command: Vec<f64>,
    pub values: Vec<f64>,
}

/// One live neighbour's newest share this agent has: of step k on ideal links, or older.
#[derive(Debug, Clone, Copy)]
pub struct Neighbour<'a> {
    pub id: u32,
    pub values: &'a [f64],
    /// Steps since the neighbour sent it: 0 on ideal links; more when a link delays or loses
    /// shares (`run.link_delay_steps`, delay and drop faults, `[links]` model `geometric`), in
    /// which case the newest share delivered is held. Every shipped algorithm uses the share it
    /// is given whatever its age (a zero-order hold of the neighbour's values); one that needs
    /// fresh shares reads this.
    pub age_steps: u64,
}

/// One spacecraft's estimator, controller and learner. The step protocol calls `share` when the
/// measurement of step k arrives, then `step` once every neighbour's share of step k is in.
pub trait Algorithm: Send {
    fn columns(&self) -> Vec<String>;
    /// Compute what this agent owes the others at tₖ from its state and the measurement.
    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut);
    /// Advance internal states from tₖ to tₖ₊₁, the neighbours' values held over the step.
    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]);
    /// Telemetry values matching [`Algorithm::columns`], taken right after `share` (state at tₖ
    /// and the command of step k).
    fn row(&self, out: &mut Vec<f64>);
    /// Which of the configured neighbours (in the scenario's order) are on the roster from this
    /// step on; called before `share` whenever that changes (and once at the start). A dead
    /// neighbour's shares stop coming by themselves; this is for what the algorithm gets about
    /// its neighbours from elsewhere (seed 000: relative measurements in the readings).
    fn roster(&mut self, _live: &[bool]) {}
    /// The algorithm's full state as bytes (for checkpoints; see `checkpoint.rs`). Restoring
    /// them into an algorithm built from the same scenario must give back the same state exactly.
    fn save_state(&self) -> Vec<u8>;
    /// Replace the state with one saved by [`Algorithm::save_state`]; on error nothing changed.
    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError>;
    /// For an algorithm that solves an optimisation problem every step: its solver's counts and
    /// wall-clock solve times, for the end-of-run report (never telemetry: times differ between
    /// runs). None for the others.
    fn solver_stats(&self) -> Option<crate::solver_stats::SolverStats> {
        None
    }
    /// An error the algorithm hit since the driver last asked (see [`PlantModel::take_failure`]);
    /// its outputs of that call are then not used.
    fn take_failure(&mut self) -> Option<String> {
        None
    }
}

/// Why saved bytes cannot be restored into an algorithm ([`Algorithm::restore_state`]).
#[derive(Debug, thiserror::Error)]
pub enum RestoreStateError {
    /// The bytes are not a state of this algorithm's type.
    #[error(transparent)]
    Decode(#[from] crate::checkpoint::DecodeStateError),
    /// The state decodes but does not fit this instance, or the algorithm's own restore failed;
    /// the reason names what.
    #[error("{0}")]
    Refused(String),
}

/// Implements the checkpoint methods of [`Algorithm`] for a type that is its own serde state.
#[macro_export]
macro_rules! serde_checkpoint {
    () => {
        fn save_state(&self) -> Vec<u8> {
            $crate::checkpoint::encode_state(self)
        }
        fn restore_state(&mut self, bytes: &[u8]) -> Result<(), $crate::model::RestoreStateError> {
            *self = $crate::checkpoint::decode_state(bytes)?;
            Ok(())
        }
    };
}
