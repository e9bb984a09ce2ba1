//! The `orbital` plant and `lb-dnn-servicing` algorithm sections, their checks (including the
//! paper's trackability condition, Def. 1), and the configured setups that build the models.

use std::sync::Arc;

use cohort_astro::orbit::{
    BodyProps, DensityHold, EarthForces, J2_EARTH, Lvlh, MU_EARTH_M3PS2, R_EARTH_M, V3, periapsis_state,
};
use cohort_runtime::model::{Algorithm, PlantModel};
use cohort_runtime::paper::{
    AlgorithmKind, AlgorithmSetup, ConfigTableError, ConfigureCtx, PlantKind, PlantSetup, Setup, agent_keys,
    section_as, table_of,
};
use cohort_runtime::rng::{process_rng, setup_rng};
use cohort_scenario::{Checker, Problem, Scenario, fmt_f64};
use cohort_wire::transport::Proc;
use rand::Rng;
use serde::{Deserialize, Serialize};

use crate::servicing::{Body, Sensing, ServicingPlant};

// ---------------------------------------------------------------------------------------------
// Plant `orbital`

/// Servicers and a defunct spacecraft in Earth orbit: ECI truth with two-body + J2 + drag; agents
/// sense yᵢ = Cᵢ(q₀ − qᵢ) and dᵢⱼ = qⱼ − qᵢ in the LVLH frame of a reference point on the
/// defunct's initial osculating Keplerian orbit.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrbitalPlant {
    /// Standard deviation of the zero-mean Gaussian noise on every component of yᵢ and dᵢⱼ, m.
    pub noise_std_m: f64,
    /// RK4 sub-steps per lockstep step.
    #[serde(default = "one")]
    pub substeps: u32,
    #[serde(default = "default_true")]
    pub j2: bool,
    #[serde(default = "default_true")]
    pub drag: bool,
    /// Drag coefficient C_D of every body.
    #[serde(default = "default_cd")]
    pub drag_coeff: f64,
    /// Where the density is evaluated; see [`DensityAt`].
    #[serde(default = "default_density_hold")]
    pub density_hold: DensityAt,
    pub defunct: DefunctConfig,
    /// Random initial offsets of the servicers (Sec. 6), drawn from the seed; when absent, every
    /// agent gives `offset_lvlh_m`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub random_offsets: Option<RandomOffsets>,
}

/// `plant.density_hold`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum DensityAt {
    /// Once per RK4 step, held over its stages (Basilisk's convention).
    Step,
    /// At every stage.
    Stage,
}

fn one() -> u32 {
    1
}
fn default_true() -> bool {
    true
}
fn default_cd() -> f64 {
    2.2
}
fn default_density_hold() -> DensityAt {
    DensityAt::Step
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DefunctConfig {
    pub periapsis_alt_m: f64,
    pub apoapsis_alt_m: f64,
    pub inclination_rad: f64,
    #[serde(default)]
    pub raan_rad: f64,
    #[serde(default)]
    pub arg_periapsis_rad: f64,
    pub mass_kg: f64,
    pub area_m2: f64,
}

/// Servicer start: range U(range_m), azimuth γ U(azimuth_rad), elevation φ U(elevation_rad) in
/// the defunct's LVLH frame: x = σ cos φ cos γ, y = σ cos φ sin γ, z = σ sin φ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RandomOffsets {
    pub range_m: [f64; 2],
    pub azimuth_rad: [f64; 2],
    pub elevation_rad: [f64; 2],
}

/// A servicer's per-agent keys.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct OrbitalAgent {
    /// Start offset from the defunct in its LVLH frame, m (unless `plant.random_offsets`).
    pub offset_lvlh_m: Option<[f64; 3]>,
    /// Spacecraft mass, kg, and drag cross-section, m².
    pub mass_kg: Option<f64>,
    pub area_m2: Option<f64>,
    /// Output matrix Cᵢ (1–4 rows of 3) of yᵢ = Cᵢ(q₀ − qᵢ).
    pub output_matrix: Option<Vec<[f64; 3]>>,
    /// Whether this agent senses the defunct (bᵢ ∈ {0, 1}; 1 when absent).
    pub b: Option<u8>,
}

