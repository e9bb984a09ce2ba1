//! Seed 003 in the registry: the `iso-encounter` plant kind and the `neural-rendezvous`
//! algorithm kind (Algorithm 1 of "Neural-Rendezvous", arXiv:2208.04883, and the baselines of its
//! Sec. 6.3, chosen by `algorithm.method`). Each parses its section with the typed configuration
//! of [`crate::iso::config`], reports every problem with its key path, and builds the models.
//!
//! Checks beyond the sections' own (`IsoEncounterConfig::validate`, `NrAlgorithmConfig::validate`):
//!
//! - `scenario.duration_s` ≤ `plant.t_f_s`: the encounter is at t_f. A shorter run is the first
//!   part of the same flight (its rows are bit for bit those of the full run) and has no delivery
//!   error; a longer one would fly the spacecraft past the ISO at the encounter speed with nothing
//!   left to decide, so it is refused.
//! - the agents carry no per-agent keys (the plant draws each spacecraft's start and ρ_f) and no
//!   neighbours: the spacecraft fly independently, so the algorithm tells the runtime it needs no
//!   connected communication graph.
//! - `algorithm.weights`, relative to the scenario file, is resolved while configuring (the
//!   resolved scenario carries it absolute), loaded and checked (input and output sizes, and
//!   `algorithm.c_sn` if given) whenever it is given; the loaded network is shared by every
//!   agent of the process.

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};
use std::sync::Arc;

use cohort_runtime::model::{Algorithm, PlantModel};
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, PlantKind, PlantSetup, Setup, agent_keys,
    section_as, table_of,
};
use cohort_scenario::{Checker, Scenario, fmt_f64};

use crate::iso::config::{IsoEncounterConfig, NrAlgorithmConfig, build_plant};
use crate::iso::control::agent::NrAgent;
use crate::iso::dynamics::messages::{COMMAND_LEN, READINGS_LEN, SHARE_LEN};
use crate::iso::guidance::features::{N_FEATURES, REFERENCE_INPUTS};
use crate::nn::sn_dnn::SnDnn;

/// The plant kind's name.
pub const PLANT_KIND: &str = "iso-encounter";
/// The algorithm kind's name.
pub const ALGORITHM_KIND: &str = "neural-rendezvous";

pub struct IsoEncounterKind;

impl PlantKind for IsoEncounterKind {
    fn kind(&self) -> &'static str {
        PLANT_KIND
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let p = section_as::<IsoEncounterConfig>(&ctx.scenario.plant.body, "plant", c);
        let agents = agent_keys::<cohort_runtime::paper::NoAgentKeys>(ctx.scenario, c);
        let mut p = p?;
        let s = ctx.scenario;
        c.problems.extend(p.validate(s.scenario.dt_s, s.n_agents()));
        let duration = s.scenario.duration_s;
        if duration.is_finite() && p.t_f_s.is_finite() && duration > p.t_f_s * (1.0 + 1e-12) {
            c.fail(
                "scenario.duration_s",
                fmt_f64(duration),
                format!(
                    "longer than the encounter (plant.t_f_s = {} s): past t_f the spacecraft only coasts by the \
                     ISO; a run may stop at or before t_f (before it, there is no delivery error)",
                    fmt_f64(p.t_f_s)
                ),
            );
        }
        agents?;
        // The ISO the run's seed picks, written into the resolved scenario.
        p.iso_index = Some(p.index(s.scenario.seed));
        Some(Arc::new(p))
    }
}

impl PlantSetup for IsoEncounterConfig {
    fn kind(&self) -> &'static str {
        PLANT_KIND
    }
    fn link_frame(&self) -> cohort_runtime::paper::LinkFrame {
        cohort_runtime::paper::LinkFrame::CentralBody("the Sun", 6.957e8)
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(self)
    }
    fn readings(&self, _s: &Scenario, _id: u32) -> usize {
        READINGS_LEN
    }
    fn command_len(&self) -> usize {
        COMMAND_LEN
    }
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel> {
        let plant = build_plant(self, setup.n_agents(), setup.scenario.dt_s, setup.scenario.seed)
            .unwrap_or_else(|p| panic!("validated while configuring: {p:?}"));
        Box::new(plant)
    }
}

/// The configured `neural-rendezvous` section and its loaded network (if it names one).
pub struct NrSetup {
    pub config: NrAlgorithmConfig,
    pub net: Option<Arc<SnDnn>>,
}

pub struct NeuralRendezvousKind;

impl AlgorithmKind for NeuralRendezvousKind {
    fn kind(&self) -> &'static str {
        ALGORITHM_KIND
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        _plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<NrAlgorithmConfig>(&ctx.scenario.algorithm.body, "algorithm", c);
        if ctx.scenario.plant.kind != PLANT_KIND {
            c.fail(
                "algorithm.kind",
                format!("{ALGORITHM_KIND:?}"),
                format!("needs plant.kind = {PLANT_KIND:?} (its readings and mission constants)"),
            );
        }
        // The spacecraft fly independently: nothing would read a neighbour's share.
        for (k, agent) in ctx.scenario.agents.iter().enumerate().filter(|(_, a)| !a.neighbours.is_empty()) {
            c.fail(
                format!("agents[{k}].neighbours"),
                format!("{:?}", agent.neighbours),
                "must be []: neural-rendezvous spacecraft fly independently and read no neighbour",
            );
        }
        let mut config = a?;
        c.problems.extend(config.validate());
        if let Some(w) = &config.weights {
            config.weights = Some(PathBuf::from(ctx.scenario.resolve_path(&w.to_string_lossy())));
        }
        // A file that does not load is a problem in `c`, so the scenario is refused either way.
        let net = config.weights.as_deref().and_then(|path| load_checked(path, &config, c));
        Some(Arc::new(NrSetup { config, net }))
    }
}

