//! Training the swarm's deep-set policy ([`crate::swarm::control::policy`]) by imitation of the global
//! solution (Sec. 7.2.1 of "Neural-Rendezvous", arXiv:2208.04883), as a library function the
//! trainer `orchestrator train nr-swarm --seed N` ([`crate::swarm::train::command`]) calls: generate the
//! data ([`crate::swarm::train::data`]), train φ and ρ together with candle on the CPU (the SN layers of
//! [`crate::nn::sn_mlp`], reused), write the one weights file and report.
//!
//! Loss: mean ‖u_ℓ/a_max − target/a_max‖² over a batch (the control term of (10)–(12); the
//! state term of the ISO case is not used: the targets already carry the return to the plan
//! through the PD term, see [`crate::swarm::train::data`]). AdamW (no weight decay), cosine-decaying rate.
//! The last [`SwarmTrainOptions::validation_cases`] cases are held out and only reported.
//!
//! Then [`SwarmTrainOptions::dagger_rounds`] DAgger rounds ([`crate::swarm::train::dagger`]): fly the
//! current policy on every training case, label the visited states by that case's global
//! solution, add them to the set and train [`SwarmTrainOptions::dagger_epochs`] more epochs on
//! the union (the same optimiser, a fresh cosine schedule per round). The report adds the policy
//! alone in closed loop on the held-out cases ([`crate::swarm::train::eval::closed_loop`]).
//!
//! Seeded and deterministic: the data are (see there), the initial weights and the batch order
//! come from one generator of the seed, candle's CPU kernels are deterministic at a fixed thread
//! count (the trainer runs with RAYON_NUM_THREADS=1), so the same options write the same bytes.

use std::path::PathBuf;
use std::time::Instant;

use candle_core::{Device, Tensor};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;

use crate::iso::train::imitation::TrainError;
use crate::nn::sn_mlp::SnMlp;
use crate::swarm::control::obs::{MAX_NEIGHBOURS, SwarmPolicy};
use crate::swarm::control::policy::{DeepSetPolicy, OWN_IN, PHI_IN, own_input, phi_input, phi_scales, rho_scales};
use crate::swarm::train::avoidance::{self, CollisionLoss};
use crate::swarm::train::data::{self as swarm_data, CaseOutcome, Expert, SwarmDataOptions, SwarmSample};
use crate::swarm::train::problem::A_MAX_MPS2;

/// Everything a training run depends on.
#[derive(Debug, Clone)]
pub struct SwarmTrainOptions {
    pub out: PathBuf,
    pub seed: u64,
    pub data: SwarmDataOptions,
    /// The last this many cases of `data` are held out for validation.
    pub validation_cases: usize,
    pub threads: usize,
    pub phi_hidden: Vec<usize>,
    pub rho_hidden: Vec<usize>,
    pub c_sn: f64,
    pub epochs: usize,
    pub batch: usize,
    pub lr_start: f64,
    pub lr_end: f64,
    /// DAgger rounds after the first `epochs` ([`crate::swarm::train::dagger`]).
    pub dagger_rounds: usize,
    /// Epochs of each DAgger round.
    pub dagger_epochs: usize,
    /// Extra copies of each near-conflict training sample ([`crate::swarm::train::avoidance`]).
    pub near_copies: usize,
    /// The collision-aware loss term (weight 0: off).
    pub collision: CollisionLoss,
}

impl SwarmTrainOptions {
    /// The reference run: 150 cases (135 trained on, 15 held out), φ 6 → 32 → 32,
    /// ρ 39 → 64 → 64 → 3, C_sn = 2, 40 epochs of batches of 256, no DAgger round (the rounds
    /// we tried made the closed loop worse; see the crate README).
    pub fn reference(out: PathBuf, seed: u64) -> Self {
        Self {
            out,
            seed,
            data: SwarmDataOptions::reference(seed),
            validation_cases: 15,
            threads: 2,
            phi_hidden: vec![32, 32],
            rho_hidden: vec![64, 64],
            c_sn: 2.0,
            epochs: 40,
            batch: 256,
            lr_start: 3e-3,
            lr_end: 3e-5,
            dagger_rounds: 0,
            dagger_epochs: 8,
            near_copies: 0,
            collision: CollisionLoss::off(),
        }
    }
}

