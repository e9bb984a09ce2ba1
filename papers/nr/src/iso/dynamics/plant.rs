//! The `iso-encounter` plant: the truth of one ISO and K spacecraft in heliocentric inertial
//! coordinates (two-body about the Sun), each spacecraft's thrust held in inertial axes over the
//! control interval, its mass falling by the rocket equation (ṁ = −‖u‖/(I_sp g₀)), and each
//! step's navigation readings ([`crate::iso::dynamics::navigation`], [`crate::iso::dynamics::messages`]). Set-up of
//! [`crate::iso::dynamics::iso_set`]; "Neural-Rendezvous" (arXiv:2208.04883), Secs. 2 and 6.
//!
//! Departures: the thrust is limited to ‖u‖ ≤ √3·u_max (the smallest ball holding the per-axis box
//! in any orientation, so no command within the per-axis limit of the agent's frame is ever cut;
//! a cut is counted). The delivery error is the true ‖p(t_f) − ρ_f‖ in the true ISO's LVLH frame,
//! taken when the clock reaches t_f.

use cohort_runtime::model::PlantModel;
use rand_chacha::ChaCha8Rng;

use crate::iso::dynamics::constants::G0_MPS2;
use crate::iso::dynamics::iso_set;
use crate::iso::dynamics::lvlh::{IsoFrame, pos};
use crate::iso::dynamics::messages::Reading;
use crate::iso::dynamics::navigation::{self, NavSigmas};
use crate::iso::dynamics::two_body::{Inertial, V3};

/// What the plant needs besides the encounter (checked by `config`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PlantParams {
    pub t_f_s: f64,
    pub m0_kg: f64,
    pub u_max_n: f64,
    pub isp_s: f64,
    pub nav_scale: f64,
    pub nav: NavSigmas,
    pub substeps: u32,
}

/// One spacecraft's truth and accounts.
#[derive(Debug, Clone, PartialEq)]
struct Craft {
    state: Inertial,
    m_kg: f64,
    dv_mps: f64,
    u_n: V3,
    rho_f_m: V3,
    clamped_steps: u64,
    /// (delivery error, true p) when the clock reached t_f.
    at_tf: Option<(f64, V3)>,
}

pub struct IsoEncounterPlant {
    p: PlantParams,
    iso_index: u32,
    t_s: f64,
    iso: Inertial,
    craft: Vec<Craft>,
    /// Control intervals advanced so far.
    steps: u64,
}

impl IsoEncounterPlant {
    /// ISO `iso_index` of the set `set_seed` with `n_craft` spacecraft, the true start dispersed
    /// about the ideal one by `dispersion_scale`·Σ(0).
    pub fn new(
        p: PlantParams,
        set_seed: u64,
        iso_index: u32,
        n_craft: u32,
        rho_radius_m: f64,
        dispersion_scale: f64,
    ) -> Self {
        let sigma0 = p.nav.at(0.0, p.t_f_s, dispersion_scale);
        let mut iso = None;
        let craft = (0..n_craft)
            .map(|j| {
                let ideal = iso_set::ideal(set_seed, iso_index, j, p.t_f_s, rho_radius_m);
                let (iso0, sc0) = iso_set::dispersed_start(set_seed, iso_index, &ideal.at(0.0), j, &sigma0);
                iso = Some(iso0);
                Craft {
                    state: sc0,
                    m_kg: p.m0_kg,
                    dv_mps: 0.0,
                    u_n: V3::zeros(),
                    rho_f_m: ideal.rho_f_m,
                    clamped_steps: 0,
                    at_tf: None,
                }
            })
            .collect();
        let iso = iso.unwrap_or_else(|| iso_set::ideal(set_seed, iso_index, 0, p.t_f_s, rho_radius_m).at(0.0).0);
        Self { p, iso_index, t_s: 0.0, iso, craft, steps: 0 }
    }

    pub fn iso_index(&self) -> u32 {
        self.iso_index
    }

    /// Spacecraft `j`'s (0-based) true state relative to the true ISO and its ρ_f.
    pub fn truth(&self, j: usize) -> (crate::iso::dynamics::lvlh::X6, V3) {
        let c = &self.craft[j];
        (IsoFrame::of(&self.iso).relative(&c.state), c.rho_f_m)
    }

    /// Delivery error of spacecraft `j` at t_f (None before the clock reached it), m.
    pub fn delivery_error_m(&self, j: usize) -> Option<f64> {
        self.craft[j].at_tf.map(|(e, _)| e)
    }

    /// Δv spent by spacecraft `j`, ∫‖u‖/m dt, m/s.
    pub fn dv_mps(&self, j: usize) -> f64 {
        self.craft[j].dv_mps
    }

    pub fn t_s(&self) -> f64 {
        self.t_s
    }

    fn miss(&self, c: &Craft) -> (f64, V3) {
        let p = pos(&IsoFrame::of(&self.iso).relative(&c.state));
        ((p - c.rho_f_m).norm(), p)
    }
}

