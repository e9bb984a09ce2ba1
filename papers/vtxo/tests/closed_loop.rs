//! Closed-loop checks of seed 002 in the in-process lockstep loop (short horizons; the long runs
//! are in `examples/vtxo_study.rs`).

use cohort_paper_vtxo::flight::config::{LeaderControl, RelativeController, RelativeNavigation, VtxoAlgorithmConfig};
use cohort_paper_vtxo::flight::layout::{COMMAND_LEN, READINGS_LEN};
use cohort_paper_vtxo::flight::mekf::MekfVariant;
use cohort_paper_vtxo::flight::relative_control::Switching;
use cohort_paper_vtxo::flight::share::{FOLLOWER_SHARE_LEN, LEADER_SHARE_LEN};
use cohort_paper_vtxo::formation::sim::Sim;
use cohort_paper_vtxo::model::config::{AttitudeDraw, VtxoPlantConfig};
use cohort_paper_vtxo::model::metrics::mekf_error_rad;
use cohort_paper_vtxo::model::quaternion::Quat;
use cohort_runtime::model::{Algorithm, PlantModel};

fn metric(sim: &Sim, name: &str) -> f64 {
    sim.plant.metrics().into_iter().find(|(k, _)| k == name).unwrap_or_else(|| panic!("no metric {name}")).1
}

fn col(agent: &dyn Algorithm, name: &str) -> usize {
    agent.columns().iter().position(|c| c == name).unwrap_or_else(|| panic!("no column {name}"))
}

#[test]
fn pd_reaches_the_formation_within_a_minute() {
    let mut a = VtxoAlgorithmConfig::default();
    a.relative.controller = RelativeController::Pd;
    let mut sim = Sim::new(&VtxoPlantConfig::default(), &a, 0.01, 1).unwrap();
    sim.run(6000);
    // Measured (seed 1): first inside 1 m at 9.66 s, settled from 19.06 s; a 2× regression fails.
    let t = metric(&sim, "formation_first_within_s");
    let settled = metric(&sim, "formation_settled_s");
    assert!(t > 9.66 / 1.9 && t < 9.66 * 1.9, "PD first inside 1 m at {t} s");
    assert!(settled > 19.06 / 1.9 && settled < 19.06 * 1.9, "PD settled at {settled} s");
    // The command at t = 0 is what (56) asks for: P·|r_rel(0) − r_f| ≈ 9.3 km/s² → ≈ 94 kN.
    let peak = metric(&sim, "follower_thrust_peak_n");
    assert!(peak > 9.0e4 && peak < 1.0e5, "peak thrust {peak} N");
}

/// Sec. 7's PD with every model on, 600 s: with v̂_rel dead-reckoned the accelerometer biases hold
/// the formation 1.4 mm off; the fusing filter estimates their difference and holds it at 15 µm
/// (seed 1, measured; the test fails at a tenth of that gain), and its b̂ finds the truth's.
#[test]
fn the_fusing_filter_removes_the_accelerometer_drift() {
    let run = |nav: RelativeNavigation| {
        let mut a = VtxoAlgorithmConfig::default();
        a.relative.controller = RelativeController::Pd;
        a.relative.navigation = nav;
        let mut sim = Sim::new(&VtxoPlantConfig::default(), &a, 0.01, 1).unwrap();
        sim.run(60_000);
        sim
    };
    let (dead, filt) = (run(RelativeNavigation::DeadReckoning), run(RelativeNavigation::Filter));
    let (d, f) = (metric(&dead, "transverse_rms_mm"), metric(&filt, "transverse_rms_mm"));
    assert!(d > 0.7 && d < 2.8, "dead reckoning {d} mm (measured 1.40)");
    assert!(f < 0.1 * d && f > 1e-4, "filter {f} mm against dead reckoning {d} mm (measured 0.0148)");
    // b̂ against the truth's differential bias (follower − leader), x and y.
    let follower = filt.agents[1].as_ref();
    let mut row = Vec::new();
    follower.row(&mut row);
    let b_hat = [row[col(follower, "accel_bias_hat_eci_x_mps2")], row[col(follower, "accel_bias_hat_eci_y_mps2")]];
    let c = &filt.plant.craft;
    let truth = c[1].sensors.accelerometer.bias.value - c[0].sensors.accelerometer.bias.value;
    // Seed 1 draws |b| of 2.4e-6 and 1.6e-6 m/s² on x and y, so "no estimate" (b̂ = 0) and a
    // wrong sign both fail; the filter's own 1σ is ≈ 2–4e-7 (the bias is an ECRV it keeps
    // forgetting, and the leader's reading arrives a step late).
    for ax in 0..2 {
        assert!(truth[ax].abs() > 1.5e-6, "axis {ax}: truth {truth:?}");
        assert!((b_hat[ax] - truth[ax]).abs() < 1e-6, "axis {ax}: b̂ {b_hat:?}, truth {truth:?}");
    }
}