impl OrbitalAgent {
    pub fn b(&self) -> u8 {
        self.b.unwrap_or(1)
    }
}

pub struct OrbitalKind;

/// A configured `orbital` plant: the section and every servicer's keys, in id order.
#[derive(Clone)]
pub struct OrbitalSetup {
    pub config: OrbitalPlant,
    pub agents: Vec<OrbitalAgent>,
}

impl PlantKind for OrbitalKind {
    fn kind(&self) -> &'static str {
        "orbital"
    }
    fn configure(&self, ctx: &ConfigureCtx<'_>, c: &mut Checker) -> Option<Arc<dyn PlantSetup>> {
        let s = ctx.scenario;
        let config = section_as::<OrbitalPlant>(&s.plant.body, "plant", c);
        let agents = agent_keys::<OrbitalAgent>(s, c);
        if let Some(p) = &config {
            check_plant(c, p);
        }
        let agents = agents?;
        let all_given = check_agents(c, &agents, config.as_ref().is_some_and(|p| p.random_offsets.is_some()));
        let config = config?;
        if !ctx.ids_ok || !all_given {
            return None;
        }
        let order = cohort_kinds_generic::config::by_id(s);
        Some(Arc::new(OrbitalSetup { config, agents: order.iter().map(|&k| agents[k].clone()).collect() }))
    }
}

fn check_plant(c: &mut Checker, p: &OrbitalPlant) {
    c.non_negative("plant.noise_std_m", p.noise_std_m);
    if p.substeps == 0 || p.substeps > 10_000 {
        c.fail("plant.substeps", p.substeps, "must be 1..=10000");
    }
    c.positive("plant.drag_coeff", p.drag_coeff);
    let d = &p.defunct;
    c.positive("plant.defunct.periapsis_alt_m", d.periapsis_alt_m);
    c.positive("plant.defunct.apoapsis_alt_m", d.apoapsis_alt_m);
    if d.periapsis_alt_m.is_finite() && d.apoapsis_alt_m.is_finite() && d.apoapsis_alt_m < d.periapsis_alt_m {
        c.fail(
            "plant.defunct.apoapsis_alt_m",
            fmt_f64(d.apoapsis_alt_m),
            format!("below plant.defunct.periapsis_alt_m = {}", fmt_f64(d.periapsis_alt_m)),
        );
    }
    if c.finite("plant.defunct.inclination_rad", d.inclination_rad)
        && !(0.0..=std::f64::consts::PI).contains(&d.inclination_rad)
    {
        c.fail("plant.defunct.inclination_rad", fmt_f64(d.inclination_rad), "must be in [0, π]");
    }
    c.finite("plant.defunct.raan_rad", d.raan_rad);
    c.finite("plant.defunct.arg_periapsis_rad", d.arg_periapsis_rad);
    c.positive("plant.defunct.mass_kg", d.mass_kg);
    c.non_negative("plant.defunct.area_m2", d.area_m2);
    if let Some(r) = &p.random_offsets {
        for (key, v, positive) in [
            ("range_m", r.range_m, true),
            ("azimuth_rad", r.azimuth_rad, false),
            ("elevation_rad", r.elevation_rad, false),
        ] {
            let path = format!("plant.random_offsets.{key}");
            if c.finite(&format!("{path}[0]"), v[0]) && c.finite(&format!("{path}[1]"), v[1]) {
                if v[0] > v[1] {
                    c.fail(&path, format!("[{}, {}]", fmt_f64(v[0]), fmt_f64(v[1])), "lower bound above upper bound");
                }
                if positive && v[0] <= 0.0 {
                    c.fail(&path, format!("[{}, {}]", fmt_f64(v[0]), fmt_f64(v[1])), "ranges must be > 0");
                }
            }
        }
    }
}

