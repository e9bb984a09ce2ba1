//! One spacecraft of the hand-off scenario: its flight agent ([`crate::flight::leader::Leader`] or
//! [`crate::flight::follower::Follower`]: MEKF, relative navigation and relative law) with the Sec. 8
//! supervisor of "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft
//! Formation" (arXiv:2509.13331) riding along ([`crate::automaton::lockstep::SupervisorAgent`]:
//! the follower is the master, the leader adopts the master's location one step later), and the
//! attitude law switched with the supervisor's location at every step:
//!
//! - s2 transient: the Lyapunov law (57) with (k₁, k₂) this spacecraft's transient predictor (the
//!   DNN) answered at its own entry to s2, from its MEKF estimate (δq = q̂ ⊗ q_f⁻¹, ω̂) and w; u2 =
//!   max(T̂_L, T̂_F) is the supervisor's rule (`u2_ticks`), as in the mission;
//! - s3 science: PD (54) or SMC (58)–(60) with the gains k̂ its [`SciencePredictor`] answered at its
//!   own entry to s3, from its MEKF estimate (δq, ω̂) and w: the science DNN of Sec. 3.2.2
//!   ([`crate::handoff::science::DnnScience`]; what it is given and where that departs from the print
//!   is in [`crate::handoff::science`]) or the configured gains ([`ConfiguredScience`]);
//! - every other location (s1 stabilisation here; s0, s4, s5, s6 if a longer run reached them):
//!   the stabilisation law of Sec. 2.11, a feed-forward that cancels the gravity-gradient torque
//!   (23) predicted from q̂ and this spacecraft's own orbit estimate r̂ (the leader's r̂_L; the
//!   follower's r̂_L + r̂_rel), J̄ and μ — no feedback, so the body drifts under the wheel noise
//!   and bias until the transient (the paper: ω grows to 0.59 rad/s over a 22.5 h stabilisation).
//!
//! Step k: the flight agent filters the readings and writes its shares; then the supervisor ticks
//! (fires or adopts, predicts at an entry), and the law the location prescribes computes the
//! torque from the estimate of t_k, replacing the flight agent's: one law acts per step, whichever
//! the location, and the telemetry says which (`law_*_on`), with the transient's (k₁, k₂, T̂) and
//! the science law's k̂, Ê, ê chosen at the latest entries (`transient_*`, `science_*`).
//!
//! Shares: the flight share (padded to [`SUPERVISOR_OFFSET`] values), then the supervisor share
//! ([`crate::automaton::share`]). The supervisor's clocks count steps (its tick is `dt_s`).

use std::sync::Arc;

use cohort_runtime::model::{AgentInput, Algorithm, Neighbour, RestoreStateError, ShareOut};
use nalgebra::Matrix3;
use serde::{Deserialize, Serialize};

use crate::automaton::lockstep::SupervisorAgent;
use crate::automaton::table::{S2, S3};
use crate::flight::acs::Acs;
use crate::flight::attitude_control::AttitudeLaw;
use crate::flight::follower::Follower;
use crate::flight::leader::Leader;
use crate::flight::share::{FOLLOWER_SHARE_LEN, LEADER_SHARE_LEN};
use crate::handoff::science::{self, ScienceChoice};
pub use crate::handoff::science::{ConfiguredScience, SciencePredictor};
use crate::learn::transient::gains::{MeasuredState, TransientPredictor};
use crate::model::attitude::gravity_gradient;
use crate::model::quaternion::{self, V3};

/// Where the supervisor's share starts in a hand-off agent's share values.
pub const SUPERVISOR_OFFSET: usize =
    if LEADER_SHARE_LEN > FOLLOWER_SHARE_LEN { LEADER_SHARE_LEN } else { FOLLOWER_SHARE_LEN };

/// The attitude law that computed a step's torque.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ActingLaw {
    Stabilisation,
    Transient,
    Science,
}

impl ActingLaw {
    /// The law a supervisor location prescribes.
    pub fn of_state(state: usize) -> Self {
        match state {
            S2 => ActingLaw::Transient,
            S3 => ActingLaw::Science,
            _ => ActingLaw::Stabilisation,
        }
    }
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum Flight {
    Leader(Leader),
    Follower(Follower),
}

impl Flight {
    fn acs(&mut self) -> &mut Acs {
        match self {
            Flight::Leader(l) => &mut l.acs,
            Flight::Follower(f) => &mut f.acs,
        }
    }

    fn acs_ref(&self) -> &Acs {
        match self {
            Flight::Leader(l) => &l.acs,
            Flight::Follower(f) => &f.acs,
        }
    }

    /// This spacecraft's own ECI position estimate, once it has one.
    fn r_hat_eci_m(&self) -> Option<V3> {
        match self {
            Flight::Leader(l) => l.rv_hat.map(|(r, _)| r),
            Flight::Follower(f) => f.nav.leader_rv.map(|(r, _)| r + f.nav.r_rel_m),
        }
    }

    fn algorithm(&mut self) -> &mut dyn Algorithm {
        match self {
            Flight::Leader(l) => l,
            Flight::Follower(f) => f,
        }
    }
}

/// What a hand-off agent checkpoints (everything but its predictors).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct HandoffState {
    pub flight: Flight,
    pub sup: SupervisorAgent,
    pub acting: ActingLaw,
    /// The science law (and its predicted Ê, ê) chosen at the latest entry to s3.
    pub science: Option<ScienceChoice>,
    pub mu_m3ps2: f64,
}

