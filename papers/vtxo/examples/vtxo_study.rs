//! The seed-002 measurements of the crate README, in-process (release build):
//!
//!   cargo run --release -p cohort-paper-vtxo --example vtxo_study -- [SECTION...]
//!
//! SECTION: `sec7` (the Sec. 7 case, SMC-sign / SMC-sat / PD at dt 10 ms and 1 ms, 9 300 s, all
//! models), `seeds` (the same at 10 ms for seeds 1–5), `band` (the sliding band Z·dt/(2k) of the
//! sign law under a zero-order hold: the same laws with the accelerometer bias off, and the ideal loop without any noise or
//! actuator error started 1 cm from the target: `ideal`), `mekf` (3σ consistency over 1 h, both filters,
//! both agents), `science` (the Table 5 analogue: 100 seeds of the science phase, PD and SMC
//! attitude), `leader` (both spacecraft controlling, (70) with (66)), `orbit` (the orbit period
//! with and without J2), `sources` (the Sec. 7 case with no noise, each noise source alone, and
//! all, each law at 10 ms and 1 ms, two threads), `fused` (the same case by noise set with the
//! paper's dead-reckoned v̂_rel and with the fusing filter, two threads), `table5` (Table 5 by step
//! and by reading of the wheel bias, two threads). No section: all of them
//! (≈ 12 min on one core, and `sources` 8.7 min on two). Tables go to stdout as markdown.

use std::time::Instant;

use cohort_host::campaign::Campaign;
use cohort_paper_vtxo::flight::config::{
    LeaderControl, RelativeController, RelativeNavigation, ScienceAttitude, VtxoAlgorithmConfig,
};
use cohort_paper_vtxo::flight::mekf::MekfVariant;
use cohort_paper_vtxo::flight::relative_control::Switching;
use cohort_paper_vtxo::formation::sim::Sim;
use cohort_paper_vtxo::learn::science::sim as science_sim;
use cohort_paper_vtxo::model::config::{AttitudeDraw, VtxoPlantConfig};
use cohort_paper_vtxo::model::metrics::mekf_error_rad;
use cohort_paper_vtxo::model::orbit::{Gravity, MU_EARTH_M3PS2, OrbitPair, V3};
use cohort_paper_vtxo::model::orbit_setup::{Elements, kepler_period_s, state_from_elements};
use cohort_paper_vtxo::model::quaternion::Quat;
use cohort_runtime::model::PlantModel;

#[derive(Clone, Copy, PartialEq)]
enum Law {
    SmcSign,
    SmcSat,
    Pd,
}

impl Law {
    const ALL: [Law; 3] = [Law::SmcSign, Law::SmcSat, Law::Pd];
    fn name(self) -> &'static str {
        match self {
            Law::SmcSign => "SMC-sign",
            Law::SmcSat => "SMC-sat",
            Law::Pd => "PD",
        }
    }
    fn apply(self, a: &mut VtxoAlgorithmConfig) {
        match self {
            Law::SmcSign => a.relative.switching = Switching::Sign,
            Law::SmcSat => a.relative.switching = Switching::Sat,
            Law::Pd => a.relative.controller = RelativeController::Pd,
        }
    }
}

fn metric(m: &[(String, f64)], name: &str) -> f64 {
    m.iter().find(|(k, _)| k == name).map_or(f64::NAN, |(_, v)| *v)
}

struct Run {
    metrics: Vec<(String, f64)>,
    wall_s: f64,
    /// Mean of the follower's sliding vector (x, y) over the window, m/s.
    s_mean: [f64; 2],
}

