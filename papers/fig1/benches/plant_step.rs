//! Plant cost per spacecraft-step: the fig1 orbital plant (two-body + J2 + drag, RK4, commands
//! rotated from the reference LVLH frame at every stage) advancing 7 bodies by 10 ms.
//! Target (issue 8): ≤ 0.5 µs per spacecraft-step.

use std::hint::black_box;

use cohort_astro::orbit::{BodyProps, DensityHold, EarthForces, R_EARTH_M, V3, rk4_step};
use cohort_runtime::model::PlantModel;
use criterion::{Criterion, criterion_group, criterion_main};

fn fig1_plant(c: &mut Criterion) {
    let path = concat!(env!("CARGO_MANIFEST_DIR"), "/../../topologies/fig1-fixed.toml");
    let papers: &[&'static dyn cohort_runtime::paper::Paper] =
        &[&cohort_paper_fig1::Fig1, &cohort_kinds_generic::Generic];
    let s =
        cohort_runtime::paper::load(std::path::Path::new(path), &Default::default(), papers).expect("fig1-fixed.toml");
    let p = s.plant_as::<cohort_paper_fig1::config::OrbitalSetup>().expect("fig1 has an orbital plant");
    let mut plant = p.servicing(&s);
    for i in 1..=6 {
        plant.apply_command(i, &[1e-3, -2e-3, 5e-4]);
    }
    let bodies = plant.bodies().len();
    c.bench_function(&format!("fig1 plant advance 10 ms ({bodies} bodies)"), |b| {
        b.iter(|| plant.advance(black_box(0.01)))
    });
}

fn one_body(c: &mut Criterion) {
    let forces = EarthForces::full();
    let body = BodyProps { mass_kg: 640.1074, area_m2: 10.1267, drag_coeff: 2.2 };
    let mut r = V3::new(R_EARTH_M + 300e3, 0.0, 0.0);
    let mut v = V3::new(0.0, 6787.28, 3918.64);
    let u = V3::new(1e-3, 0.0, 0.0);
    c.bench_function("one body RK4 step (two-body + J2 + drag)", |b| {
        b.iter(|| rk4_step(&forces, &body, DensityHold::Step, &mut r, &mut v, black_box(0.01), &|_| u))
    });
}

criterion_group!(benches, fig1_plant, one_body);
criterion_main!(benches);