pub struct HandoffAgent {
    pub state: HandoffState,
    pub transient: Arc<dyn TransientPredictor>,
    pub science: Arc<dyn SciencePredictor>,
}

impl HandoffAgent {
    pub fn new(
        flight: Flight,
        sup: SupervisorAgent,
        mu_m3ps2: f64,
        transient: Arc<dyn TransientPredictor>,
        science: Arc<dyn SciencePredictor>,
    ) -> Self {
        let state = HandoffState { flight, sup, acting: ActingLaw::Stabilisation, science: None, mu_m3ps2 };
        Self { state, transient, science }
    }

    /// The estimate the predictors see: δq = q̂ ⊗ q_f⁻¹ (the DNN was trained with q_f = identity)
    /// and ω̂, after the measurement update of t_k.
    fn estimate(acs: &Acs) -> MeasuredState {
        let dq = quaternion::error(&acs.q_hat(), &acs.q_target_body_eci);
        let w = acs.omega_hat_rad_s();
        MeasuredState { q_body_eci: [dq[0], dq[1], dq[2], dq[3]], omega_body_rad_s: [w[0], w[1], w[2]] }
    }

    /// The stabilisation law: τ̂ = −τ̂_gg(q̂, r̂) (feed-forward only; zero before the orbit is known).
    fn stabilisation_torque(&self) -> V3 {
        let s = &self.state;
        let acs = s.flight.acs_ref();
        let Some(r) = s.flight.r_hat_eci_m().filter(|r| r.norm() > 0.0) else { return V3::zeros() };
        let j = Matrix3::from_diagonal(&V3::from(acs.model.inertia_kg_m2));
        -gravity_gradient(&acs.q_hat(), &r, &j, s.mu_m3ps2)
    }

    /// The torque of the law the current location prescribes; records which law acted.
    fn command(&mut self) -> V3 {
        let law = ActingLaw::of_state(self.state.sup.sup.state);
        let x = Self::estimate(self.state.flight.acs_ref());
        if law == ActingLaw::Science && self.state.acting != ActingLaw::Science {
            self.state.science = Some(self.science.science_law(&x));
        }
        let torque = match law {
            ActingLaw::Stabilisation => {
                let t = self.stabilisation_torque();
                self.state.flight.acs().torque_cmd_n_m = t;
                t
            }
            ActingLaw::Transient => {
                let g = self.state.sup.entry_gains;
                let acs = self.state.flight.acs();
                acs.set_law(AttitudeLaw::Lyapunov { k1: g.k1, k2: g.k2 });
                acs.command()
            }
            ActingLaw::Science => {
                let c = self.state.science.expect("chosen at the entry to s3, just above");
                let acs = self.state.flight.acs();
                acs.set_law(c.law);
                acs.command()
            }
        };
        self.state.acting = law;
        torque
    }
}

impl Algorithm for HandoffAgent {
    fn columns(&self) -> Vec<String> {
        let mut c = match &self.state.flight {
            Flight::Leader(l) => l.columns(),
            Flight::Follower(f) => f.columns(),
        };
        c.extend(self.state.sup.columns().into_iter().map(|n| format!("sup_{n}")));
        for n in ["law_stabilisation_on", "law_transient_on", "law_science_on"] {
            c.push(n.into());
        }
        c.extend(["transient_k1_n_m", "transient_k2_n_m_s", "transient_t_hat_entry_s"].map(String::from));
        c.extend(science::columns(self.science.kind()));
        c
    }

    fn share(&mut self, input: &AgentInput<'_>, out: &mut ShareOut) {
        self.state.flight.algorithm().share(input, out);
        out.values.resize(SUPERVISOR_OFFSET, 0.0);
        let x = Self::estimate(self.state.flight.acs_ref());
        self.state.sup.tick(&x, self.transient.as_ref(), &mut out.values);
        let torque = self.command();
        // A short reading message leaves the flight agent's zero command (it trusts nothing).
        if out.command.len() >= 3 && self.state.flight.acs_ref().mekf.is_some() {
            out.command[..3].copy_from_slice(torque.as_slice());
        }
    }

    fn step(&mut self, dt_s: f64, neighbours: &[Neighbour<'_>]) {
        self.state.flight.algorithm().step(dt_s, neighbours);
        let sup: Vec<Neighbour<'_>> = neighbours
            .iter()
            .filter(|n| n.values.len() > SUPERVISOR_OFFSET)
            .map(|n| Neighbour { id: n.id, values: &n.values[SUPERVISOR_OFFSET..], age_steps: n.age_steps })
            .collect();
        self.state.sup.receive(&sup);
        self.state.sup.advance(dt_s);
    }

    fn row(&self, out: &mut Vec<f64>) {
        match &self.state.flight {
            Flight::Leader(l) => l.row(out),
            Flight::Follower(f) => f.row(out),
        }
        self.state.sup.row(out);
        let on = |l: ActingLaw| if self.state.acting == l { 1.0 } else { 0.0 };
        out.extend([on(ActingLaw::Stabilisation), on(ActingLaw::Transient), on(ActingLaw::Science)]);
        let g = self.state.sup.entry_gains;
        out.extend([g.k1, g.k2, g.t_s]);
        science::row(self.science.kind(), self.state.science.as_ref(), out);
    }

    fn save_state(&self) -> Vec<u8> {
        cohort_runtime::checkpoint::encode_state(&self.state)
    }

    fn restore_state(&mut self, bytes: &[u8]) -> Result<(), RestoreStateError> {
        self.state = cohort_runtime::checkpoint::decode_state(bytes)?;
        Ok(())
    }
}