/// What a training run reports.
#[derive(Debug, Clone)]
pub struct SwarmTrainReport {
    pub weights: PathBuf,
    pub seed: u64,
    pub outcomes: Vec<CaseOutcome>,
    pub train_samples: usize,
    /// Of `train_samples`, the states visited by the policy (DAgger).
    pub dagger_samples: usize,
    pub validation_samples: usize,
    /// The policy alone on the held-out cases: (collision-free cases, colliding pairs, cases).
    pub validation_closed_loop: (usize, usize, usize),
    /// Mean loss of the first and last epochs.
    pub first_loss: f64,
    pub last_loss: f64,
    /// RMS of ‖u_ℓ − target‖ (m/s²) of the written f64 policy.
    pub rms_train_mps2: f64,
    pub rms_validation_mps2: f64,
    pub data_s: f64,
    pub train_s: f64,
    pub c_sn: f64,
    pub epochs: usize,
    pub dagger_rounds: usize,
    pub dagger_epochs: usize,
    /// Of `train_samples`, the near-conflict copies.
    pub near_samples: usize,
    pub near_copies: usize,
    pub collision: CollisionLoss,
}

impl SwarmTrainReport {
    /// The report file: no wall-clock time, so the same options give the same bytes.
    pub fn markdown(&self, command: &str) -> String {
        let solved: Vec<&CaseOutcome> = self.outcomes.iter().filter(|o| o.safe == Some(true)).collect();
        let failed = self.outcomes.iter().filter(|o| o.safe.is_none()).count();
        let unsafe_ = self.outcomes.iter().filter(|o| o.safe == Some(false)).count();
        let mean =
            |f: &dyn Fn(&CaseOutcome) -> f64| solved.iter().map(|o| f(o)).sum::<f64>() / solved.len().max(1) as f64;
        let min_d = solved.iter().map(|o| o.min_distance_fine).fold(f64::INFINITY, f64::min);
        format!(
            "# Swarm deep-set policy training (seed {seed})\n\n\
             Reproduce: `{command}` (from the repository root).\n\n\
             Weights: `{w}`; φ 6→32→32, ρ 39→64→64→3 (ρ also reads the time to go), tanh, C_sn = {c}, {ep} epochs, then {dr} DAgger rounds \
             of {de} epochs.\n\n\
             Global solutions: {nc} cases (N = 6–8), {ns} collision-free on the fine grid, {nu} not, {nf} failed; \
             mean SCP iterations {it:.2}, mean ∫‖u‖dt {ef:.4} m/s per case, least ellipsoid distance {md:.4}.\n\n\
             Samples: {nt} training ({nd} of them states the policy visited, DAgger), {nv} validation (held-out \
             cases, perturbed states).\n\n\
             Loss (normalised, per sample): first epoch {l0:.4e}, last {l1:.4e}.\n\n\
             RMS ‖u_ℓ − target‖: training {rt:.4} m/s², validation {rv:.4} m/s².\n\n\
             The policy alone in closed loop on the {vc} held-out cases (exact observations, T + 2 s): {vf} \
             collision-free, {vp} colliding pairs in all.\n",
            seed = self.seed,
            w = self.weights.display(),
            c = self.c_sn,
            ep = self.epochs,
            dr = self.dagger_rounds,
            de = self.dagger_epochs,
            nd = self.dagger_samples,
            vf = self.validation_closed_loop.0,
            vp = self.validation_closed_loop.1,
            vc = self.validation_closed_loop.2,
            nc = self.outcomes.len(),
            ns = solved.len(),
            nu = unsafe_,
            nf = failed,
            it = mean(&|o| f64::from(o.iterations)),
            ef = mean(&|o| o.effort_l1),
            md = min_d,
            nt = self.train_samples,
            nv = self.validation_samples,
            l0 = self.first_loss,
            l1 = self.last_loss,
            rt = self.rms_train_mps2,
            rv = self.rms_validation_mps2,
        ) + &self.avoidance_line()
    }

