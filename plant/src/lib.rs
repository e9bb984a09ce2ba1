//! Cohort's plant: the truth models ([`models`]) and how a scenario selects one ([`build`]).

// Axis loops (`for a in 0..3`) read like the equations they implement; keep them.
#![allow(clippy::needless_range_loop)]

pub mod models;

use cohort_runtime::model::PlantModel;
use cohort_scenario::{AlgorithmConfig, OrbitalPlant, PlantConfig, Scenario};
use models::orbit::{
    BodyProps, DensityHold, EarthForces, J2_EARTH, Lvlh, MU_EARTH_M3PS2, R_EARTH_M, V3, periapsis_state,
};
use models::servicing::{Body, Sensing, ServicingPlant};
use rand::Rng;

/// The plant model a (validated) scenario asks for.
pub fn build(s: &Scenario) -> Box<dyn PlantModel> {
    match &s.plant {
        PlantConfig::DoubleIntegrator(p) => {
            let ids = 1..=s.n_agents();
            let r0 = ids.clone().map(|i| s.agent(i).r0_m.expect("validated")).collect();
            let v0 = ids.map(|i| s.agent(i).v0_mps.expect("validated")).collect();
            let slots = match &s.algorithm {
                AlgorithmConfig::ConsensusFormation(a) => {
                    (1..=s.n_agents()).map(|i| a.slot_m(i, s.n_agents())).collect()
                }
                _ => vec![[0.0; 3]; s.n_agents() as usize],
            };
            Box::new(models::double_integrator::DoubleIntegrator::new(r0, v0, p.position_noise_std_m, slots))
        }
        PlantConfig::Orbital(p) => Box::new(build_servicing(s, p)),
        PlantConfig::Null(p) => Box::new(models::null::NullPlant { readings: p.readings }),
        PlantConfig::RigidBody(p) => Box::new(models::rigid_body::RigidBodyPlant::new(
            &p.inertia_kg_m2,
            p.omega0_body_rad_s,
            p.q0_inertial_body,
            s.n_agents() as usize,
            p.substeps(s.scenario.dt_s),
            p.gyro_noise_std_rad_s,
        )),
        PlantConfig::TsnrNet(p) => {
            let mu = |i: usize| s.agent(i as u32 + 1);
            let r0 = std::array::from_fn(|i| mu(i).r0_m.expect("validated"));
            let v0 = std::array::from_fn(|i| mu(i).v0_mps.expect("validated"));
            let dt_s = s.scenario.dt_s;
            let plant = models::tsnr_net::TsnrNetPlant::new(
                p.net_params(),
                r0,
                v0,
                p.thrust_bound_n,
                dt_s,
                p.snapshot_steps(dt_s),
            );
            Box::new(plant.expect("validated: the net parameters passed NetParams::validate"))
        }
    }
}

/// The defunct's initial ECI state (periapsis of the configured orbit).
pub fn defunct_initial_state(p: &OrbitalPlant) -> (V3, V3) {
    let d = &p.defunct;
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
pub fn initial_offsets(s: &Scenario, p: &OrbitalPlant) -> Vec<[f64; 3]> {
    match &p.random_offsets {
        None => (1..=s.n_agents()).map(|i| s.agent(i).offset_lvlh_m.expect("validated")).collect(),
        Some(ro) => {
            let mut rng = cohort_runtime::rng::setup_rng(s.scenario.seed, "orbital.random_offsets");
            let mut draw = |lim: [f64; 2]| if lim[0] == lim[1] { lim[0] } else { rng.random_range(lim[0]..lim[1]) };
            (1..=s.n_agents())
                .map(|_| {
                    let (sigma, gamma, phi) = (draw(ro.range_m), draw(ro.azimuth_rad), draw(ro.elevation_rad));
                    [sigma * phi.cos() * gamma.cos(), sigma * phi.cos() * gamma.sin(), sigma * phi.sin()]
                })
                .collect()
        }
    }
}

pub fn build_servicing(s: &Scenario, p: &OrbitalPlant) -> ServicingPlant {
    let forces = EarthForces { mu_m3ps2: MU_EARTH_M3PS2, j2: if p.j2 { J2_EARTH } else { 0.0 }, drag: p.drag };
    let hold = if p.density_hold == "stage" { DensityHold::Stage } else { DensityHold::Step };
    let (r0, v0) = defunct_initial_state(p);
    let frame0 = Lvlh::of(&r0, &v0);
    let d = &p.defunct;
    let mut bodies = vec![Body {
        props: BodyProps { mass_kg: d.mass_kg, area_m2: d.area_m2, drag_coeff: p.drag_coeff },
        r_eci_m: r0,
        v_eci_mps: v0,
    }];
    let mut sensing = Vec::new();
    for (i, off) in (1..=s.n_agents()).zip(initial_offsets(s, p)) {
        let a = s.agent(i);
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
            neighbours: a.neighbours.clone(),
        });
    }
    ServicingPlant::new(forces, hold, p.substeps, bodies, sensing, p.noise_std_m, s.scenario.duration_s)
}