/// The fraction of samples (per body axis, per agent) with |δθᵢ| ≤ 3σᵢ over `steps`.
fn mekf_fractions(variant: MekfVariant, steps: u64, seed: u64) -> [[f64; 3]; 2] {
    let mut p = VtxoPlantConfig::default();
    p.attitude.draw = AttitudeDraw::Science;
    let mut a = VtxoAlgorithmConfig::default();
    a.mekf.variant = variant;
    let mut sim = Sim::new(&p, &a, 0.01, seed).unwrap();
    let q_col = col(sim.agents[0].as_ref(), "q_hat_q1");
    let s_col = col(sim.agents[0].as_ref(), "sigma_theta_x_rad");
    let mut inside = [[0u64; 3]; 2];
    let mut row = Vec::new();
    sim.run_with(steps, &mut |_, plant, agents| {
        for i in 0..2 {
            row.clear();
            agents[i].row(&mut row);
            let q_hat = Quat::new(row[q_col], row[q_col + 1], row[q_col + 2], row[q_col + 3]);
            let e = mekf_error_rad(&plant.craft[i].attitude.q_body_eci, &q_hat);
            for ax in 0..3 {
                if e[ax].abs() <= 3.0 * row[s_col + ax] {
                    inside[i][ax] += 1;
                }
            }
        }
    });
    inside.map(|a| a.map(|c| c as f64 / steps as f64))
}

#[test]
fn mekf_truth_error_stays_inside_three_sigma() {
    for (variant, steps) in [(MekfVariant::ModelReplacement, 60_000), (MekfVariant::Full, 30_000)] {
        let f = mekf_fractions(variant, steps, 7);
        // A consistent filter misses ±3σ on 0.27 % of the samples; measured (seed 7): the
        // leader never, the follower on 0.25–0.31 % per axis. Twice that fails.
        for (who, axes) in ["leader", "follower"].iter().zip(f) {
            for (ax, frac) in axes.iter().enumerate() {
                assert!(*frac >= 0.994, "{variant:?} {who} axis {ax}: {frac} inside ±3σ over {steps} steps");
            }
        }
    }
}

#[test]
fn checkpoint_round_trip_is_bit_exact() {
    let mut a = VtxoAlgorithmConfig::default();
    a.leader.control = LeaderControl::Smc;
    // The follower's filter state (x, P per axis) rides in the checkpoint too.
    a.relative.navigation = RelativeNavigation::Filter;
    let p = VtxoPlantConfig::default();
    let rows_after = |sim: &mut Sim, n: u64| {
        let mut rows = Vec::new();
        sim.run_with(n, &mut |_, plant, agents| {
            let mut r = Vec::new();
            plant.row(&mut r);
            for ag in agents {
                ag.row(&mut r);
            }
            rows.push(r.iter().map(|x| x.to_bits()).collect::<Vec<u64>>());
        });
        rows
    };
    let mut straight = Sim::new(&p, &a, 0.01, 3).unwrap();
    straight.run(500);
    let want = rows_after(&mut straight, 500);

    let mut resumed = Sim::new(&p, &a, 0.01, 3).unwrap();
    resumed.run(500);
    let saved: Vec<Vec<u8>> = resumed.agents.iter().map(|ag| ag.save_state()).collect();
    for (i, bytes) in saved.iter().enumerate() {
        let mut fresh = cohort_paper_vtxo::formation::build_agent(&a, i as u32 + 1).unwrap();
        fresh.restore_state(bytes).unwrap();
        assert_eq!(&fresh.save_state(), bytes, "agent {} re-encodes differently", i + 1);
        resumed.agents[i] = fresh;
    }
    assert_eq!(rows_after(&mut resumed, 500), want);
    // A damaged state is refused and leaves the agent as it was.
    let before = resumed.agents[0].save_state();
    assert!(resumed.agents[0].restore_state(&saved[0][..saved[0].len() / 2]).is_err());
    assert_eq!(resumed.agents[0].save_state(), before);
}

#[test]
fn same_seed_gives_identical_telemetry_and_another_seed_does_not() {
    let run = |seed: u64| {
        let mut sim = Sim::new(&VtxoPlantConfig::default(), &VtxoAlgorithmConfig::default(), 0.01, seed).unwrap();
        sim.run(300);
        let mut r = Vec::new();
        sim.plant.row(&mut r);
        r.iter().map(|x| x.to_bits()).collect::<Vec<u64>>()
    };
    assert_eq!(run(5), run(5));
    assert_ne!(run(5), run(6));
}