    /// What the avoidance levers added (nothing when both are off, as in the reference run).
    fn avoidance_line(&self) -> String {
        let c = &self.collision;
        if self.near_copies == 0 && c.weight == 0.0 {
            return String::new();
        }
        format!(
            "\nAvoidance: {} near-conflict copies ({} extra of each sample with a neighbour nearer than {}), \
             collision-aware loss λ = {} (horizon {} s, margin {}).\n",
            self.near_samples,
            self.near_copies,
            avoidance::NEAR_DISTANCE,
            c.weight,
            c.horizon_s,
            c.margin
        )
    }

    /// Wall-clock times (not in the report file).
    pub fn timings(&self) -> String {
        let scp: f64 = self.outcomes.iter().map(|o| o.solve_s).sum();
        format!("data generation {:.1} s (Σ SCP solve times {scp:.1} s), training {:.1} s", self.data_s, self.train_s)
    }
}

/// The training model: φ and ρ as candle SN-MLPs.
pub struct DeepSetMlp {
    pub phi: SnMlp,
    pub rho: SnMlp,
}

/// Samples as normalised f32 tensors: neighbours (S, 6, 6), mask (S, 6, 1), own (S, 6),
/// targets / a_max (S, 3).
pub struct SwarmTensors {
    pub nb: Tensor,
    pub mask: Tensor,
    pub own: Tensor,
    pub y: Tensor,
}

impl SwarmTensors {
    pub fn of(samples: &[SwarmSample], dev: &Device) -> candle_core::Result<Self> {
        let s = samples.len();
        let (ps, rs) = (phi_scales(), rho_scales(0));
        let (mut nb, mut mask, mut own, mut y) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for smp in samples {
            for slot in 0..MAX_NEIGHBOURS {
                nb.extend(phi_input(&smp.obs.neighbours[slot]).iter().zip(&ps).map(|(x, k)| (x / k) as f32));
                mask.push(if slot < smp.obs.n_neighbours { 1f32 } else { 0.0 });
            }
            own.extend(own_input(&smp.obs).iter().zip(&rs).map(|(x, k)| (x / k) as f32));
            y.extend(smp.target_mps2.iter().map(|u| (u / A_MAX_MPS2) as f32));
        }
        Ok(Self {
            nb: Tensor::from_vec(nb, (s, MAX_NEIGHBOURS, PHI_IN), dev)?,
            mask: Tensor::from_vec(mask, (s, MAX_NEIGHBOURS, 1), dev)?,
            own: Tensor::from_vec(own, (s, OWN_IN), dev)?,
            y: Tensor::from_vec(y, (s, 3), dev)?,
        })
    }

    fn select(&self, idx: &[u32]) -> candle_core::Result<Self> {
        let i = Tensor::from_slice(idx, idx.len(), self.nb.device())?;
        Ok(Self {
            nb: self.nb.index_select(&i, 0)?,
            mask: self.mask.index_select(&i, 0)?,
            own: self.own.index_select(&i, 0)?,
            y: self.y.index_select(&i, 0)?,
        })
    }
}

impl DeepSetMlp {
    pub fn new(o: &SwarmTrainOptions, rng: &mut ChaCha8Rng, dev: &Device) -> candle_core::Result<Self> {
        let mut ps = vec![PHI_IN];
        ps.extend(&o.phi_hidden);
        let mut rs = vec![OWN_IN + ps.last().expect("φ has a layer")];
        rs.extend(&o.rho_hidden);
        rs.push(3);
        Ok(Self { phi: SnMlp::new(&ps, o.c_sn, rng, dev)?, rho: SnMlp::new(&rs, o.c_sn, rng, dev)? })
    }

    /// Normalised outputs (B, 3) of the batch with the weights of one training step.
    pub fn forward(&self, wp: &[Tensor], wr: &[Tensor], t: &SwarmTensors) -> candle_core::Result<Tensor> {
        let (b, m, k) = t.nb.dims3()?;
        let f = self.phi.forward(wp, &t.nb.reshape((b * m, k))?)?;
        let f = f.reshape((b, m, ()))?.broadcast_mul(&t.mask)?.sum(1)?;
        self.rho.forward(wr, &Tensor::cat(&[&t.own, &f], 1)?)
    }

