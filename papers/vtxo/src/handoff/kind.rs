//! The registry's `vtxo-handoff` algorithm kind: s1 stabilisation → s2 transient → s3 science of
//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (arXiv:2509.13331, Secs. 2.11, 3.2.1 and 8) flown in lockstep on the `vtxo` plant, the leader
//! (agent 1) and the follower (agent 2, the supervisor master) each a [`HandoffAgent`].
//!
//! Configuring checks the section ([`VtxoHandoffConfig::validate`]), the pair with the plant
//! (targets, [`crate::config::check_pair`], reported under `algorithm.flight.…`; the supervisor's
//! orbit period, which this scenario does not read, is the plant's or agrees with it,
//! [`crate::mission::period`]), the links (each
//! agent lists the other), and loads the transient DNN named by `algorithm.handoff.transient_weights`
//! (relative to the scenario file; the resolved scenario the processes read carries it absolute):
//! a missing or malformed file is a problem at that key path naming the file. The science DNN
//! named by `algorithm.handoff.science_weights` is resolved, loaded and refused in the same way
//! (a file of another model, e.g. the transient DNN's, is refused too: it has no science
//! network). The loaded networks are shared by both agents of a process.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use cohort_runtime::model::Algorithm;
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, PlantSetup, Setup, section_as, table_of,
};
use cohort_scenario::{Checker, Scenario};

use crate::automaton::exec::Supervisor;
use crate::automaton::lockstep::SupervisorAgent;
use crate::automaton::share::{LEADER_SHARE_LEN, MASTER_SHARE_LEN};
use crate::automaton::table::S1;
use crate::flight::config::{Phase, VtxoAlgorithmConfig};
use crate::formation::kinds::check_pair_kind;
use crate::handoff::agent::{ConfiguredScience, Flight, HandoffAgent, SUPERVISOR_OFFSET, SciencePredictor};
use crate::handoff::config::{ScienceGainsSource, VtxoHandoffConfig};
use crate::handoff::science::DnnScience;
use crate::learn::science::dnn::ScienceDnn;
use crate::learn::transient::dnn::TransientDnn;
use crate::learn::transient::gains::{FixedTransient, TransientGains, TransientPredictor};
use crate::mission::kind::MISSION_KIND;
use crate::model::config::VtxoPlantConfig;

pub const HANDOFF_KIND: &str = "vtxo-handoff";
const WEIGHTS_KEY: &str = "algorithm.handoff.transient_weights";
const SCIENCE_WEIGHTS_KEY: &str = "algorithm.handoff.science_weights";

pub struct VtxoHandoffKind;

/// The configured section and its loaded networks (transient None: the fixed predictor; science
/// None: only with `science_gains = "configured"`).
pub struct HandoffSetup {
    pub config: VtxoHandoffConfig,
    pub dnn: Option<Arc<TransientDnn>>,
    pub science_dnn: Option<Arc<ScienceDnn>>,
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
        let plant = plant.and_then(|p| p.downcast_ref::<VtxoPlantConfig>());
        if let Some(p) = plant {
            c.problems.extend(a.supervisor.timers.follow_plant("algorithm.supervisor", p));
        }
        c.problems.extend(a.validate("algorithm", ctx.scenario.scenario.dt_s));
        if let Some(p) = plant {
            for mut pr in crate::config::check_pair(p, &a.flight) {
                pr.path = pr.path.replacen("algorithm.", "algorithm.flight.", 1);
                c.problems.push(pr);
            }
        }
        let dnn = load_weights(ctx.scenario, &mut a.handoff.transient_weights, WEIGHTS_KEY, TransientDnn::load, c);
        let science_dnn =
            load_weights(ctx.scenario, &mut a.handoff.science_weights, SCIENCE_WEIGHTS_KEY, ScienceDnn::load, c);
        Some(Arc::new(HandoffSetup { config: a, dnn, science_dnn }))
    }
}

/// Resolve the weights file at `key` (if given) against the scenario's folder, in place, and load
/// it with `load`; a file that does not load is a problem at `key` naming the file and the reason.
fn load_weights<T, E: std::fmt::Display>(
    scenario: &Scenario,
    file: &mut Option<PathBuf>,
    key: &str,
    load: impl Fn(&Path) -> Result<T, E>,
    c: &mut Checker,
) -> Option<Arc<T>> {
    let path = PathBuf::from(scenario.resolve_path(&file.as_ref()?.to_string_lossy()));
    let loaded = match load(&path) {
        Ok(d) => Some(Arc::new(d)),
        Err(e) => {
            c.fail(key, format!("{:?}", path.display().to_string()), e.to_string());
            None
        }
    };
    *file = Some(path);
    loaded
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
        let f = VtxoAlgorithmConfig { phase: Phase::Science, ..self.config.flight.clone() };
        let configured = ConfiguredScience(f.attitude_law());
        match (self.config.handoff.science_gains, &self.science_dnn) {
            (ScienceGainsSource::Dnn, Some(d)) => Arc::new(DnnScience {
                dnn: d.clone(),
                law: configured.kind(),
                w_deg_per_j: self.config.handoff.science_w_deg_per_j,
            }),
            // Validation refuses "dnn" without loaded weights.
            _ => Arc::new(configured),
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
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        SUPERVISOR_OFFSET + MASTER_SHARE_LEN.max(LEADER_SHARE_LEN)
    }
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        let f = &self.config.flight;
        // Validated: the ids are 1 and 2.
        let flight = match id {
            1 => Flight::Leader(crate::formation::build_leader(f)),
            _ => Flight::Follower(crate::formation::build_follower(f)),
        };
        let sup = self.supervisor(setup.scenario.dt_s, id);
        Box::new(HandoffAgent::new(flight, sup, crate::model::orbit::MU_EARTH_M3PS2, self.transient(), self.science()))
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
        m.insert("science_gains".into(), self.config.handoff.science_gains.name().into());
        m
    }
}

