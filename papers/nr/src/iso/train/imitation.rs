//! Training the SN-DNN guidance policy by imitation of the global solution (Secs. 3.2 and
//! 6.2.2–6.2.4 of "Neural-Rendezvous", arXiv:2208.04883), as a library function the integrator
//! exposes as `orchestrator train nr-iso --seed N`: generate (or load from the cache) SCP data
//! for the training ISOs ([`data`]), train the SN-DNN ([`crate::nn::sn_mlp`]) on the loss (10)–(12)
//! ([`loss`]) with candle on the CPU, write the weights file ([`crate::nn::sn_dnn`]) and report the
//! loss history, timings and the terms of Lemma 1 ([`lemma1`]) on samples of the test ISOs.
//!
//! Seeded and deterministic: data samples are functions of (seed, ISO, index), the initial
//! weights and batch order come from one generator of the seed, so the same options rewrite the
//! same weights file byte for byte (only the report's wall-clock times differ).
//!
//! Departures (ours; the paper's values are lost): AdamW (no weight decay) with a cosine-decaying
//! rate rather than plain SGD; each training step draws a batch of control samples and a batch
//! of state samples (those whose Δτ fits before t_f), one epoch covering both.

use std::ops::Range;
use std::path::PathBuf;
use std::time::Instant;

use candle_core::{Device, Tensor};
use candle_nn::{AdamW, Optimizer, ParamsAdamW};
use nalgebra::{Matrix6, SMatrix};
use rand::SeedableRng;
use rand::seq::SliceRandom;
use rand_chacha::ChaCha8Rng;
use serde::Serialize;

use super::data::{self, DataOptions, Sample};
use super::lemma1;
use super::loss::{self, Batch};
use crate::iso::dynamics::constants::{
    ISO_SET_SEED, ISP_S, M0_KG, RHO_F_RADIUS_M, T_F_S, TEST_ISOS, TRAIN_ISOS, U_MAX_N,
};
use crate::iso::dynamics::navigation::NavSigmas;
use crate::iso::guidance::features::{N_FEATURES, NAMES, REFERENCE_INPUTS};
use crate::iso::guidance::scp::ScpSettings;
use crate::nn::sn_dnn::SnDnn;
use crate::nn::sn_mlp::SnMlp;

/// Everything a training run depends on.
#[derive(Debug, Clone)]
pub struct TrainOptions {
    /// The weights file to write.
    pub out: PathBuf,
    pub seed: u64,
    /// The training data (its `isos` are the training ISOs).
    pub data: DataOptions,
    /// ISOs and samples per ISO for the Lemma 1 report (never used for any choice).
    pub test_isos: Range<u32>,
    pub test_samples_per_iso: u32,
    /// Where generated data is cached (None: not cached).
    pub cache_dir: Option<PathBuf>,
    /// Threads of the data generation.
    pub threads: usize,
    pub hidden: Vec<usize>,
    /// Network inputs: the first `inputs` values of the transform (18, or the reference's 15).
    pub inputs: usize,
    pub c_sn: f64,
    /// γ of C_x = γI.
    pub gamma: f64,
    pub epochs: usize,
    pub batch: usize,
    pub lr_start: f64,
    pub lr_end: f64,
}

impl TrainOptions {
    /// The reference set-up: ISOs 0–199, 30 samples each, Δτ = 6 steps, 3 × 64 tanh, C_sn = 2,
    /// γ = 10, 400 epochs of batches of 256.
    pub fn reference(out: PathBuf, seed: u64) -> Self {
        Self {
            out,
            seed,
            data: DataOptions {
                seed,
                iso_set_seed: ISO_SET_SEED,
                isos: TRAIN_ISOS,
                samples_per_iso: 30,
                t_f_s: T_F_S,
                dt_s: crate::iso::dynamics::constants::DT_S,
                m0_kg: M0_KG,
                u_max_n: U_MAX_N,
                isp_s: ISP_S,
                rho_f_radius_m: RHO_F_RADIUS_M,
                nav: NavSigmas::default(),
                nav_scale: 1.0,
                dtau_steps: 6,
                scp: ScpSettings::default(),
            },
            test_isos: TEST_ISOS,
            test_samples_per_iso: 5,
            cache_dir: None,
            threads: 2,
            hidden: vec![64, 64, 64],
            inputs: N_FEATURES,
            c_sn: 2.0,
            // Chosen by the paper's Fig. 9 rule (smallest delivery error and spread without state
            // uncertainty) on held-out training ISOs 180–199 among 0.1, 1, 10 (crate README).
            gamma: 10.0,
            epochs: 400,
            batch: 256,
            lr_start: 3e-3,
            lr_end: 3e-5,
        }
    }
}