fn run(p: &VtxoPlantConfig, a: &VtxoAlgorithmConfig, dt_s: f64, t_end_s: f64, seed: u64) -> Run {
    let mut sim = Sim::new(p, a, dt_s, seed).expect("valid study configuration");
    let n = (t_end_s / dt_s).round() as u64;
    let window_from = n.saturating_sub((p.metrics.transverse_window_s / dt_s).round() as u64);
    let s_col = sim.agents[1].columns().iter().position(|c| c == "s_eci_x_mps").expect("follower column");
    let (mut s_sum, mut s_n) = ([0.0; 2], 0.0f64);
    let mut row = Vec::new();
    let t0 = Instant::now();
    sim.run_with(n, &mut |k, _, agents| {
        if k >= window_from {
            row.clear();
            agents[1].row(&mut row);
            s_sum[0] += row[s_col];
            s_sum[1] += row[s_col + 1];
            s_n += 1.0;
        }
    });
    Run { metrics: sim.plant.metrics(), wall_s: t0.elapsed().as_secs_f64(), s_mean: s_sum.map(|s| s / s_n.max(1.0)) }
}

fn header() {
    println!(
        "| case | dt | horizon s | first < 1 m (s) | settled (s) | transverse RMS (mm) | transverse max (mm) | range error end (m) | peak thrust F (N) | Δv F (m/s) | impulse F (N·s) | e mean / P99 L (deg) | e mean / P99 F (deg) | wall s |"
    );
    println!("|---|---|---|---|---|---|---|---|---|---|---|---|---|---|");
}

fn line(case: &str, dt: f64, t_end: f64, r: &Run) {
    let m = &r.metrics;
    let g = |k: &str| metric(m, k);
    println!(
        "| {case} | {} ms | {t_end} | {:.2} | {:.2} | {:.4} | {:.4} | {:.3} | {:.1} | {:.0} | {:.0} | {:.3} / {:.3} | {:.3} / {:.3} | {:.0} |",
        dt * 1e3,
        g("formation_first_within_s"),
        g("formation_settled_s"),
        g("transverse_rms_mm"),
        g("transverse_max_mm"),
        g("range_error_end_m"),
        g("follower_thrust_peak_n"),
        g("follower_delta_v_mps"),
        g("follower_impulse_n_s"),
        g("leader_attitude_error_mean_deg"),
        g("leader_attitude_error_p99_deg"),
        g("follower_attitude_error_mean_deg"),
        g("follower_attitude_error_p99_deg"),
        r.wall_s
    );
}

fn sec7() {
    println!("\n### Sec. 7 case, all models (seed 1)\n");
    header();
    for dt in [0.01, 0.001] {
        for law in Law::ALL {
            let mut a = VtxoAlgorithmConfig::default();
            law.apply(&mut a);
            let r = run(&VtxoPlantConfig::default(), &a, dt, 9300.0, 1);
            line(law.name(), dt, 9300.0, &r);
        }
    }
}

fn seeds() {
    println!("\n### Sec. 7 case, all models, dt 10 ms, seeds 1–5: transverse RMS / max over the last 15 s (mm)\n");
    println!("| law | seed 1 | seed 2 | seed 3 | seed 4 | seed 5 |");
    println!("|---|---|---|---|---|---|");
    for law in Law::ALL {
        let mut cells = Vec::new();
        for seed in 1..=5 {
            let mut a = VtxoAlgorithmConfig::default();
            law.apply(&mut a);
            let r = run(&VtxoPlantConfig::default(), &a, 0.01, 9300.0, seed);
            cells.push(format!(
                "{:.3} / {:.3}",
                metric(&r.metrics, "transverse_rms_mm"),
                metric(&r.metrics, "transverse_max_mm")
            ));
        }
        println!("| {} | {} |", law.name(), cells.join(" | "));
    }
}