    /// The f64 policy (exact normalisation, the fixed scales, a_max at the output).
    pub fn export(&self, metadata: serde_json::Value) -> Result<DeepSetPolicy, String> {
        let n_phi = *self.phi.sizes.last().expect("φ has a layer");
        let phi = self.phi.export(phi_scales(), vec![1.0; n_phi], serde_json::json!({}))?;
        let rho = self.rho.export(rho_scales(n_phi), vec![A_MAX_MPS2; 3], serde_json::json!({}))?;
        DeepSetPolicy::new(phi, rho, metadata)
    }
}

/// The model, its optimiser and the generator of the batch order, across the training phases.
struct Fitter {
    net: DeepSetMlp,
    opt: AdamW,
    rng: ChaCha8Rng,
}

impl Fitter {
    fn new(o: &SwarmTrainOptions, dev: &Device) -> Result<Self, TrainError> {
        let mut rng = ChaCha8Rng::seed_from_u64(o.seed ^ 0x5357_4152_4d5f_4e4e);
        let net = DeepSetMlp::new(o, &mut rng, dev)?;
        let mut vars = net.phi.vars();
        vars.extend(net.rho.vars());
        let opt = AdamW::new(vars, ParamsAdamW { lr: o.lr_start, weight_decay: 0.0, ..Default::default() })?;
        Ok(Self { net, opt, rng })
    }

    /// Train `epochs` on `t` (a cosine rate from `lr_start` to `lr_end`); the mean loss per epoch.
    fn phase(&mut self, o: &SwarmTrainOptions, t: &SwarmTensors, epochs: usize) -> Result<Vec<f64>, TrainError> {
        let n = t.y.dims2()?.0;
        let mut order: Vec<u32> = (0..n as u32).collect();
        let nb = n.div_ceil(o.batch);
        let total = (epochs * nb).max(1) as f64;
        let mut history = Vec::with_capacity(epochs);
        for epoch in 0..epochs {
            order.shuffle(&mut self.rng);
            let mut sum = 0.0;
            for bi in 0..nb {
                let progress = (epoch * nb + bi) as f64 / total;
                self.opt.set_learning_rate(
                    o.lr_end + 0.5 * (o.lr_start - o.lr_end) * (1.0 + (std::f64::consts::PI * progress).cos()),
                );
                let idx = &order[bi * o.batch..((bi + 1) * o.batch).min(n)];
                let b = t.select(idx)?;
                let (wp, wr) = (self.net.phi.weights()?, self.net.rho.weights()?);
                let pred = self.net.forward(&wp, &wr, &b)?;
                let mut loss = ((&pred - &b.y)?.sqr()?.sum_all()? / idx.len() as f64)?;
                if o.collision.weight > 0.0 {
                    let pen = avoidance::collision_penalty(&o.collision, &b.nb, &b.mask, &pred)?;
                    loss = (loss + (pen * o.collision.weight)?)?;
                }
                self.opt.backward_step(&loss)?;
                sum += f64::from(loss.to_scalar::<f32>()?) / nb as f64;
            }
            history.push(sum);
        }
        Ok(history)
    }
}

/// The policy alone on each expert's case: (collision-free cases, colliding pairs, cases).
fn closed_loop_check(p: &DeepSetPolicy, experts: &[Expert]) -> (usize, usize, usize) {
    let runs: Vec<usize> = experts
        .iter()
        .map(|e| {
            crate::swarm::train::eval::closed_loop(p, &e.problem, crate::swarm::train::eval::EVAL_STEPS).collisions
        })
        .collect();
    (runs.iter().filter(|c| **c == 0).count(), runs.iter().sum(), runs.len())
}

/// RMS of ‖u_ℓ − target‖ over `samples` (0 for none).
pub fn rms_error(p: &DeepSetPolicy, samples: &[SwarmSample]) -> f64 {
    let se: f64 = samples
        .iter()
        .map(|s| {
            let u = p.accel_mps2(&s.obs);
            (0..3).map(|k| (u[k] - s.target_mps2[k]).powi(2)).sum::<f64>()
        })
        .sum();
    (se / samples.len().max(1) as f64).sqrt()
}