#[cfg(test)]
mod tests {
    use std::path::Path;

    use cohort_runtime::paper::{Paper, configure};
    use cohort_scenario::{Overrides, parse};

    use super::*;
    use crate::formation::sim::Sim;
    use crate::model::plant::VtxoPlant;

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

    /// Into fresh agents of the setup (in s1, nothing predicted yet) `y`'s current state.
    fn restore_into_fresh(s: &Setup, y: &mut Sim) -> Vec<Vec<u8>> {
        let saved: Vec<Vec<u8>> = y.agents.iter().map(|g| g.save_state()).collect();
        y.agents = (1..=2).map(|id| s.algorithm.build(s, id)).collect();
        for (g, b) in y.agents.iter_mut().zip(&saved) {
            g.restore_state(b).unwrap();
        }
        saved
    }

    /// The shipped scenario resolves both weights paths and configures to itself; agents restored
    /// from a checkpoint taken inside s2, and one taken inside s3 (the science DNN's gains are
    /// state, not asked again), with fresh predictors from the setup, fly on bit for bit.
    #[test]
    fn the_weights_resolve_and_checkpoints_inside_the_transient_and_the_science_phase_round_trip() {
        // s1 1 s and u2 = 7.2 s: s2 from step 100, s3 from step 820.
        let text =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/vtxo-handoff.toml"))
                .unwrap()
                .replace("stabilisation_s = 30.0", "stabilisation_s = 1.0")
                .replace("t_max_s = 72.0", "t_max_s = 7.2\nt_s = 7.2");
        let s = configured(&text).unwrap();
        let a = s.algorithm_as::<HandoffSetup>().unwrap();
        assert!(a.config.handoff.transient_weights.as_ref().unwrap().is_absolute() && a.dnn.is_some());
        assert!(a.config.handoff.science_weights.as_ref().unwrap().is_absolute() && a.science_dnn.is_some());
        assert_eq!(a.labels()["science_gains"], "dnn");
        let again = configured(&s.to_toml().unwrap()).unwrap();
        assert_eq!(again.algorithm_as::<HandoffSetup>().unwrap().config, a.config);
        let (mut x, mut y) = (sim(&s), sim(&s));
        x.run(150);
        y.run(150);
        let saved = restore_into_fresh(&s, &mut y);
        assert_eq!(rows(&mut x, 50), rows(&mut y, 50));
        assert!(y.agents[1].restore_state(&saved[1][..saved[1].len() / 2]).is_err());
        let (mut x, mut y) = (sim(&s), sim(&s));
        x.run(900);
        y.run(900);
        let mut r = Vec::new();
        y.agents[1].row(&mut r);
        assert!(r[r.len() - 5].is_finite(), "the science gains are chosen by step 900: {:?}", &r[r.len() - 5..]);
        restore_into_fresh(&s, &mut y);
        assert_eq!(rows(&mut x, 50), rows(&mut y, 50));
    }

    /// `science_gains = "dnn"` without weights, and weights of another model, are refused at
    /// `algorithm.handoff.science_weights`; configured gains with named weights still check them.
    #[test]
    fn science_weights_are_required_by_the_dnn_source_and_checked_whenever_named() {
        let text =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/vtxo-handoff.toml"))
                .unwrap();
        let without = text.replace("science_weights = \"../papers/vtxo/weights/science.safetensors\"\n", "");
        let e = configured(&without).expect_err("dnn without weights");
        assert!(e.contains(SCIENCE_WEIGHTS_KEY) && e.contains("required"), "{e}");
        let configured_src = without.replace("science_gains = \"dnn\"", "science_gains = \"configured\"");
        let s = configured(&configured_src).expect("configured gains need no weights");
        assert!(s.algorithm_as::<HandoffSetup>().unwrap().science_dnn.is_none());
        let wrong = text
            .replace("science_gains = \"dnn\"", "science_gains = \"configured\"")
            .replace("weights/science.safetensors", "weights/transient.safetensors");
        let e = configured(&wrong).expect_err("transient weights as science weights");
        assert!(e.contains(SCIENCE_WEIGHTS_KEY) && e.contains("transient.safetensors"), "{e}");
        assert!(e.contains("holds no science DNN"), "{e}");
    }

    /// The supervisor's period (not read here) is the plant's, and a disagreeing one is refused
    /// at `algorithm.supervisor.timers.orbit_period_s` naming the plant's orbit.
    #[test]
    fn the_supervisors_period_is_the_plants_or_refused() {
        let text =
            std::fs::read_to_string(Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/vtxo-handoff.toml"))
                .unwrap();
        let s = configured(&text).unwrap();
        let want = s.plant_as::<VtxoPlantConfig>().unwrap().orbit_period_s();
        assert_eq!(s.algorithm_as::<HandoffSetup>().unwrap().config.supervisor.timers.orbit_period_s, want);
        let wrong = text
            .replace("[algorithm.supervisor.timers]\n", "[algorithm.supervisor.timers]\norbit_period_s = 117000.0\n");
        let e = configured(&wrong).expect_err("32.5 h over Table D.9's orbit");
        assert!(e.contains("algorithm.supervisor.timers.orbit_period_s = 117000.000 s (32.5000 h)"), "{e}");
        assert!(e.contains("plant.orbit.a_m") && e.contains("(26.6536 h)"), "{e}");
    }
}
