//! Training data of Sec. 6.2.2 of "Neural-Rendezvous" (arXiv:2208.04883): for each sample a
//! (control step, ISO) pair drawn uniformly, ρ_f uniform on the sphere of radius R, the ISO and
//! spacecraft ideal states at that time perturbed by N(0, Σ(t)) (the navigation covariance), and
//! the global solution (SCP, [`crate::iso::guidance::scp`]) from there. Each sample keeps
//!
//! - the network input at the start and the MPC's first command (the control term of (11));
//! - if Δτ fits before t_f, the MPC plan over [t, t + Δτ]: at each of its nodes the input and
//!   its Jacobian in x, the plan's command, and the step Jacobians A, B of the last SCP
//!   linearisation — what the state term of (11) needs to roll the SN-DNN's closed loop through
//!   the linearised dynamics (ours: the MPC open-loop nodes stand for its closed loop, which
//!   they equal without estimation error).
//!
//! Departures (ours): the spacecraft's arrival velocity is drawn afresh per sample from the set's
//! distribution ([`crate::iso::dynamics::iso_set`]) so the approach geometries vary more than 200 ISOs allow; the
//! mass is m₀ (it changes by < 1 % over a mission and is not an input). Every sample is a
//! deterministic function of (seed, ISO, sample index), so the set is the same on any number of
//! threads; it is cached on disk by a hash of its options.

use std::ops::Range;
use std::path::{Path, PathBuf};

use cohort_host::campaign::Campaign;
use cohort_runtime::solver_stats::SolveLog;
use nalgebra::{Matrix6, Matrix6x3};
use rand::Rng;
use rand_distr::StandardNormal;
use serde::{Deserialize, Serialize};

use crate::iso::dynamics::iso_set::{self, Ideal};
use crate::iso::dynamics::lvlh::IsoFrame;
use crate::iso::dynamics::navigation::{self, NavSigmas};
use crate::iso::dynamics::two_body::V3;
use crate::iso::guidance::features::{FeatureJac, Features, features_jac};
use crate::iso::guidance::scp::{self, ScpInput, ScpSettings};

/// Changed whenever a sample's content changes (the cache key includes it with the input size).
const FORMAT: &str = "nr-data-v1";

/// How the data set is drawn.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct DataOptions {
    pub seed: u64,
    pub iso_set_seed: u64,
    pub isos: Range<u32>,
    pub samples_per_iso: u32,
    pub t_f_s: f64,
    pub dt_s: f64,
    pub m0_kg: f64,
    pub u_max_n: f64,
    pub isp_s: f64,
    pub rho_f_radius_m: f64,
    pub nav: NavSigmas,
    pub nav_scale: f64,
    /// Δτ of the state term, in control steps.
    pub dtau_steps: usize,
    pub scp: ScpSettings,
}

impl DataOptions {
    /// Stable hash of the options and the sample format (FNV-1a of their JSON), naming the cache
    /// file.
    pub fn hash(&self) -> u64 {
        let text = format!(
            "{FORMAT}|{}|{}",
            crate::iso::guidance::features::N_FEATURES,
            serde_json::to_string(self).expect("plain options serialise")
        );
        cohort_wire::fnv1a(text.as_bytes())
    }
}

/// One node of the MPC plan over Δτ.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Node {
    pub f: Features,
    pub f_jac: FeatureJac,
    pub u_n: V3,
    pub a: Matrix6<f64>,
    pub b: Matrix6x3<f64>,
}

#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Sample {
    pub iso: u32,
    pub step: u32,
    /// Network input at the sample (raw).
    pub f0: Features,
    /// MPC's first command, LVLH, N.
    pub u0_n: V3,
    /// The SCP's terminal miss, m, and whether the target was out of reach.
    pub miss_m: f64,
    pub soft: bool,
    /// The plan's first Δτ/Δt nodes (empty when Δτ does not fit before t_f).
    pub nodes: Vec<Node>,
}

fn unit(rng: &mut impl Rng) -> V3 {
    loop {
        let v = V3::new(rng.sample(StandardNormal), rng.sample(StandardNormal), rng.sample(StandardNormal));
        if v.norm() > 1e-9 {
            return v.normalize();
        }
    }
}