/// Every noise, bias and actuator error off.
fn ideal(p: &mut VtxoPlantConfig) {
    p.disturbances.torque_noise_3sigma_n_m = 0.0;
    p.disturbances.force_3sigma_n = 0.0;
    p.wheels = zero_wheel_errors();
    p.thrusters.scale_3sigma = 0.0;
    p.thrusters.noise_3sigma_n = 0.0;
    p.thrusters.bias_3sigma_n = 0.0;
    p.thrusters.bias0_3sigma_n = 0.0;
    let s = &mut p.sensors;
    s.gyro.scale_3sigma = 0.0;
    s.gyro.misalignment_3sigma_rad = 0.0;
    s.gyro.noise_3sigma_rad_s = 0.0;
    s.gyro.bias_3sigma_rad_s = 0.0;
    for st in [&mut s.star_tracker_leader, &mut s.star_tracker_follower] {
        st.noise_3sigma_rad = 0.0;
        st.bias_3sigma_rad = 0.0;
    }
    s.accelerometer.noise_3sigma_mps2 = 0.0;
    s.accelerometer.bias_3sigma_mps2 = 0.0;
    for r in [&mut s.ranging, &mut s.interferometer] {
        r.noise_3sigma_m = 0.0;
        r.bias_3sigma_m = 0.0;
    }
}

fn zero_wheel_errors() -> cohort_paper_vtxo::model::config::WheelConfig {
    cohort_paper_vtxo::model::config::WheelConfig {
        scale_3sigma: 0.0,
        misalignment_3sigma_rad: 0.0,
        noise_3sigma_n_m: 0.0,
        bias_3sigma_n_m: 0.0,
        bias0_3sigma_n_m: 0.0,
        bias_tau_s: 3600.0,
    }
}

fn band() {
    println!("\n### Sliding band Z·dt/(2k): Sec. 7 case with the accelerometer bias off (seed 1)\n");
    header();
    for dt in [0.01, 0.001] {
        for law in Law::ALL {
            let mut p = VtxoPlantConfig::default();
            p.sensors.accelerometer.bias_3sigma_mps2 = 0.0;
            let mut a = VtxoAlgorithmConfig::default();
            law.apply(&mut a);
            let r = run(&p, &a, dt, 9300.0, 1);
            line(&format!("{} (no accel. bias)", law.name()), dt, 9300.0, &r);
        }
    }
}

fn ideal_band() {
    println!("\n### Sliding band: ideal loop (no noise, no bias, no actuator error), 60 s from a small offset\n");
    println!(
        "| law | dt | start offset x, y (mm) | transverse RMS (mm) | transverse max (mm) | mean s_x, s_y over the last 15 s (mm/s) | Z·dt/(2k) (mm) |"
    );
    println!("|---|---|---|---|---|---|---|");
    for dt in [0.01, 0.001, 0.0001] {
        for law in Law::ALL {
            for start in [[10.0, 10.0], [12.3, 17.7]] {
                let mut p = VtxoPlantConfig::default();
                ideal(&mut p);
                p.orbit.r_rel0_eci_m = [start[0] * 1e-3, start[1] * 1e-3, 1000.01];
                p.orbit.v_rel0_eci_mps = [0.0; 3];
                let mut a = VtxoAlgorithmConfig::default();
                law.apply(&mut a);
                let r = run(&p, &a, dt, 60.0, 1);
                println!(
                    "| {} | {} ms | {}, {} | {:.3e} | {:.3e} | {:.3e}, {:.3e} | {:.3} |",
                    law.name(),
                    dt * 1e3,
                    start[0],
                    start[1],
                    metric(&r.metrics, "transverse_rms_mm"),
                    metric(&r.metrics, "transverse_max_mm"),
                    r.s_mean[0] * 1e3,
                    r.s_mean[1] * 1e3,
                    1.0 * dt / 2.0 * 1e3
                );
            }
        }
    }
}

/// The plant with every noise, bias and actuator error off but the group `source`, as the
/// defaults have it ("none": the ideal loop; "all": the defaults).
fn only(source: &str) -> VtxoPlantConfig {
    let d = VtxoPlantConfig::default();
    let mut p = d.clone();
    ideal(&mut p);
    match source {
        "disturbances" => p.disturbances = d.disturbances.clone(),
        "wheels" => p.wheels = d.wheels.clone(),
        "thrusters" => p.thrusters = d.thrusters.clone(),
        "attitude sensors" => {
            p.sensors.gyro = d.sensors.gyro.clone();
            p.sensors.star_tracker_leader = d.sensors.star_tracker_leader.clone();
            p.sensors.star_tracker_follower = d.sensors.star_tracker_follower.clone();
        }
        "accelerometer noise" => p.sensors.accelerometer.noise_3sigma_mps2 = d.sensors.accelerometer.noise_3sigma_mps2,
        "accelerometer bias" => p.sensors.accelerometer.bias_3sigma_mps2 = d.sensors.accelerometer.bias_3sigma_mps2,
        "ranging + interferometer" => {
            p.sensors.ranging = d.sensors.ranging.clone();
            p.sensors.interferometer = d.sensors.interferometer.clone();
        }
        "all" => p = d,
        _ => {}
    }
    p
}