#[test]
fn message_sizes_are_within_the_wire_bounds() {
    let mut sim = Sim::new(&VtxoPlantConfig::default(), &VtxoAlgorithmConfig::default(), 0.01, 1).unwrap();
    let cols = sim.plant.columns();
    let mut row = Vec::new();
    sim.plant.row(&mut row);
    assert_eq!(cols.len(), row.len());
    for ag in &sim.agents {
        let mut r = Vec::new();
        ag.row(&mut r);
        assert_eq!(ag.columns().len(), r.len());
    }
    sim.step();
    let mut readings = Vec::new();
    let mut rng = cohort_runtime::rng::setup_rng(1, "test");
    sim.plant.readings(2, &mut rng, &mut readings);
    assert_eq!(readings.len(), READINGS_LEN);
    let shares = sim.last_shares();
    assert_eq!(shares[0].values.len(), LEADER_SHARE_LEN);
    assert_eq!(shares[1].values.len(), FOLLOWER_SHARE_LEN);
    for s in shares {
        assert_eq!(s.command.len(), COMMAND_LEN);
    }
}

/// Every noise, bias and actuator error of the plant off, the follower started `start_mm` (x, y)
/// off its target, at rest.
fn ideal_plant(start_mm: [f64; 2]) -> VtxoPlantConfig {
    let mut p = VtxoPlantConfig::default();
    p.disturbances.torque_noise_3sigma_n_m = 0.0;
    p.disturbances.force_3sigma_n = 0.0;
    let w = &mut p.wheels;
    (w.scale_3sigma, w.misalignment_3sigma_rad, w.noise_3sigma_n_m, w.bias_3sigma_n_m, w.bias0_3sigma_n_m) =
        (0.0, 0.0, 0.0, 0.0, 0.0);
    let t = &mut p.thrusters;
    (t.scale_3sigma, t.noise_3sigma_n, t.bias_3sigma_n, t.bias0_3sigma_n) = (0.0, 0.0, 0.0, 0.0);
    let s = &mut p.sensors;
    (s.gyro.scale_3sigma, s.gyro.misalignment_3sigma_rad, s.gyro.noise_3sigma_rad_s, s.gyro.bias_3sigma_rad_s) =
        (0.0, 0.0, 0.0, 0.0);
    for st in [&mut s.star_tracker_leader, &mut s.star_tracker_follower] {
        (st.noise_3sigma_rad, st.bias_3sigma_rad) = (0.0, 0.0);
    }
    (s.accelerometer.noise_3sigma_mps2, s.accelerometer.bias_3sigma_mps2) = (0.0, 0.0);
    for r in [&mut s.ranging, &mut s.interferometer] {
        (r.noise_3sigma_m, r.bias_3sigma_m) = (0.0, 0.0);
    }
    p.orbit.r_rel0_eci_m = [start_mm[0] * 1e-3, start_mm[1] * 1e-3, 1000.01];
    p.orbit.v_rel0_eci_mps = [0.0; 3];
    p
}

/// The follower's largest |x| and |y| offset from its target over the last `window_s` of a run, m.
fn ideal_offsets(switching: Switching, dt_s: f64, start_mm: [f64; 2]) -> [f64; 2] {
    let p = ideal_plant(start_mm);
    let mut a = VtxoAlgorithmConfig::default();
    a.relative.switching = switching;
    let mut sim = Sim::new(&p, &a, dt_s, 1).unwrap();
    let n = (60.0 / dt_s).round() as u64;
    let from = n - (p.metrics.transverse_window_s / dt_s).round() as u64;
    let mut worst = [0.0f64; 2];
    sim.run_with(n, &mut |k, plant, _| {
        if k >= from {
            let e = plant.orbit.r_rel_eci_m - plant.r_target_eci_m;
            worst = [worst[0].max(e.x.abs()), worst[1].max(e.y.abs())];
        }
    });
    worst
}

/// The sign law under a zero-order hold cannot stay on s = 0: it ends in a two-step cycle whose
/// offset per axis lies within ±Z·dt/(2k). Measured in the ideal loop (no noise, bias or actuator
/// error), 60 s from 10 mm and from (12.3, 17.7) mm off the target, over the last 15 s: the offset
/// stays inside the band and, from at least one start, fills most of it, at 10 ms and at 1 ms — so
/// it scales with dt; the saturated law (67) leaves nothing of the kind.
#[test]
fn the_sign_law_ends_inside_its_zero_order_hold_band_which_scales_with_dt() {
    let g = VtxoAlgorithmConfig::default().relative.smc;
    for dt in [0.01, 0.001] {
        let band = |ax: usize| g.z_mps2[ax] * dt / (2.0 * g.k);
        let mut fill = 0.0f64;
        for start in [[10.0, 10.0], [12.3, 17.7]] {
            let off = ideal_offsets(Switching::Sign, dt, start);
            for (ax, o) in off.iter().enumerate() {
                let b = band(ax);
                assert!(*o <= b * 1.01, "dt {dt} s, start {start:?}, axis {ax}: {o} m > band {b} m");
                fill = fill.max(o / b);
            }
            let sat = ideal_offsets(Switching::Sat, dt, start);
            assert!(sat.iter().all(|o| *o < 1e-3 * band(0)), "sat law, dt {dt} s: {sat:?}");
        }
        assert!(fill > 0.6, "dt {dt} s: the offset fills only {fill} of the band");
    }
}