/// Every servicer's keys; returns whether every required key is present and well formed. Then
/// the paper's trackability condition (Def. 1): rank(Σ bᵢ CᵢᵀCᵢ) = 3.
fn check_agents(c: &mut Checker, agents: &[OrbitalAgent], random_offsets: bool) -> bool {
    let kind = OrbitalKind.kind();
    let mut ok = true;
    let mut rows_ok = true;
    for (k, a) in agents.iter().enumerate() {
        let mut req = |c: &mut Checker, key: &str, present: bool, what: &str| {
            if !present {
                ok = false;
                c.problems.push(Problem::new(
                    format!("agents[{k}].{key}"),
                    None,
                    format!("required by plant.kind = \"{kind}\" ({what})"),
                ));
            }
        };
        req(c, "mass_kg", a.mass_kg.is_some(), "spacecraft mass, kg");
        req(c, "area_m2", a.area_m2.is_some(), "drag cross-section, m²");
        req(c, "output_matrix", a.output_matrix.is_some(), "Cᵢ of yᵢ = Cᵢ(q₀ − qᵢ), 1–4 rows of 3");
        if !random_offsets {
            req(
                c,
                "offset_lvlh_m",
                a.offset_lvlh_m.is_some(),
                "start offset from the defunct in its LVLH frame, m; or give plant.random_offsets",
            );
        }
        if let Some(m) = a.mass_kg {
            c.positive(&format!("agents[{k}].mass_kg"), m);
        }
        if let Some(x) = a.area_m2 {
            c.non_negative(&format!("agents[{k}].area_m2"), x);
        }
        if let Some(o) = &a.offset_lvlh_m {
            c.vec3(&format!("agents[{k}].offset_lvlh_m"), o);
        }
        if a.b() > 1 {
            c.fail(format!("agents[{k}].b"), a.b(), "must be 0 or 1");
        }
        if let Some(cm) = &a.output_matrix {
            let path = format!("agents[{k}].output_matrix");
            if cm.is_empty() || cm.len() > 4 {
                c.fail(&path, format!("{} rows", cm.len()), "must have 1 to 4 rows of 3");
                rows_ok = false;
            }
            for (r, row) in cm.iter().enumerate() {
                for (col, x) in row.iter().enumerate() {
                    rows_ok &= c.finite(&format!("{path}[{r}][{col}]"), *x);
                }
            }
        }
    }
    if rows_ok
        && agents.iter().all(|a| a.output_matrix.is_some())
        && let Some((rank, eig)) = trackability(agents, &vec![true; agents.len()])
        && rank < 3
    {
        c.fail(
            "agents[].output_matrix",
            format!("rank {rank}"),
            format!(
                "the defunct spacecraft is not trackable (Def. 1 of the Lb-DNN servicing paper): \
                 rank(Σ bᵢ CᵢᵀCᵢ) = {rank} < 3 (eigenvalues {:.3e}, {:.3e}, {:.3e})",
                eig[0], eig[1], eig[2]
            ),
        );
    }
    ok && rows_ok
}

/// rank(Σ bᵢ CᵢᵀCᵢ) over the live agents (`live[k]` for `agents[k]`; Def. 1) and its eigenvalues,
/// when every agent has an output matrix; None otherwise.
pub fn trackability(agents: &[OrbitalAgent], live: &[bool]) -> Option<(usize, [f64; 3])> {
    if agents.is_empty() || !agents.iter().all(|a| a.output_matrix.is_some()) {
        return None;
    }
    let mut sum = nalgebra::Matrix3::<f64>::zeros();
    for (a, _) in agents.iter().zip(live).filter(|(a, on)| a.b() == 1 && **on) {
        for row in a.output_matrix.as_ref().expect("checked above") {
            let v = nalgebra::Vector3::from_row_slice(row);
            sum += v * v.transpose();
        }
    }
    let eig = sum.symmetric_eigenvalues();
    let max = eig.iter().cloned().fold(0.0, f64::max);
    let rank = eig.iter().filter(|&&e| e > 1e-9 * max.max(1e-300)).count();
    Some((rank, [eig[0], eig[1], eig[2]]))
}