/// Sec. 7 at the paper's conditions (its initial state, 9 300 s): each law at 10 ms and 1 ms with
/// no noise, with each noise source alone, and with all of them — where the paper's "SMC ~1e-6,
/// PD ~1e-3" could arise. Two threads.
fn sources() {
    const SOURCES: [&str; 9] = [
        "none",
        "disturbances",
        "wheels",
        "thrusters",
        "attitude sensors",
        "accelerometer noise",
        "accelerometer bias",
        "ranging + interferometer",
        "all",
    ];
    println!("\n### Sec. 7 case by noise source: transverse RMS / max over the last 15 s (mm), seed 1, 9 300 s\n");
    let jobs: Vec<(f64, Law, &str)> = [0.01, 0.001]
        .into_iter()
        .flat_map(|dt| Law::ALL.into_iter().flat_map(move |l| SOURCES.map(|s| (dt, l, s))))
        .collect();
    let results = on_two_threads(&jobs, |&(dt, law, source)| {
        let mut a = VtxoAlgorithmConfig::default();
        law.apply(&mut a);
        let r = run(&only(source), &a, dt, 9300.0, 1);
        format!("{:.3e} / {:.3e}", metric(&r.metrics, "transverse_rms_mm"), metric(&r.metrics, "transverse_max_mm"))
    });
    println!("| source | {} |", law_columns());
    println!("|---|{}", "---|".repeat(6));
    for (k, source) in SOURCES.iter().enumerate() {
        let cells: Vec<String> = (0..6).map(|c| results[c * SOURCES.len() + k].clone()).collect();
        println!("| {source} | {} |", cells.join(" | "));
    }
}

/// The six column heads "law dt" of the Sec. 7 tables (10 ms first).
fn law_columns() -> String {
    [0.01, 0.001].map(|dt| Law::ALL.map(|l| format!("{} {} ms", l.name(), dt * 1e3)).join(" | ")).join(" | ")
}

/// `f` of every job on two threads (the campaign runner), in the jobs' order.
fn on_two_threads<J: Sync, R: Send>(jobs: &[J], f: impl Fn(&J) -> R + Sync) -> Vec<R> {
    Campaign::new(jobs.len()).workers(2).map(|k| f(&jobs[k]))
}

/// Sec. 7 at the paper's conditions with the follower's relative navigation as the paper has it
/// (dead reckoning of v̂_rel from the accelerometers) and with the fusing filter
/// (`algorithm.relative.navigation = "filter"`): each law at 10 ms and 1 ms, with no noise, with
/// the accelerometer noise, its bias, the position sensors, or everything. Two threads.
fn fused() {
    const SETS: [&str; 5] = ["none", "accelerometer noise", "accelerometer bias", "ranging + interferometer", "all"];
    const NAVS: [RelativeNavigation; 2] = [RelativeNavigation::DeadReckoning, RelativeNavigation::Filter];
    let jobs: Vec<(RelativeNavigation, &str, f64, Law)> = NAVS
        .into_iter()
        .flat_map(|n| {
            SETS.into_iter()
                .flat_map(move |s| [0.01, 0.001].into_iter().flat_map(move |dt| Law::ALL.map(|l| (n, s, dt, l))))
        })
        .collect();
    let results = on_two_threads(&jobs, |&(nav, set, dt, law)| {
        let mut a = VtxoAlgorithmConfig::default();
        law.apply(&mut a);
        a.relative.navigation = nav;
        let m = run(&only(set), &a, dt, 9300.0, 1).metrics;
        let g = |k: &str| metric(&m, k);
        (
            format!("{:.3e} / {:.3e}", g("transverse_rms_mm"), g("transverse_max_mm")),
            format!("{:.3}", g("range_error_end_m")),
        )
    });
    let head = law_columns();
    for (title, pick) in [("transverse RMS / max over the last 15 s (mm)", 0), ("range error at the end (m)", 1)] {
        println!("\n### Sec. 7 by navigation and noise set: {title}, seed 1, 9 300 s\n");
        println!("| navigation | noise | {head} |");
        println!("|---|---|{}", "---|".repeat(6));
        for (row, chunk) in results.chunks(6).enumerate() {
            let (nav, set, _, _) = jobs[row * 6];
            let cells: Vec<&str> = chunk.iter().map(|c| [&c.0, &c.1][pick].as_str()).collect();
            println!("| {} | {set} | {} |", nav_name(nav), cells.join(" | "));
        }
    }
}

