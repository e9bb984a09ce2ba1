//! The registry's `vtxo-handoff` algorithm kind: s1 stabilisation → s2 transient → s3 science of
//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (arXiv:2509.13331, Secs. 2.11, 3.2.1 and 8) flown in lockstep on the `vtxo` plant, the leader
//! (agent 1) and the follower (agent 2, the supervisor master) each a [`HandoffAgent`].
//!
//! Configuring checks the section ([`VtxoHandoffConfig::validate`]), the pair with the plant
//! (targets, [`crate::config::check_pair`], reported under `algorithm.flight.…`), the links (each
//! agent lists the other), and loads the transient DNN named by `algorithm.handoff.transient_weights`
//! (relative to the scenario file; the resolved scenario the processes read carries it absolute):
//! a missing or malformed file is a problem at that key path naming the file. The loaded network
//! is shared by both agents of a process.

use std::any::Any;
use std::collections::BTreeMap;
use std::path::PathBuf;
use std::sync::Arc;

use cohort_runtime::model::Algorithm;
use cohort_runtime::paper::{AlgorithmKind, AlgorithmSetup, ConfigureCtx, PlantSetup, Setup, section_as, table_of};
use cohort_scenario::{Checker, Scenario};

use crate::config_algorithm::{Phase, VtxoAlgorithmConfig};
use crate::config_plant::VtxoPlantConfig;
use crate::handoff::{ConfiguredScience, Flight, HandoffAgent, SUPERVISOR_OFFSET, SciencePredictor};
use crate::handoff_config::{ScienceGainsSource, VtxoHandoffConfig};
use crate::kinds::check_pair_kind;
use crate::mission_kind::MISSION_KIND;
use crate::supervisor::S1;
use crate::supervisor_exec::Supervisor;
use crate::supervisor_lockstep::SupervisorAgent;
use crate::supervisor_share::{LEADER_SHARE_LEN, MASTER_SHARE_LEN};
use crate::transient_dnn::TransientDnn;
use crate::transient_gains::{FixedTransient, TransientGains, TransientPredictor};

pub const HANDOFF_KIND: &str = "vtxo-handoff";
const WEIGHTS_KEY: &str = "algorithm.handoff.transient_weights";

pub struct VtxoHandoffKind;

/// The configured section and its loaded transient DNN (None: the fixed predictor).
pub struct HandoffSetup {
    pub config: VtxoHandoffConfig,
    pub dnn: Option<Arc<TransientDnn>>,
}

impl AlgorithmKind for VtxoHandoffKind {
    fn kind(&self) -> &'static str {
        HANDOFF_KIND
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<VtxoHandoffConfig>(&ctx.scenario.algorithm.body, "algorithm", c);
        check_pair_kind(
            ctx.scenario,
            HANDOFF_KIND,
            "the flight shares and the supervisor's state (follower, the master) and acknowledgement (leader) pass between them",
            c,
        );
        let mut a = a?;
        c.problems.extend(a.validate("algorithm", ctx.scenario.scenario.dt_s));
        if let Some(p) = plant.and_then(|p| p.as_any().downcast_ref::<VtxoPlantConfig>()) {
            for mut pr in crate::config::check_pair(p, &a.flight) {
                pr.path = pr.path.replacen("algorithm.", "algorithm.flight.", 1);
                c.problems.push(pr);
            }
        }
        let mut dnn = None;
        if let Some(w) = &a.handoff.transient_weights {
            let path = PathBuf::from(ctx.scenario.resolve_path(&w.to_string_lossy()));
            match TransientDnn::load(&path) {
                Ok(d) => dnn = Some(Arc::new(d)),
                Err(e) => c.fail(WEIGHTS_KEY, format!("{:?}", path.display().to_string()), e.to_string()),
            }
            a.handoff.transient_weights = Some(path);
        }
        Some(Arc::new(HandoffSetup { config: a, dnn }))
    }
}

impl HandoffSetup {
    fn transient(&self) -> Arc<dyn TransientPredictor> {
        match &self.dnn {
            Some(d) => d.clone(),
            None => {
                let x = &self.config.supervisor.transient;
                Arc::new(FixedTransient(TransientGains { k1: x.k1, k2: x.k2, t_s: x.t_s }))
            }
        }
    }

    fn science(&self) -> Arc<dyn SciencePredictor> {
        match self.config.handoff.science_gains {
            ScienceGainsSource::Configured => {
                let f = VtxoAlgorithmConfig { phase: Phase::Science, ..self.config.flight.clone() };
                Arc::new(ConfiguredScience(f.attitude_law()))
            }
        }
    }