impl PlantSetup for OrbitalSetup {
    fn link_frame(&self) -> cohort_runtime::paper::LinkFrame {
        cohort_runtime::paper::LinkFrame::CentralBody("the Earth", 6_378_137.0)
    }
    fn kind(&self) -> &'static str {
        OrbitalKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn readings(&self, s: &Scenario, id: u32) -> usize {
        let rows = self.agents[id as usize - 1].output_matrix.as_ref().map_or(0, |m| m.len());
        rows + 3 * s.agent(id).neighbours.len()
    }
    /// yᵢ's rows (`y1_m`…), then dᵢⱼ for every neighbour j in the scenario's order, LVLH axes.
    fn reading_names(&self, s: &Scenario, id: u32) -> Vec<String> {
        let rows = self.agents[id as usize - 1].output_matrix.as_ref().map_or(0, |m| m.len());
        let mut names: Vec<String> = (1..=rows).map(|r| format!("y{r}_m")).collect();
        for j in &s.agent(id).neighbours {
            names.extend(["x", "y", "z"].map(|ax| format!("d{j}_{ax}_lvlh_m")));
        }
        names
    }
    fn command_len(&self) -> usize {
        3
    }
    fn command_names(&self) -> Vec<String> {
        ["u_x_lvlh_mps2", "u_y_lvlh_mps2", "u_z_lvlh_mps2"].map(String::from).to_vec()
    }
    fn build(&self, setup: &Setup) -> Box<dyn PlantModel> {
        Box::new(self.servicing(setup))
    }
    fn roster_warnings(&self, _s: &Scenario, live: &[bool]) -> Vec<String> {
        match trackability(&self.agents, live) {
            Some((rank, _)) if rank < 3 => vec![format!(
                "the defunct spacecraft is no longer trackable by the live servicers (Def. 1 of the Lb-DNN \
                 servicing paper): rank(Σ bᵢ CᵢᵀCᵢ) = {rank} < 3"
            )],
            _ => Vec::new(),
        }
    }
}

impl OrbitalSetup {
    /// The defunct's initial ECI state (periapsis of the configured orbit).
    pub fn defunct_initial_state(&self) -> (V3, V3) {
        let d = &self.config.defunct;
        periapsis_state(
            R_EARTH_M + d.periapsis_alt_m,
            R_EARTH_M + d.apoapsis_alt_m,
            d.inclination_rad,
            d.raan_rad,
            d.arg_periapsis_rad,
            MU_EARTH_M3PS2,
        )
    }

    /// Each servicer's start offset from the defunct in its initial LVLH frame, m: fixed by the
    /// scenario, or drawn from the seed (range, azimuth, elevation per agent in id order).
    pub fn initial_offsets(&self, seed: u64) -> Vec<[f64; 3]> {
        match &self.config.random_offsets {
            None => self.agents.iter().map(|a| a.offset_lvlh_m.expect("validated")).collect(),
            Some(ro) => {
                let mut rng = setup_rng(seed, "orbital.random_offsets");
                let mut draw = |lim: [f64; 2]| if lim[0] == lim[1] { lim[0] } else { rng.random_range(lim[0]..lim[1]) };
                self.agents
                    .iter()
                    .map(|_| {
                        let (sigma, gamma, phi) = (draw(ro.range_m), draw(ro.azimuth_rad), draw(ro.elevation_rad));
                        [sigma * phi.cos() * gamma.cos(), sigma * phi.cos() * gamma.sin(), sigma * phi.sin()]
                    })
                    .collect()
            }
        }
    }