/// What a training run reports.
#[derive(Debug, Clone, Serialize)]
pub struct TrainReport {
    pub weights: PathBuf,
    pub seed: u64,
    pub gamma: f64,
    pub c_sn: f64,
    pub hidden: Vec<usize>,
    pub epochs: usize,
    pub control_samples: usize,
    pub state_samples: usize,
    pub soft_samples: usize,
    pub data_from_cache: bool,
    pub data_s: f64,
    pub test_data_s: f64,
    pub train_s: f64,
    pub input_scale: Vec<f64>,
    pub u_scale_n: f64,
    /// Mean (control term, state term) of the first and last epochs.
    pub first_epoch: (f64, f64),
    pub last_epoch: (f64, f64),
    pub lemma1: lemma1::Lemma1,
}

impl TrainReport {
    /// The report file: deterministic (the same options give the same bytes), so no wall-clock
    /// times and no word of the cache (see [`TrainReport::timings`]). `command` reproduces it.
    pub fn markdown(&self, command: &str) -> String {
        let l = &self.lemma1;
        format!(
            "# SN-DNN training (seed {seed})\n\n\
             Reproduce: `{command}` (from the repository root).\n\n\
             Weights: `{w}`; {h:?} tanh, C_sn = {c}, γ = {g}, {ep} epochs.\n\n\
             Data: {nc} control samples, {ns} state samples ({soft} with the target out of reach).\n\n\
             Loss (control, state): first epoch ({f0:.4e}, {f1:.4e}), last ({l0:.4e}, {l1:.4e}); output scale {us:.4} N.\n\n\
             ## Lemma 1 ({nt} training, {ne} test samples)\n\n\
             | term | value |\n|---|---|\n\
             | ε_train (max training error) | {et:.4e} N (RMS {rt:.4e}) |\n\
             | r (max test-to-nearest-training distance, normalised input) | {r:.4e} |\n\
             | L_ℓ bound C_sn^L·max|u| | {lb:.4e} N |\n| L_ℓ empirical | {le:.4e} N |\n\
             | L_mpc empirical | {lm:.4e} N |\n\
             | bound ε_train + r(L_ℓ + L_mpc) | {b:.4e} N |\n\
             | measured sup_test ‖u_ℓ − u_mpc‖ | {st:.4e} N (RMS {rte:.4e}) |\n",
            seed = self.seed,
            w = self.weights.display(),
            h = self.hidden,
            c = self.c_sn,
            g = self.gamma,
            ep = self.epochs,
            nc = self.control_samples,
            ns = self.state_samples,
            soft = self.soft_samples,
            f0 = self.first_epoch.0,
            f1 = self.first_epoch.1,
            l0 = self.last_epoch.0,
            l1 = self.last_epoch.1,
            us = self.u_scale_n,
            nt = l.training_samples,
            ne = l.test_samples,
            et = l.eps_train_n,
            rt = l.rms_train_n,
            r = l.r,
            lb = l.l_ell_bound_n,
            le = l.l_ell_empirical_n,
            lm = l.l_mpc_empirical_n,
            b = l.bound_n,
            st = l.sup_test_n,
            rte = l.rms_test_n,
        )
    }

    /// The wall-clock times of the run, in words (not part of the report file).
    pub fn timings(&self) -> String {
        format!(
            "data generation {:.1} s{}, test samples {:.1} s, training {:.1} s",
            self.data_s,
            if self.data_from_cache { " (from the cache)" } else { "" },
            self.test_data_s,
            self.train_s
        )
    }
}