impl PlantModel for IsoEncounterPlant {
    /// Heliocentric inertial positions: the Sun is the origin.
    fn positions_m(&self, out: &mut Vec<[f64; 3]>) -> bool {
        out.extend(self.craft.iter().map(|c| [c.state.r_m[0], c.state.r_m[1], c.state.r_m[2]]));
        true
    }
    fn columns(&self) -> Vec<String> {
        let mut c = Vec::new();
        for j in 1..=self.craft.len() {
            for name in ["p_x_m", "p_y_m", "p_z_m", "miss_m", "mass_kg", "dv_mps", "u_x_n", "u_y_n", "u_z_n"] {
                c.push(format!("a{j}_{name}"));
            }
        }
        c
    }

    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let Some(c) = self.craft.get((agent as usize).wrapping_sub(1)) else { return };
        let sigma = self.p.nav.at(self.t_s, self.p.t_f_s, self.p.nav_scale);
        let iso_hat = navigation::draw(&self.iso, &sigma, rng);
        let sc_hat = navigation::draw(&c.state, &sigma, rng);
        Reading {
            x_hat: IsoFrame::of(&iso_hat).relative(&sc_hat),
            iso_hat,
            m_kg: c.m_kg,
            sigma,
            t_f_s: self.p.t_f_s,
            rho_f_m: c.rho_f_m,
            u_max_n: self.p.u_max_n,
            isp_s: self.p.isp_s,
        }
        .write(out);
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        let limit = 3f64.sqrt() * self.p.u_max_n;
        let Some(c) = self.craft.get_mut((agent as usize).wrapping_sub(1)) else { return };
        let mut u = V3::from_fn(|a, _| command.get(a).copied().filter(|x| x.is_finite()).unwrap_or(0.0));
        if u.norm() > limit {
            u *= limit / u.norm();
            c.clamped_steps += 1;
        }
        c.u_n = u;
    }

    fn advance(&mut self, dt_s: f64) {
        let n = self.p.substeps.max(1);
        let h = dt_s / n as f64;
        let ve = self.p.isp_s * G0_MPS2;
        for _ in 0..n {
            for c in &mut self.craft {
                let (m0, u) = (c.m_kg, c.u_n);
                let mdot = u.norm() / ve;
                c.state.step(h, &|tau| u / (m0 - mdot * tau));
                c.m_kg = m0 - mdot * h;
                c.dv_mps += ve * (m0 / c.m_kg).ln();
            }
            self.iso.step(h, &|_| V3::zeros());
        }
        self.t_s += dt_s;
        self.steps += 1;
        if (self.t_s - self.p.t_f_s).abs() <= 1e-6 * dt_s {
            let misses: Vec<_> = self.craft.iter().map(|c| self.miss(c)).collect();
            for (c, m) in self.craft.iter_mut().zip(misses) {
                c.at_tf.get_or_insert(m);
            }
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        for c in &self.craft {
            let (miss, p) = self.miss(c);
            out.extend(p.iter());
            out.extend([miss, c.m_kg, c.dv_mps]);
            out.extend(c.u_n.iter());
        }
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        let mut m = vec![("iso_index".to_string(), f64::from(self.iso_index))];
        let mut worst = 0.0f64;
        for (j, c) in self.craft.iter().enumerate() {
            let j = j + 1;
            match c.at_tf {
                Some((e, _)) => {
                    m.push((format!("a{j}_delivery_error_m"), e));
                    worst = worst.max(e);
                }
                None => m.push((format!("a{j}_miss_at_end_m"), self.miss(c).0)),
            }
            m.push((format!("a{j}_dv_mps"), c.dv_mps));
            m.push((format!("a{j}_thrust_clamped_steps"), c.clamped_steps as f64));
        }
        if self.craft.iter().all(|c| c.at_tf.is_some()) {
            m.push(("max_delivery_error_m".to_string(), worst));
        }
        m
    }

    /// `snapshots/encounter.csv`: one row (`k`, `t_s` at the end of the run) with each
    /// spacecraft's true p and ρ_f at t_f (or at the end, if the run stopped before t_f), its
    /// miss, mass, Δv and clamp count, and whether t_f was reached: what the per-step rows (the
    /// state at each t_k before its command) never hold.
    fn extra_telemetry(&self) -> Vec<(String, String)> {
        vec![(ENCOUNTER_FILE.to_string(), self.encounter_csv())]
    }
}

/// The plant's end-of-run file in the run's `snapshots/` (see `extra_telemetry`).
pub const ENCOUNTER_FILE: &str = "encounter.csv";
/// Its columns per spacecraft j (prefixed `a{j}_`).
pub const ENCOUNTER_COLUMNS: [&str; 11] = [
    "p_x_m",
    "p_y_m",
    "p_z_m",
    "rho_f_x_m",
    "rho_f_y_m",
    "rho_f_z_m",
    "miss_m",
    "mass_kg",
    "dv_mps",
    "thrust_clamped_steps",
    "reached_t_f",
];