fn nav_name(n: RelativeNavigation) -> &'static str {
    match n {
        RelativeNavigation::DeadReckoning => "dead reckoning",
        RelativeNavigation::Filter => "filter",
    }
}

fn mekf() {
    println!("\n### MEKF consistency over 1 h (science phase, initial attitude drawn per (84), dt 10 ms, seed 1)\n");
    println!("| filter | agent | fraction |δθᵢ| ≤ 3σᵢ (x, y, z) | RMS error (x, y, z) µrad | RMS σ (x, y, z) µrad |");
    println!("|---|---|---|---|---|");
    for variant in [MekfVariant::ModelReplacement, MekfVariant::Full] {
        let mut p = VtxoPlantConfig::default();
        p.attitude.draw = AttitudeDraw::Science;
        let mut a = VtxoAlgorithmConfig::default();
        a.mekf.variant = variant;
        let mut sim = Sim::new(&p, &a, 0.01, 1).expect("valid");
        let cols = sim.agents[0].columns();
        let q_col = cols.iter().position(|c| c == "q_hat_q1").expect("column");
        let s_col = cols.iter().position(|c| c == "sigma_theta_x_rad").expect("column");
        let n = 360_000u64;
        let mut inside = [[0u64; 3]; 2];
        let (mut e2, mut s2) = ([[0.0; 3]; 2], [[0.0; 3]; 2]);
        let mut row = Vec::new();
        sim.run_with(n, &mut |_, plant, agents| {
            for i in 0..2 {
                row.clear();
                agents[i].row(&mut row);
                let q_hat = Quat::new(row[q_col], row[q_col + 1], row[q_col + 2], row[q_col + 3]);
                let e = mekf_error_rad(&plant.craft[i].attitude.q_body_eci, &q_hat);
                for ax in 0..3 {
                    let sg = row[s_col + ax];
                    inside[i][ax] += u64::from(e[ax].abs() <= 3.0 * sg);
                    e2[i][ax] += e[ax] * e[ax];
                    s2[i][ax] += sg * sg;
                }
            }
        });
        for (i, who) in ["leader", "follower"].iter().enumerate() {
            let f = inside[i].map(|c| format!("{:.4}", c as f64 / n as f64));
            let rms = |v: [f64; 3]| v.map(|x| format!("{:.4}", (x / n as f64).sqrt() * 1e6));
            println!(
                "| {variant:?} | {who} | {} | {} | {} |",
                f.join(", "),
                rms(e2[i]).join(", "),
                rms(s2[i]).join(", ")
            );
        }
    }
}