/// Load the weights at `path` and check them against what the guidance needs; problems go to
/// `c` at `algorithm.weights` (or `algorithm.c_sn`).
fn load_checked(path: &Path, config: &NrAlgorithmConfig, c: &mut Checker) -> Option<Arc<SnDnn>> {
    let shown = format!("{:?}", path.display().to_string());
    let net = match SnDnn::load(path) {
        Ok(n) => n,
        Err(e) => {
            c.fail("algorithm.weights", shown, e.problem.to_string());
            return None;
        }
    };
    if !(net.n_in() == N_FEATURES || net.n_in() == REFERENCE_INPUTS) || net.n_out() != 3 {
        c.fail(
            "algorithm.weights",
            shown,
            format!(
                "a network of {} inputs and {} outputs; the guidance needs {N_FEATURES} (or the reference's \
                 {REFERENCE_INPUTS}) inputs and 3 outputs",
                net.n_in(),
                net.n_out()
            ),
        );
        return None;
    }
    if let Some(want) = config.c_sn.filter(|want| *want != net.c_sn()) {
        c.fail("algorithm.c_sn", fmt_f64(want), format!("the weights file {shown} has C_sn = {}", fmt_f64(net.c_sn())));
        return None;
    }
    Some(Arc::new(net))
}

impl AlgorithmSetup for NrSetup {
    fn kind(&self) -> &'static str {
        ALGORITHM_KIND
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        SHARE_LEN
    }
    fn build(&self, setup: &Setup, _id: u32) -> Box<dyn Algorithm> {
        let agent = NrAgent::new(self.config.clone(), setup.scenario.dt_s, self.net.clone())
            .unwrap_or_else(|e| panic!("validated while configuring: {e}"));
        Box::new(agent)
    }
    /// The spacecraft fly independently (no agent-agent messages).
    fn needs_connected_graph(&self) -> bool {
        false
    }
    fn labels(&self) -> BTreeMap<String, String> {
        BTreeMap::from([("method".to_string(), self.config.method.name().to_string())])
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use cohort_runtime::paper::{Paper, configure};
    use cohort_scenario::{Overrides, parse};

    use super::*;

    const PAPERS: &[&dyn Paper] = &[&crate::Nr];

    pub(crate) fn topologies() -> PathBuf {
        Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies")
    }

    /// The text configured as a file of the topologies directory (so its weights path resolves).
    pub(crate) fn configured(text: &str) -> Result<Setup, String> {
        let s = parse(text, &topologies().join("x.toml"), &Overrides::default()).map_err(|e| e.to_string())?;
        configure(s, PAPERS).map_err(|p| p.iter().map(|p| p.to_string()).collect::<Vec<_>>().join("\n"))
    }

    /// A shipped scenario's text.
    pub(crate) fn file(name: &str) -> String {
        std::fs::read_to_string(topologies().join(name)).unwrap()
    }

    #[test]
    fn the_shipped_scenarios_configure_with_the_iso_of_their_seed_and_the_weights_resolved() {
        let s = configured(&file("nr-iso.toml")).unwrap();
        let p = s.plant_as::<IsoEncounterConfig>().unwrap();
        assert_eq!(p.iso_index, Some(200 + (s.scenario.seed % 100) as u32));
        let a = s.algorithm_as::<NrSetup>().unwrap();
        assert!(a.config.weights.as_ref().unwrap().is_absolute() && a.net.is_some());
        let fleet = configured(&file("nr-iso-fleet.toml")).unwrap();
        assert_eq!(fleet.n_agents(), 4);
        // The resolved scenario configures to itself.
        let again = configured(&s.to_toml().unwrap()).unwrap();
        assert_eq!(again.to_toml().unwrap(), s.to_toml().unwrap());
    }

    #[test]
    fn every_bad_key_is_reported_with_its_path() {
        let bad = file("nr-iso.toml")
            .replace("duration_s = 86400.0", "duration_s = 87000.0")
            .replace("t_s_fraction = 0.75", "t_s_fraction = 1.5\nc_sn = 4.0");
        let e = configured(&bad).unwrap_err();
        for want in ["scenario.duration_s", "algorithm.t_s_fraction"] {
            assert!(e.contains(want), "{want} missing from:\n{e}");
        }
        let e = configured(&file("nr-iso.toml").replace("t_s_fraction = 0.75", "c_sn = 4.0")).unwrap_err();
        assert!(e.contains("algorithm.c_sn") && e.contains("C_sn = 2"), "{e}");
        let e = configured(&file("nr-iso.toml").replace("sn-dnn.safetensors", "none.safetensors")).unwrap_err();
        assert!(e.contains("algorithm.weights") && e.contains("cannot read"), "{e}");
        let e =
            configured(&file("nr-iso.toml").replace("neighbours = []", "neighbours = []\nmass_kg = 3.0")).unwrap_err();
        assert!(e.contains("agents[0]") && e.contains("mass_kg"), "{e}");
        let e = configured(&file("nr-iso.toml").replace("kind = \"iso-encounter\"", "kind = \"null\"")).unwrap_err();
        assert!(e.contains("algorithm.kind") || e.contains("plant.kind"), "{e}");
    }
}