/// The avoidance levers in the weights' metadata when used (a reference run's file keeps the
/// bytes it had before they existed).
fn with_avoidance(mut meta: serde_json::Value, o: &SwarmTrainOptions) -> serde_json::Value {
    let c = &o.collision;
    if o.near_copies > 0 || c.weight > 0.0 {
        meta["training"]["avoidance"] = serde_json::json!({
            "near_copies": o.near_copies, "collision_weight": c.weight,
            "collision_horizon_s": c.horizon_s, "collision_margin": c.margin,
        });
    }
    meta
}

/// Generate the data, train, write the weights file, report.
pub fn train(o: &SwarmTrainOptions) -> Result<SwarmTrainReport, TrainError> {
    let d = &o.data;
    if o.epochs == 0 || o.batch == 0 || o.phi_hidden.is_empty() || !(o.c_sn.is_finite() && o.c_sn > 0.0) {
        return Err(TrainError::Options("epochs, batch and φ's layers must be ≥ 1, C_sn > 0".into()));
    }
    if d.n_min == 0 || d.n_min > d.n_max || o.validation_cases >= d.cases {
        return Err(TrainError::Options(format!(
            "cases {} (validation {}), N {}–{}: need 1 ≤ N_min ≤ N_max and a training case",
            d.cases, o.validation_cases, d.n_min, d.n_max
        )));
    }
    let started = Instant::now();
    let (outcomes, samples, experts) = swarm_data::generate_with_experts(d, o.threads);
    let data_s = started.elapsed().as_secs_f64();
    let split = d.cases - o.validation_cases;
    let (mut train_set, val_set): (Vec<SwarmSample>, Vec<SwarmSample>) = samples.iter().partition(|s| s.case < split);
    let (train_experts, val_experts): (Vec<Expert>, Vec<Expert>) = experts.into_iter().partition(|e| e.case < split);
    if train_set.is_empty() {
        return Err(TrainError::Data("no training case has a collision-free global solution".into()));
    }
    let near_samples = avoidance::oversample(&mut train_set, o.near_copies);
    let started = Instant::now();
    let dev = Device::Cpu;
    let mut fitter = Fitter::new(o, &dev)?;
    let mut history = fitter.phase(o, &SwarmTensors::of(&train_set, &dev)?, o.epochs)?;
    let base = train_set.len();
    for _ in 0..o.dagger_rounds {
        let now = fitter.net.export(serde_json::json!({})).map_err(TrainError::Options)?;
        train_set.extend(crate::swarm::train::dagger::visited_all(d, &train_experts, &now, o.threads));
        history.extend(fitter.phase(o, &SwarmTensors::of(&train_set, &dev)?, o.dagger_epochs)?);
    }
    let mlp = fitter.net;
    let train_s = started.elapsed().as_secs_f64();
    let meta = serde_json::json!({
        "inputs": {"phi": ["dp_x_m", "dp_y_m", "dp_z_m", "dv_x_mps", "dv_y_mps", "dv_z_mps"],
                   "rho": "goal offset g − p (m, 3), own velocity (m/s, 3), Σ φ over the observed neighbours"},
        "outputs": ["a_x_mps2", "a_y_mps2", "a_z_mps2"],
        "activation": "tanh (every layer of φ and ρ, the outputs included)",
        "training": {
            "seed": o.seed, "epochs": o.epochs, "dagger_rounds": o.dagger_rounds, "dagger_epochs": o.dagger_epochs,
            "batch": o.batch, "phi_hidden": o.phi_hidden,
            "rho_hidden": o.rho_hidden, "lr": [o.lr_start, o.lr_end], "validation_cases": o.validation_cases,
            "data": d,
        },
    });
    let policy = mlp.export(with_avoidance(meta, o)).map_err(TrainError::Options)?;
    let write_err = |reason: String| TrainError::Write { path: o.out.clone(), reason };
    if let Some(dir) = o.out.parent().filter(|p| !p.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| write_err(e.to_string()))?;
    }
    std::fs::write(&o.out, policy.to_bytes()).map_err(|e| write_err(e.to_string()))?;
    let check = DeepSetPolicy::load(&o.out).map_err(|e| write_err(e.to_string()))?;
    Ok(SwarmTrainReport {
        weights: o.out.clone(),
        seed: o.seed,
        outcomes,
        train_samples: train_set.len(),
        dagger_samples: train_set.len() - base,
        validation_samples: val_set.len(),
        validation_closed_loop: closed_loop_check(&check, &val_experts),
        first_loss: history[0],
        last_loss: *history.last().expect("≥ 1 epoch"),
        rms_train_mps2: rms_error(&check, &train_set),
        rms_validation_mps2: rms_error(&check, &val_set),
        data_s,
        train_s,
        c_sn: o.c_sn,
        epochs: o.epochs,
        dagger_rounds: o.dagger_rounds,
        dagger_epochs: o.dagger_epochs,
        near_samples,
        near_copies: o.near_copies,
        collision: o.collision,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::swarm::control::policy::tests::observations;

    fn tiny(out: PathBuf) -> SwarmTrainOptions {
        let mut o = SwarmTrainOptions::reference(out, 7);
        o.data.cases = 3;
        o.data.n_min = 2;
        o.data.n_max = 3;
        o.data.hold_steps = 2;
        o.validation_cases = 1;
        o.phi_hidden = vec![8, 8];
        o.rho_hidden = vec![8];
        o.epochs = 2;
        o.batch = 64;
        o.dagger_rounds = 1;
        o.dagger_epochs = 1;
        o
    }

    #[test]
    fn training_is_byte_identical_on_re_run_and_the_file_loads() {
        let dir = std::env::temp_dir().join(format!("nr-swarm-train-{}", std::process::id()));
        let (a, b) = (dir.join("a.safetensors"), dir.join("b.safetensors"));
        let ra = train(&tiny(a.clone())).unwrap();
        let rb = train(&tiny(b.clone())).unwrap();
        assert_eq!(std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), "the weights files differ");
        let text = |r: &SwarmTrainReport, p: &PathBuf| r.markdown("cmd").replace(&p.display().to_string(), "W");
        assert_eq!(text(&ra, &a), text(&rb, &b));
        // The perturbed states and, after one DAgger round, as many visited ones.
        assert_eq!((ra.train_samples, ra.dagger_samples), (2 * (2 + 3) * (80 + 2), (2 + 3) * (80 + 2)));
        assert_eq!(ra.validation_closed_loop.2, 1);
        assert_eq!(ra.validation_samples, 2 * (80 + 2));
        assert!(ra.rms_train_mps2 > 0.0 && ra.rms_validation_mps2 > 0.0);
        let p = DeepSetPolicy::load(&a).unwrap();
        assert_eq!((p.phi().n_in(), p.rho().n_in(), p.rho().n_out()), (6, 15, 3));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn the_exported_policy_matches_the_candle_training_forward_pass() {
        let dev = Device::Cpu;
        let o = SwarmTrainOptions::reference(PathBuf::from("unused"), 3);
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let mut net = DeepSetMlp::new(&o, &mut rng, &dev).unwrap();
        // Converge the running power iterations, as training does over its steps.
        let (mut wp, mut wr) = (Vec::new(), Vec::new());
        for _ in 0..300 {
            (wp, wr) = (net.phi.weights().unwrap(), net.rho.weights().unwrap());
        }
        let policy = net.export(serde_json::json!({})).unwrap();
        let obs = observations(8, 18);
        let samples: Vec<SwarmSample> =
            obs.iter().map(|&obs| SwarmSample { case: 0, obs, target_mps2: [0.0; 3] }).collect();
        let t = SwarmTensors::of(&samples, &dev).unwrap();
        let y: Vec<Vec<f32>> = net.forward(&wp, &wr, &t).unwrap().to_vec2().unwrap();
        for (o, yc) in obs.iter().zip(&y) {
            let u = policy.accel_mps2(o);
            for k in 0..3 {
                let c = f64::from(yc[k]) * A_MAX_MPS2;
                assert!((u[k] - c).abs() < 1e-4, "f64 {u:?} vs candle f32 {yc:?}");
            }
        }
    }
}