/// First return of the in-plane angle to its start, RK4 at 1 s, a bisected last step.
fn measured_period_s(el: &Elements, gravity: &Gravity) -> f64 {
    let (r0, v0) = state_from_elements(el, MU_EARTH_M3PS2);
    let e2 = r0.cross(&v0).normalize().cross(&r0.normalize());
    let zero = V3::zeros();
    let mut pair = OrbitPair { r_leader_eci_m: r0, v_leader_eci_mps: v0, r_rel_eci_m: zero, v_rel_eci_mps: zero };
    let (dt, mut t, mut half) = (1.0, 0.0, false);
    loop {
        let before = pair.clone();
        pair.rk4_step(gravity, &zero, &zero, dt);
        t += dt;
        let s = pair.r_leader_eci_m.dot(&e2);
        half |= s < 0.0;
        if half && s >= 0.0 && pair.r_leader_eci_m.dot(&r0) > 0.0 {
            let (mut lo, mut hi) = (0.0, dt);
            for _ in 0..60 {
                let mid = 0.5 * (lo + hi);
                let mut p = before.clone();
                p.rk4_step(gravity, &zero, &zero, mid);
                if p.r_leader_eci_m.dot(&e2) >= 0.0 { hi = mid } else { lo = mid }
            }
            return t - dt + hi;
        }
    }
}

fn orbit() {
    println!("\n### Orbit period (leader, Table D.9, from perigee)\n");
    let el = Elements {
        a_m: 45_300e3,
        e: 0.7125,
        inc_rad: 0.34f64.to_radians(),
        raan_rad: 0.0,
        argp_rad: 4.6743f64.to_radians(),
        true_anomaly_rad: 0.0,
    };
    let kepler = kepler_period_s(el.a_m, MU_EARTH_M3PS2);
    println!("| model | period (s) | period (h) | relative to 2π√(a³/μ) |");
    println!("|---|---|---|---|");
    println!("| 2π√(a³/μ) | {kepler:.3} | {:.4} | 0 |", kepler / 3600.0);
    for (name, j2) in [("two-body RK4", false), ("two-body + J2 RK4 (angle from perigee)", true)] {
        let t = measured_period_s(&el, &Gravity::earth(j2));
        println!("| {name} | {t:.3} | {:.4} | {:.3e} |", t / 3600.0, (t - kepler) / kepler);
    }
    let a32 = (MU_EARTH_M3PS2 * (32.5f64 * 3600.0 / std::f64::consts::TAU).powi(2)).cbrt();
    println!("\nThe paper's 32.5 h period needs a = {:.0} km.", a32 / 1e3);
}

/// P99 of a sample by the one quantile rule of Cohort's tables (`cohort_report::stats`).
fn p99(v: &mut [f64]) -> f64 {
    v.sort_by(f64::total_cmp);
    cohort_report::stats::quantile(v, 0.99)
}

/// The science phase of Table 5 in the full plant: both spacecraft at the formation, relative
/// control off, the attitude drawn per (84) from `seed`, law `sci`, 0.2 h at `dt_s`.
fn science_run(sci: ScienceAttitude, dt_s: f64, seed: u64) -> Run {
    let mut p = VtxoPlantConfig::default();
    p.attitude.draw = AttitudeDraw::Science;
    p.orbit.r_rel0_eci_m = p.metrics.r_target_eci_m;
    p.orbit.v_rel0_eci_mps = [0.0; 3];
    let mut a = VtxoAlgorithmConfig::default();
    a.attitude.science = sci;
    a.relative.controller = RelativeController::Off;
    run(&p, &a, dt_s, 720.0, seed)
}