/// Sample `s` of ISO `i`.
pub fn sample(o: &DataOptions, i: u32, s: u32, log: &mut SolveLog) -> Sample {
    let mut rng = cohort_runtime::rng::setup_rng(o.seed, &format!("nr.train.data[{i}][{s}]"));
    let n = (o.t_f_s / o.dt_s).round() as u32;
    let step = rng.random_range(0..n);
    let t_s = f64::from(step) * o.dt_s;
    let rho_f_m = o.rho_f_radius_m * unit(&mut rng);
    let extra = 5e3 * unit(&mut rng);
    let iso_tf = iso_set::iso_at_encounter(o.iso_set_seed, i);
    let ideal = Ideal { t_f_s: o.t_f_s, iso_tf, sc_tf: iso_set::arrival(&iso_tf, &rho_f_m, extra), rho_f_m };
    let (iso_t, sc_t) = ideal.at(t_s);
    let sigma = o.nav.at(t_s, o.t_f_s, o.nav_scale);
    let iso_hat = navigation::draw(&iso_t, &sigma, &mut rng);
    let sc_hat = navigation::draw(&sc_t, &sigma, &mut rng);
    let inp = ScpInput {
        x0: IsoFrame::of(&iso_hat).relative(&sc_hat),
        iso0: iso_hat,
        m0_kg: o.m0_kg,
        t0_s: t_s,
        t_f_s: o.t_f_s,
        dt_s: o.dt_s,
        rho_f_m,
        u_max_n: o.u_max_n,
        isp_s: o.isp_s,
    };
    let plan = scp::solve(&inp, None, &o.scp, log);
    let traj = &plan.traj;
    let f0 = features_jac(&inp.x0, &iso_hat, t_s, o.t_f_s, &rho_f_m).0;
    let nodes = if (step as usize) + o.dtau_steps <= n as usize {
        (0..o.dtau_steps)
            .map(|j| {
                let (f, f_jac) = features_jac(&traj.x[j], &traj.iso[j], t_s + j as f64 * o.dt_s, o.t_f_s, &rho_f_m);
                Node { f, f_jac, u_n: traj.u_n[j], a: traj.jac[j].a, b: traj.jac[j].b }
            })
            .collect()
    } else {
        Vec::new()
    };
    Sample { iso: i, step, f0, u0_n: plan.first_u(), miss_m: plan.miss_m, soft: plan.soft, nodes }
}

/// Every sample, in (ISO, sample) order, computed on `threads` threads.
pub fn generate(o: &DataOptions, threads: usize) -> Vec<Sample> {
    let jobs: Vec<(u32, u32)> = o.isos.clone().flat_map(|i| (0..o.samples_per_iso).map(move |s| (i, s))).collect();
    Campaign::new(jobs.len())
        .workers(threads)
        .map_with(|| SolveLog::new("training data"), |log, j| sample(o, jobs[j].0, jobs[j].1, log))
}

/// The cache file for `o` in `dir`.
pub fn cache_path(dir: &Path, o: &DataOptions) -> PathBuf {
    dir.join(format!("nr-data-{:016x}.bin", o.hash()))
}

/// Load the cached set for `o` from `dir`, or generate and cache it; also says whether it came
/// from the cache.
pub fn load_or_generate(o: &DataOptions, dir: Option<&Path>, threads: usize) -> Result<(Vec<Sample>, bool), String> {
    if let Some(dir) = dir {
        let path = cache_path(dir, o);
        if let Ok(bytes) = std::fs::read(&path)
            && let Ok(v) = cohort_runtime::checkpoint::decode_state::<Vec<Sample>>(&bytes)
        {
            return Ok((v, true));
        }
        let v = generate(o, threads);
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
        std::fs::write(&path, cohort_runtime::checkpoint::encode_state(&v))
            .map_err(|e| format!("{}: {e}", path.display()))?;
        return Ok((v, false));
    }
    Ok((generate(o, threads), false))
}