impl IsoEncounterPlant {
    fn encounter_csv(&self) -> String {
        let mut header = vec!["k".to_string(), "t_s".to_string()];
        let mut row = vec![self.steps.to_string(), format!("{:?}", self.t_s)];
        for (j, c) in self.craft.iter().enumerate() {
            header.extend(ENCOUNTER_COLUMNS.iter().map(|n| format!("a{}_{n}", j + 1)));
            let (miss, p) = c.at_tf.unwrap_or_else(|| self.miss(c));
            let values = [
                p.x,
                p.y,
                p.z,
                c.rho_f_m.x,
                c.rho_f_m.y,
                c.rho_f_m.z,
                miss,
                c.m_kg,
                c.dv_mps,
                c.clamped_steps as f64,
                if c.at_tf.is_some() { 1.0 } else { 0.0 },
            ];
            // Rust's shortest round-trip form, as in every telemetry file.
            row.extend(values.iter().map(|v| format!("{v:?}")));
        }
        format!("{}\n{}\n", header.join(","), row.join(","))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::iso::dynamics::constants::{ISO_SET_SEED, T_F_S};
    use rand::SeedableRng;

    fn params(nav_scale: f64) -> PlantParams {
        PlantParams {
            t_f_s: T_F_S,
            m0_kg: 500.0,
            u_max_n: 1.0,
            isp_s: 220.0,
            nav_scale,
            nav: NavSigmas::default(),
            substeps: 1,
        }
    }

    #[test]
    fn two_body_energy_of_every_body_drifts_below_1e_10_over_a_day() {
        let mut plant = IsoEncounterPlant::new(params(1.0), ISO_SET_SEED, 3, 2, 100e3, 1.0);
        let e0: Vec<f64> =
            std::iter::once(&plant.iso).chain(plant.craft.iter().map(|c| &c.state)).map(|b| b.energy_jpkg()).collect();
        for _ in 0..144 {
            plant.advance(600.0);
        }
        let e1: Vec<f64> =
            std::iter::once(&plant.iso).chain(plant.craft.iter().map(|c| &c.state)).map(|b| b.energy_jpkg()).collect();
        for (a, b) in e0.iter().zip(&e1) {
            let d = ((b - a) / a).abs();
            eprintln!("relative two-body energy drift over one day: {d:.3e}");
            assert!(d <= 1e-10, "relative energy drift {d:e}");
        }
    }

    #[test]
    fn without_dispersion_or_thrust_the_spacecraft_arrives_at_rho_f() {
        let mut plant = IsoEncounterPlant::new(params(1.0), ISO_SET_SEED, 250, 1, 100e3, 0.0);
        for _ in 0..144 {
            plant.advance(600.0);
        }
        let e = plant.delivery_error_m(0).expect("t_f reached");
        assert!(e < 1e-2, "{e} m");
        assert_eq!(plant.dv_mps(0), 0.0);
    }

    #[test]
    fn thrust_spends_mass_by_the_rocket_equation_and_is_limited() {
        let mut plant = IsoEncounterPlant::new(params(1.0), ISO_SET_SEED, 1, 1, 100e3, 1.0);
        plant.apply_command(1, &[1.0, 0.0, 0.0]);
        plant.advance(600.0);
        let m1 = 500.0 - 600.0 / (220.0 * G0_MPS2);
        assert!((plant.craft[0].m_kg - m1).abs() < 1e-12);
        assert!((plant.dv_mps(0) - 220.0 * G0_MPS2 * (500.0 / m1).ln()).abs() < 1e-12);
        plant.apply_command(1, &[5.0, 0.0, 0.0]);
        assert_eq!((plant.craft[0].u_n.x, plant.craft[0].clamped_steps), (3f64.sqrt(), 1));
        plant.apply_command(1, &[f64::NAN]);
        assert_eq!(plant.craft[0].u_n, V3::zeros());
    }

    #[test]
    fn readings_are_the_truth_when_navigation_is_perfect_and_noisy_otherwise() {
        let mut rng = ChaCha8Rng::seed_from_u64(5);
        let mut plant = IsoEncounterPlant::new(params(0.0), ISO_SET_SEED, 7, 1, 100e3, 1.0);
        let mut out = Vec::new();
        plant.readings(1, &mut rng, &mut out);
        let r = Reading::parse(&out).unwrap();
        let (x, rho) = plant.truth(0);
        assert!((r.x_hat - x).norm() < 1e-3 && r.rho_f_m == rho);
        let mut noisy = IsoEncounterPlant::new(params(1.0), ISO_SET_SEED, 7, 1, 100e3, 1.0);
        out.clear();
        noisy.readings(1, &mut rng, &mut out);
        let r = Reading::parse(&out).unwrap();
        let d = (pos(&r.x_hat) - pos(&x)).norm();
        assert!(d > 100.0 && d < 1e6, "{d}");
        assert_eq!(r.sigma.pos_along_m, 100e3);
    }
}