    /// The plant model of this configuration (the servicers in id order).
    pub fn servicing(&self, s: &Scenario) -> ServicingPlant {
        let p = &self.config;
        let forces = EarthForces { mu_m3ps2: MU_EARTH_M3PS2, j2: if p.j2 { J2_EARTH } else { 0.0 }, drag: p.drag };
        let hold = match p.density_hold {
            DensityAt::Stage => DensityHold::Stage,
            DensityAt::Step => DensityHold::Step,
        };
        let (r0, v0) = self.defunct_initial_state();
        let frame0 = Lvlh::of(&r0, &v0);
        let d = &p.defunct;
        let mut bodies = vec![Body {
            props: BodyProps { mass_kg: d.mass_kg, area_m2: d.area_m2, drag_coeff: p.drag_coeff },
            r_eci_m: r0,
            v_eci_mps: v0,
        }];
        let mut sensing = Vec::new();
        for ((i, a), off) in (1..=s.n_agents()).zip(&self.agents).zip(self.initial_offsets(s.scenario.seed)) {
            bodies.push(Body {
                props: BodyProps {
                    mass_kg: a.mass_kg.expect("validated"),
                    area_m2: a.area_m2.expect("validated"),
                    drag_coeff: p.drag_coeff,
                },
                // Same inertial velocity as the defunct (Sec. 6).
                r_eci_m: r0 + frame0.to_eci(&V3::from_row_slice(&off)),
                v_eci_mps: v0,
            });
            sensing.push(Sensing {
                output_matrix: a.output_matrix.clone().expect("validated"),
                b: a.b() == 1,
                neighbours: s.agent(i).neighbours.clone(),
            });
        }
        ServicingPlant::new(forces, hold, p.substeps, bodies, sensing, p.noise_std_m, s.scenario.duration_s)
    }
}

// ---------------------------------------------------------------------------------------------
// Algorithm `lb-dnn-servicing`

/// ρ-filter observer (24)–(26), Lb-DNN controller (27), distributed adaptation (28).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct LbDnnServicing {
    pub k1: f64,
    pub k2: f64,
    pub k3: f64,
    pub k4: f64,
    pub k5: f64,
    /// Forgetting rate of the distributed adaptation.
    pub k6: f64,
    /// Learning rate: Γᵢ = gamma · I_p.
    pub gamma: f64,
    /// Projection bound: ‖θ̂ᵢ‖ ≤ theta_bar always.
    pub theta_bar: f64,
    /// Hidden-layer widths of the Lb-DNN (input 6 = [ηᵢ; ζ̂ᵢ], output 3).
    #[serde(default = "default_hidden")]
    pub hidden_layers: Vec<usize>,
    /// Width of the smooth projection's transition band, as a fraction of theta_bar: the
    /// projection starts acting at (1 − band)·theta_bar and removes the whole outward component
    /// at theta_bar.
    #[serde(default = "default_band")]
    pub projection_band: f64,
    /// Observer start; see [`ObserverInit`].
    #[serde(default = "default_observer_init")]
    pub observer_init: ObserverInit,
    /// Optional per-axis thrust-acceleration limit (a variant; the paper has none), m/s².
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub thrust_limit_mps2: Option<f64>,
}

/// `algorithm.observer_init`.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "kebab-case")]
pub enum ObserverInit {
    /// η̂ᵢ(0) = 0 (the paper's prose).
    Zero,
    /// η̂ᵢ(0) = ηᵢ(0).
    Measured,
}

fn default_hidden() -> Vec<usize> {
    vec![4, 4, 4, 4]
}
fn default_band() -> f64 {
    0.1
}
fn default_observer_init() -> ObserverInit {
    ObserverInit::Zero
}

impl LbDnnServicing {
    /// Layer sizes of the network: 6 inputs, the hidden layers, 3 outputs.
    pub fn layers(&self) -> Vec<usize> {
        std::iter::once(6).chain(self.hidden_layers.iter().copied()).chain(std::iter::once(3)).collect()
    }
    /// Number of weights p (biases included, as in (2)).
    pub fn n_weights(&self) -> usize {
        self.layers().windows(2).map(|w| (w[0] + 1) * w[1]).sum()
    }
}

pub struct LbDnnKind;

pub struct LbDnnSetup {
    pub config: LbDnnServicing,
}