fn science() {
    println!("\n### Science phase Monte Carlo (Table 5 analogue): 100 seeds, 0.2 h at dt 10 ms, Table 4 gains\n");
    println!("Initial attitude and rate drawn per (84) around q_f; relative control off and r_rel(0) = r_f");
    println!(
        "(no coupling to the attitude). e = mean attitude error over the run, E = Σᵢ∫|τᵢωᵢ|dt; mean and P99 over runs.\n"
    );
    println!(
        "| law | agent | e mean (deg) | e P99 (deg) | E mean (J) | E P99 (J) | R2: P99(e) < 0.18° | paper (Table 5) e, E |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    for (name, sci) in [("PD", ScienceAttitude::Pd), ("SMC", ScienceAttitude::Smc)] {
        let mut e = [Vec::new(), Vec::new()];
        let mut en = [Vec::new(), Vec::new()];
        for seed in 1..=100 {
            let r = science_run(sci, 0.01, seed);
            for (i, who) in ["leader", "follower"].iter().enumerate() {
                e[i].push(metric(&r.metrics, &format!("{who}_attitude_error_mean_deg")));
                en[i].push(metric(&r.metrics, &format!("{who}_energy_j")));
            }
        }
        let paper = if name == "PD" { "0.2219°, 0.0353 J" } else { "0.1738°, 0.0066 J" };
        for (i, who) in ["leader", "follower"].iter().enumerate() {
            let mean = |v: &[f64]| v.iter().sum::<f64>() / v.len() as f64;
            let (em, ep) = (mean(&e[i]), p99(&mut e[i]));
            let (jm, jp) = (mean(&en[i]), p99(&mut en[i]));
            println!(
                "| {name} | {who} | {em:.4} | {ep:.4} | {jm:.3e} | {jp:.3e} | {} | {paper} |",
                if ep < 0.18 { "holds" } else { "fails" }
            );
        }
    }
}

/// "mean / P99" of the finite values ("—" when none is), and how many were not (lost flights).
fn spread(v: &[f64], digits: usize, sci: bool) -> (String, usize) {
    let mut ok: Vec<f64> = v.iter().copied().filter(|x| x.is_finite()).collect();
    let lost = v.len() - ok.len();
    if ok.is_empty() {
        return ("—".into(), lost);
    }
    let m = ok.iter().sum::<f64>() / ok.len() as f64;
    let p = p99(&mut ok);
    let text = if sci { format!("{m:.digits$e} / {p:.digits$e}") } else { format!("{m:.digits$} / {p:.digits$}") };
    (text, lost)
}

/// The cells "e | E | lost" of one law's flights.
fn table5_cells(e: &[f64], en: &[f64]) -> String {
    let ((e, lost), (en, _)) = (spread(e, 4, false), spread(en, 3, true));
    format!("{e} | {en} | {lost}")
}

/// A flight is lost when its rate ends above 1 deg/s (the starts are 0.05 deg/s 1σ) or its
/// numbers are not finite; its e and E are then NaN (left out of the statistics and counted).
fn science_outcome(o: &science_sim::Outcome) -> (f64, f64) {
    let w = o.omega_end_rad_s.norm().to_degrees();
    if w.is_finite() && w < 1.0 && o.error_deg.is_finite() && o.energy_j.is_finite() {
        (o.error_deg, o.energy_j)
    } else {
        (f64::NAN, f64::NAN)
    }
}