/// A training run that could not finish.
#[derive(Debug, thiserror::Error)]
pub enum TrainError {
    #[error("training options: {0}")]
    Options(String),
    #[error("training data: {0}")]
    Data(String),
    #[error("candle: {0}")]
    Candle(#[from] candle_core::Error),
    #[error("weights {path}: {reason}")]
    Write { path: PathBuf, reason: String },
}

/// Normalisation of inputs, outputs and the state of the rollout.
struct Scales {
    input: [f64; N_FEATURES],
    u_n: f64,
    p_m: f64,
    v_mps: f64,
}

impl Scales {
    fn of(samples: &[Sample], o: &TrainOptions) -> Self {
        let mut input = [0.0f64; N_FEATURES];
        let mut u_n = 0.0f64;
        for s in samples {
            input.iter_mut().zip(&s.f0).for_each(|(m, x)| *m = m.max(x.abs()));
            u_n = u_n.max(s.u0_n.amax());
        }
        input.iter_mut().for_each(|m| *m = if *m > 0.0 { *m } else { 1.0 });
        let u_n = if u_n > 0.0 { u_n } else { o.data.u_max_n };
        let tau = o.data.dtau_steps as f64 * o.data.dt_s;
        let a = u_n / o.data.m0_kg;
        Self { input, u_n, p_m: 0.5 * a * tau * tau, v_mps: a * tau }
    }
    fn d(&self) -> Matrix6<f64> {
        Matrix6::from_diagonal(&nalgebra::Vector6::new(
            self.p_m, self.p_m, self.p_m, self.v_mps, self.v_mps, self.v_mps,
        ))
    }
}

/// The data as scaled f32 tensors.
struct Tensors {
    z0: Tensor,
    y0: Tensor,
    z: Vec<Tensor>,
    ft: Vec<Tensor>,
    at: Vec<Tensor>,
    bt: Vec<Tensor>,
    y: Vec<Tensor>,
    n_state: usize,
}

fn tensors(samples: &[Sample], sc: &Scales, dtau: usize, n_in: usize, dev: &Device) -> candle_core::Result<Tensors> {
    let nc = samples.len();
    let f32s = |it: &mut dyn Iterator<Item = f64>| it.map(|x| x as f32).collect::<Vec<f32>>();
    let z0 = f32s(&mut samples.iter().flat_map(|s| s.f0.iter().zip(&sc.input).take(n_in).map(|(x, k)| x / k)));
    let y0 = f32s(&mut samples.iter().flat_map(|s| s.u0_n.iter().map(|u| u / sc.u_n).collect::<Vec<_>>()));
    let st: Vec<&Sample> = samples.iter().filter(|s| s.nodes.len() == dtau).collect();
    let ns = st.len();
    let (d, dinv) = (sc.d(), sc.d().try_inverse().expect("positive scales"));
    let inv_in =
        SMatrix::<f64, N_FEATURES, N_FEATURES>::from_diagonal(&SMatrix::<f64, N_FEATURES, 1>::from_fn(|i, _| {
            1.0 / sc.input[i]
        }));
    let (mut z, mut ft, mut at, mut bt, mut y) = (Vec::new(), Vec::new(), Vec::new(), Vec::new(), Vec::new());
    for j in 0..dtau {
        let mut zj = Vec::with_capacity(ns * N_FEATURES);
        let (mut fj, mut aj, mut bj, mut yj) = (Vec::new(), Vec::new(), Vec::new(), Vec::new());
        for s in &st {
            let n = &s.nodes[j];
            zj.extend(n.f.iter().zip(&sc.input).take(n_in).map(|(x, k)| (x / k) as f32));
            // A matrix's column-major values are its transpose's row-major ones: F̃ᵀ (6 × n_in),
            // Ãᵀ (6 × 6), B̃ᵀ (3 × 6) for the row-vector products of the roll-out.
            fj.extend((inv_in * n.f_jac * d).rows(0, n_in).iter().map(|x| *x as f32));
            aj.extend((dinv * n.a * d).iter().map(|x| *x as f32));
            bj.extend((dinv * n.b * sc.u_n).iter().map(|x| *x as f32));
            yj.extend(n.u_n.iter().map(|u| (u / sc.u_n) as f32));
        }
        z.push(Tensor::from_vec(zj, (ns, n_in), dev)?);
        ft.push(Tensor::from_vec(fj, (ns, 6, n_in), dev)?);
        at.push(Tensor::from_vec(aj, (ns, 6, 6), dev)?);
        bt.push(Tensor::from_vec(bj, (ns, 3, 6), dev)?);
        y.push(Tensor::from_vec(yj, (ns, 3), dev)?);
    }
    Ok(Tensors {
        z0: Tensor::from_vec(z0, (nc, n_in), dev)?,
        y0: Tensor::from_vec(y0, (nc, 3), dev)?,
        z,
        ft,
        at,
        bt,
        y,
        n_state: ns,
    })
}

fn batch(t: &Tensors, ctrl: &[u32], state: &[u32], dev: &Device) -> candle_core::Result<Batch> {
    let ic = Tensor::from_slice(ctrl, ctrl.len(), dev)?;
    let is = Tensor::from_slice(state, state.len(), dev)?;
    let sel = |v: &[Tensor]| v.iter().map(|x| x.index_select(&is, 0)).collect::<candle_core::Result<Vec<_>>>();
    Ok(Batch {
        z0: t.z0.index_select(&ic, 0)?,
        y0: t.y0.index_select(&ic, 0)?,
        z: sel(&t.z)?,
        ft: sel(&t.ft)?,
        at: sel(&t.at)?,
        bt: sel(&t.bt)?,
        y: sel(&t.y)?,
    })
}

/// Train for `o.epochs`; returns the network and the mean (control, state) terms per epoch.
fn fit(o: &TrainOptions, t: &Tensors, n_ctrl: usize, dev: &Device) -> Result<(SnMlp, Vec<(f64, f64)>), TrainError> {
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed ^ 0x4e52_5f53_4e44_4e4e);
    rng.set_stream(1);
    let mut sizes = vec![o.inputs];
    sizes.extend(&o.hidden);
    sizes.push(3);
    let mut net = SnMlp::new(&sizes, o.c_sn, &mut rng, dev)?;
    let mut opt = AdamW::new(net.vars(), ParamsAdamW { lr: o.lr_start, weight_decay: 0.0, ..Default::default() })?;
    let mut ctrl: Vec<u32> = (0..n_ctrl as u32).collect();
    let mut state: Vec<u32> = (0..t.n_state as u32).collect();
    let nb = n_ctrl.div_ceil(o.batch);
    let sb = t.n_state.div_ceil(nb).max(usize::from(t.n_state > 0));
    let total = (o.epochs * nb).max(1) as f64;
    let mut history = Vec::with_capacity(o.epochs);
    for epoch in 0..o.epochs {
        ctrl.shuffle(&mut rng);
        state.shuffle(&mut rng);
        let (mut su, mut sx) = (0.0, 0.0);
        for bi in 0..nb {
            let progress = (epoch * nb + bi) as f64 / total;
            opt.set_learning_rate(
                o.lr_end + 0.5 * (o.lr_start - o.lr_end) * (1.0 + (std::f64::consts::PI * progress).cos()),
            );
            let c = &ctrl[bi * o.batch..((bi + 1) * o.batch).min(n_ctrl)];
            let s = &state[(bi * sb).min(t.n_state)..((bi + 1) * sb).min(t.n_state)];
            let b = batch(t, c, s, dev)?;
            let ws = net.weights()?;
            let (lu, lx) = loss::terms(&net, &ws, &b)?;
            let l = (&lu + (&lx * o.gamma)?)?;
            opt.backward_step(&l)?;
            su += f64::from(lu.to_scalar::<f32>()?) / nb as f64;
            sx += f64::from(lx.to_scalar::<f32>()?) / nb as f64;
        }
        history.push((su, sx));
    }
    Ok((net, history))
}