impl AlgorithmKind for LbDnnKind {
    fn kind(&self) -> &'static str {
        "lb-dnn-servicing"
    }
    fn configure(
        &self,
        ctx: &ConfigureCtx<'_>,
        _plant: Option<&dyn PlantSetup>,
        c: &mut Checker,
    ) -> Option<Arc<dyn AlgorithmSetup>> {
        let a = section_as::<LbDnnServicing>(&ctx.scenario.algorithm.body, "algorithm", c);
        if ctx.scenario.plant.kind != OrbitalKind.kind() {
            c.fail("algorithm.kind", "\"lb-dnn-servicing\"", "needs plant.kind = \"orbital\"");
        }
        let a = a?;
        for (key, x) in [("k1", a.k1), ("k2", a.k2), ("k3", a.k3), ("k4", a.k4), ("k5", a.k5), ("k6", a.k6)] {
            c.positive(&format!("algorithm.{key}"), x);
        }
        c.positive("algorithm.gamma", a.gamma);
        c.positive("algorithm.theta_bar", a.theta_bar);
        if c.finite("algorithm.projection_band", a.projection_band)
            && !(a.projection_band > 0.0 && a.projection_band < 1.0)
        {
            c.fail("algorithm.projection_band", fmt_f64(a.projection_band), "must be in (0, 1)");
        }
        if a.hidden_layers.is_empty() {
            c.fail("algorithm.hidden_layers", "[]", "at least one hidden layer");
        }
        for (k, w) in a.hidden_layers.iter().enumerate() {
            if *w == 0 || *w > 256 {
                c.fail(format!("algorithm.hidden_layers[{k}]"), w, "widths must be 1..=256");
            }
        }
        if let Some(l) = a.thrust_limit_mps2 {
            c.positive("algorithm.thrust_limit_mps2", l);
        }
        Some(Arc::new(LbDnnSetup { config: a }))
    }
}

impl AlgorithmSetup for LbDnnSetup {
    fn kind(&self) -> &'static str {
        LbDnnKind.kind()
    }
    fn resolved(&self) -> Result<toml::Table, ConfigTableError> {
        table_of(&self.config)
    }
    fn share_values(&self, _s: &Scenario) -> usize {
        3 + self.config.n_weights()
    }
    fn build(&self, setup: &Setup, id: u32) -> Box<dyn Algorithm> {
        let plant = setup.plant_as::<OrbitalSetup>().expect("validated: lb-dnn-servicing needs the orbital plant");
        let a = &plant.agents[id as usize - 1];
        // Its random draws (initial weights) come from the agent's own seeded generator.
        let mut rng = process_rng(setup.scenario.seed, Proc::Agent(id));
        Box::new(crate::lbdnn_servicing::LbDnnServicing::new(
            self.config.clone(),
            a.output_matrix.clone().expect("validated: the orbital plant requires it"),
            a.b() == 1,
            setup.agent(id).neighbours.clone(),
            &mut rng,
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use cohort_runtime::paper::{Paper, load};

    const PAPERS: &[&dyn Paper] = &[&crate::Fig1, &cohort_kinds_generic::Generic];

    fn fig1() -> Setup {
        let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../topologies/fig1.toml");
        load(&path, &Default::default(), PAPERS).unwrap()
    }

    #[test]
    fn the_ring_survives_one_loss_but_not_two_opposite_ones() {
        let s = fig1();
        assert!(s.roster_warnings(&[true; 6]).is_empty());
        assert!(s.roster_warnings(&[true, true, false, true, true, true]).is_empty(), "a ring minus one is a path");
        let w = s.roster_warnings(&[true, true, false, true, true, false]);
        assert_eq!(w.len(), 1, "{w:?}");
        assert!(w[0].contains("{1, 2} and {4, 5}"), "{w:?}");
    }

    #[test]
    fn trackability_is_lost_when_the_full_rank_servicers_die() {
        let s = fig1();
        let plant = s.plant_as::<OrbitalSetup>().unwrap();
        assert_eq!(trackability(&plant.agents, &[true; 6]).unwrap().0, 3);
        // Servicers 4 and 5 carry three rows each; the others one or two.
        let w = s.roster_warnings(&[true, false, false, false, false, true]);
        assert!(w.iter().any(|m| m.contains("no longer trackable")), "{w:?}");
    }
}