/// Table 5 against the step and the reading of the wheel bias: Table 4's gains over the science
/// phase (0.2 h) at dt 0.01, 0.1, 1 and 2 s (the author's code integrates at 2 s), (a) in the
/// Pareto data's flight (truth feedback, `learn/science/sim.rs`) for every reading of Table E.10's
/// b_τ, 100 draws (seed 1), common random numbers; (b) in the full plant (MEKF, sensors, every
/// model; the plant's reading), 100 seeds, leader's metrics.
fn table5() {
    use science_sim::{ScienceLaw, WheelBias};
    println!("\n### Table 5 by step and wheel-bias reading, science-phase flight (truth feedback), 100 draws\n");
    println!(
        "| dt (s) | b_τ reading | PD e mean / P99 (deg) | PD E mean / P99 (J) | PD lost | SMC e mean / P99 (deg) | SMC E mean / P99 (J) | SMC lost |"
    );
    println!("|---|---|---|---|---|---|---|---|");
    let jobs: Vec<(f64, WheelBias)> =
        [0.01, 0.1, 1.0, 2.0].into_iter().flat_map(|dt| WheelBias::ALL.map(|b| (dt, b))).collect();
    let rows = on_two_threads(&jobs, |&(dt, bias)| {
        ScienceLaw::ALL.map(|law| {
            let (mut e, mut en) = (Vec::new(), Vec::new());
            for i in 0..100 {
                let (start, env, _) =
                    science_sim::draw_with(1, i, science_sim::steps(science_sim::PHASE_S, dt), dt, bias);
                let (a, b) = science_outcome(&science_sim::fly(&start, &env, &law.law(law.table4()), dt));
                e.push(a);
                en.push(b);
            }
            table5_cells(&e, &en)
        })
    });
    for ((dt, bias), [pd, smc]) in jobs.iter().zip(rows) {
        println!("| {dt} | {} | {pd} | {smc} |", bias.name());
    }
    println!("\n### Table 5 by step, full plant (leader; follower alike), 100 seeds\n");
    println!(
        "| dt (s) | PD e mean / P99 (deg) | PD E mean / P99 (J) | PD lost | SMC e mean / P99 (deg) | SMC E mean / P99 (J) | SMC lost |"
    );
    println!("|---|---|---|---|---|---|---|");
    let jobs: Vec<(f64, ScienceAttitude)> = [0.01, 0.1, 1.0, 2.0]
        .into_iter()
        .flat_map(|dt| [ScienceAttitude::Pd, ScienceAttitude::Smc].map(|l| (dt, l)))
        .collect();
    let cells = on_two_threads(&jobs, |&(dt, sci)| {
        let (mut e, mut en) = (Vec::new(), Vec::new());
        for seed in 1..=100 {
            let r = science_run(sci, dt, seed);
            let (em, jm) =
                (metric(&r.metrics, "leader_attitude_error_mean_deg"), metric(&r.metrics, "leader_energy_j"));
            // Lost: an error past 10° or a non-finite number (the plant has no end-rate metric).
            let ok = em.is_finite() && em < 10.0 && jm.is_finite();
            e.push(if ok { em } else { f64::NAN });
            en.push(if ok { jm } else { f64::NAN });
        }
        table5_cells(&e, &en)
    });
    for (k, pair) in cells.chunks(2).enumerate() {
        println!("| {} | {} | {} |", jobs[2 * k].0, pair[0], pair[1]);
    }
}

fn leader_smc() {
    println!("\n### Both spacecraft control: leader (70) + follower (66), each with the other's previous command\n");
    println!("Start r_rel(0) = [10, 20, 1100] m, v_rel(0) = [1, 1, 1] m/s, 200 s at dt 10 ms, seed 1.\n");
    println!("| switching | first < 1 m (s) | transverse RMS (mm) | peak thrust L / F (N) | Δv L / F (m/s) |");
    println!("|---|---|---|---|---|");
    for sw in [Switching::Sign, Switching::Sat] {
        let mut a = VtxoAlgorithmConfig::default();
        a.leader.control = LeaderControl::Smc;
        a.relative.switching = sw;
        let mut p = VtxoPlantConfig::default();
        p.orbit.r_rel0_eci_m = [10.0, 20.0, 1100.0];
        let r = run(&p, &a, 0.01, 200.0, 1);
        let g = |k: &str| metric(&r.metrics, k);
        println!(
            "| {sw:?} | {:.2} | {:.3} | {:.0} / {:.0} | {:.0} / {:.0} |",
            g("formation_first_within_s"),
            g("transverse_rms_mm"),
            g("leader_thrust_peak_n"),
            g("follower_thrust_peak_n"),
            g("leader_delta_v_mps"),
            g("follower_delta_v_mps")
        );
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let all = args.is_empty();
    let want = |s: &str| all || args.iter().any(|a| a == s);
    if want("orbit") {
        orbit();
    }
    if want("mekf") {
        mekf();
    }
    if want("ideal") {
        ideal_band();
    }
    if want("band") {
        band();
    }
    if want("sources") {
        sources();
    }
    if want("fused") {
        fused();
    }
    if want("sec7") {
        sec7();
    }
    if want("seeds") {
        seeds();
    }
    if want("science") {
        science();
    }
    if want("table5") {
        table5();
    }
    if want("leader") {
        leader_smc();
    }
}