/// Generate or load the data, train, write the weights file, report.
pub fn train(o: &TrainOptions) -> Result<TrainReport, TrainError> {
    if o.epochs == 0
        || o.batch == 0
        || o.hidden.is_empty()
        || !(o.c_sn.is_finite() && o.c_sn > 0.0)
        || !(o.gamma.is_finite() && o.gamma >= 0.0)
    {
        return Err(TrainError::Options("epochs, batch and layers must be ≥ 1, C_sn > 0, γ ≥ 0".into()));
    }
    if o.inputs != N_FEATURES && o.inputs != REFERENCE_INPUTS {
        return Err(TrainError::Options(format!("inputs = {}: {N_FEATURES} or {REFERENCE_INPUTS}", o.inputs)));
    }
    if o.data.isos.start >= o.data.isos.end || o.data.samples_per_iso == 0 {
        return Err(TrainError::Options("no training ISOs or samples".into()));
    }
    let started = Instant::now();
    let (samples, from_cache) =
        data::load_or_generate(&o.data, o.cache_dir.as_deref(), o.threads).map_err(TrainError::Data)?;
    let data_s = started.elapsed().as_secs_f64();
    let started = Instant::now();
    let test_opts = DataOptions {
        isos: o.test_isos.clone(),
        samples_per_iso: o.test_samples_per_iso,
        dtau_steps: 0,
        ..o.data.clone()
    };
    let (test, _) = data::load_or_generate(&test_opts, o.cache_dir.as_deref(), o.threads).map_err(TrainError::Data)?;
    let test_data_s = started.elapsed().as_secs_f64();

    let started = Instant::now();
    let dev = Device::Cpu;
    let sc = Scales::of(&samples, o);
    let t = tensors(&samples, &sc, o.data.dtau_steps, o.inputs, &dev)?;
    let (mlp, history) = fit(o, &t, samples.len(), &dev)?;
    let train_s = started.elapsed().as_secs_f64();

    let meta = serde_json::json!({
        "features": &NAMES[..o.inputs],
        "outputs": ["u_x_n", "u_y_n", "u_z_n"],
        "output_frame": "LVLH of the estimated ISO at the decision time; held in inertial axes over the control interval",
        "activation": "tanh (every layer, the output's included)",
        "training": {
            "seed": o.seed, "gamma": o.gamma, "epochs": o.epochs, "batch": o.batch, "hidden": o.hidden,
            "lr": [o.lr_start, o.lr_end], "data_hash": format!("{:016x}", o.data.hash()), "data": o.data,
        },
    });
    let net = mlp.export(sc.input[..o.inputs].to_vec(), vec![sc.u_n; 3], meta).map_err(TrainError::Options)?;
    let write_err = |reason: String| TrainError::Write { path: o.out.clone(), reason };
    if let Some(dir) = o.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| write_err(e.to_string()))?;
    }
    std::fs::write(&o.out, net.to_bytes()).map_err(|e| write_err(e.to_string()))?;
    let check = SnDnn::load(&o.out).map_err(|e| write_err(e.to_string()))?;
    Ok(TrainReport {
        weights: o.out.clone(),
        seed: o.seed,
        gamma: o.gamma,
        c_sn: o.c_sn,
        hidden: o.hidden.clone(),
        epochs: o.epochs,
        control_samples: samples.len(),
        state_samples: t.n_state,
        soft_samples: samples.iter().filter(|s| s.soft).count(),
        data_from_cache: from_cache,
        data_s,
        test_data_s,
        train_s,
        input_scale: sc.input[..o.inputs].to_vec(),
        u_scale_n: sc.u_n,
        first_epoch: history[0],
        last_epoch: *history.last().expect("≥ 1 epoch"),
        lemma1: lemma1::lemma1(&check, &samples, &test),
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tiny(out: PathBuf, cache: Option<PathBuf>) -> TrainOptions {
        let mut o = TrainOptions::reference(out, 5);
        o.data.isos = 0..3;
        o.data.samples_per_iso = 4;
        o.test_isos = 200..202;
        o.test_samples_per_iso = 2;
        o.epochs = 3;
        o.batch = 5;
        o.hidden = vec![8, 8];
        o.cache_dir = cache;
        o
    }

    #[test]
    fn training_is_byte_identical_on_re_run_with_or_without_the_cache_and_reports_lemma_1() {
        let dir = std::env::temp_dir().join(format!("nr-train-{}", std::process::id()));
        let (a, b, c) = (dir.join("a.safetensors"), dir.join("b.safetensors"), dir.join("c.safetensors"));
        let ra = train(&tiny(a.clone(), None)).unwrap();
        let rb = train(&tiny(b.clone(), Some(dir.join("cache")))).unwrap();
        let rc = train(&tiny(c.clone(), Some(dir.join("cache")))).unwrap();
        assert!(!rb.data_from_cache && rc.data_from_cache);
        let (ba, bb, bc) = (std::fs::read(&a).unwrap(), std::fs::read(&b).unwrap(), std::fs::read(&c).unwrap());
        assert!(ba == bb && bb == bc, "the weights files differ");
        // The report file holds no wall-clock time: it is the same bytes too.
        let text = |r: &TrainReport, path: &PathBuf| r.markdown("cmd").replace(&path.display().to_string(), "W");
        assert_eq!(text(&ra, &a), text(&rc, &c));
        assert_eq!((ra.control_samples, ra.lemma1.test_samples), (12, 4));
        let l = &ra.lemma1;
        assert!(l.eps_train_n > 0.0 && l.r > 0.0 && l.l_mpc_empirical_n > 0.0);
        assert!(l.l_ell_empirical_n <= l.l_ell_bound_n, "the SN-DNN's measured Lipschitz constant exceeds its bound");
        // The bound of Lemma 1 holds on these samples (it must, by construction of L_mpc and r).
        assert!(l.sup_test_n <= l.bound_n, "{l:?}");
        let net = SnDnn::load(&a).unwrap();
        assert_eq!((net.n_in(), net.n_out(), net.c_sn()), (N_FEATURES, 3, 2.0));
        let _ = std::fs::remove_dir_all(&dir);
    }
}