    /// Agent `id`'s supervisor: in s1 of the configured object, u1 = `handoff.stabilisation_s`.
    fn supervisor(&self, dt_s: f64, id: u32) -> SupervisorAgent {
        let mut s = SupervisorAgent::new(&self.config.supervisor, dt_s, id);
        s.p.u1 = self.config.u1_ticks(dt_s);
        s.sup = Supervisor { state: S1, id: self.config.handoff.object_id, ..s.sup };
        s
    }
}

impl AlgorithmSetup for HandoffSetup {
    fn kind(&self) -> &'static str {
        HANDOFF_KIND
    }
    fn resolved(&self) -> Result<toml::Table, String> {
        table_of(&self.config)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        SUPERVISOR_OFFSET + MASTER_SHARE_LEN.max(LEADER_SHARE_LEN)
    }
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        let f = &self.config.flight;
        // Validated: the ids are 1 and 2.
        let flight = match id {
            1 => Flight::Leader(crate::build_leader(f)),
            _ => Flight::Follower(crate::build_follower(f)),
        };
        let sup = self.supervisor(setup.scenario.dt_s, id);
        Box::new(HandoffAgent::new(flight, sup, crate::orbit::MU_EARTH_M3PS2, self.transient(), self.science()))
    }
    fn labels(&self) -> BTreeMap<String, String> {
        let science = VtxoAlgorithmConfig { phase: Phase::Science, ..self.config.flight.clone() };
        let mut m = AlgorithmSetup::labels(&science);
        m.insert("phase".into(), "handoff".into());
        let law = m.get("attitude_law").cloned().unwrap_or_default();
        m.insert("attitude_law".into(), format!("stabilisation, lyapunov, {law}"));
        m.insert("supervisor".into(), format!("lockstep ({MISSION_KIND} automaton)"));
        let t = if self.dnn.is_some() { "dnn" } else { "fixed" };
        m.insert("transient_predictor".into(), t.into());
        m.insert("science_gains".into(), "configured".into());
        m
    }
    fn as_any(&self) -> &dyn Any {
        self
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use cohort_runtime::paper::{Paper, configure};
    use cohort_scenario::{Overrides, parse};

    use super::*;
    use crate::plant::VtxoPlant;
    use crate::sim::Sim;

    const PAPERS: &[&dyn Paper] = &[&crate::Vtxo];

    fn configured(text: &str) -> Result<Setup, String> {
        let dir = Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies");
        let s = parse(text, &dir.join("x.toml"), &Overrides::default()).map_err(|e| e.to_string())?;
        configure(s, PAPERS).map_err(|p| p.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("\n"))
    }

    fn sim(s: &Setup) -> Sim {
        let p = s.plant_as::<VtxoPlantConfig>().unwrap();
        let plant = VtxoPlant::new(p, s.scenario.dt_s, s.scenario.seed);
        let agents = (1..=2).map(|id| s.algorithm.build(s, id)).collect();
        Sim::from_parts(plant, agents, s.scenario.dt_s, s.scenario.seed)
    }

    fn rows(s: &mut Sim, n: u64) -> Vec<u64> {
        let mut out = Vec::new();
        s.run_with(n, &mut |_, _, agents| {
            for a in agents {
                let mut r = Vec::new();
                a.row(&mut r);
                out.extend(r.iter().map(|x| x.to_bits()));
            }
        });
        out
    }

    /// The shipped scenario resolves its weights path and configures to itself; agents restored
    /// from a checkpoint taken inside s2 (with fresh predictors from the setup) fly on bit for bit.
    #[test]
    fn the_weights_resolve_and_a_checkpoint_inside_the_transient_round_trips() {
        let text =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/vtxo-handoff.toml"))
                .unwrap()
                .replace("stabilisation_s = 30.0", "stabilisation_s = 1.0");
        let s = configured(&text).unwrap();
        let a = s.algorithm_as::<HandoffSetup>().unwrap();
        assert!(a.config.handoff.transient_weights.as_ref().unwrap().is_absolute() && a.dnn.is_some());
        let again = configured(&s.to_toml().unwrap()).unwrap();
        assert_eq!(again.algorithm_as::<HandoffSetup>().unwrap().config, a.config);
        let (mut x, mut y) = (sim(&s), sim(&s));
        x.run(150);
        y.run(150);
        // Into fresh agents (in s1, no prediction yet) the state of step 150 (in s2 since step 100).
        let saved: Vec<Vec<u8>> = y.agents.iter().map(|g| g.save_state()).collect();
        y.agents = (1..=2).map(|id| s.algorithm.build(&s, id)).collect();
        for (g, b) in y.agents.iter_mut().zip(&saved) {
            g.restore_state(b).unwrap();
        }
        assert_eq!(rows(&mut x, 50), rows(&mut y, 50));
        assert!(y.agents[1].restore_state(&saved[1][..saved[1].len() / 2]).is_err());
    }
}
