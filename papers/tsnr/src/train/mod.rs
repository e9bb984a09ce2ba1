//! `orchestrator train tsnr-tension`: generate trajectories with our net plant ([`data`]), train
//! the tension predictor Φ of eqs. (7)–(11) with candle ([`model`]), write its weights file
//! (read by `crate::predictor`, format documented there) and a report of held-out errors
//! against the plant's true tension. Seeded and deterministic: the same arguments rewrite the same
//! weights file, byte for byte (the report's wall-clock times differ).

pub mod data;
pub mod model;

use std::path::{Path, PathBuf};
use std::time::Instant;

use crate::predictor::{FEATURES_PER_STEP, TensionPredictor, base_metadata, relative_features, weights_file_bytes};
use candle_core::{Device, Tensor};
use cohort_report::markdown::MdTable;
use serde_json::json;

/// Settings of one training run (the command line's).
#[derive(Debug, Clone)]
pub struct Options {
    pub out: PathBuf,
    pub seed: u64,
    pub trajectories: u64,
    pub epochs: usize,
    /// N_t: history samples in, predicted steps out.
    pub n_t: usize,
}

/// Share of the trajectories held out for the report (the last ones by index).
const HELD_OUT_SHARE: f64 = 0.2;
/// |T| below which a component counts as slack in the under-prediction share, N.
const SLACK_N: f64 = 0.1;

/// Window `k`'s input as the network reads it (after the predictor's fixed transform).
fn network_input(w: &data::Windows, k: usize) -> Vec<f64> {
    let mut v = Vec::with_capacity(w.input(k).len());
    relative_features(w.input(k), &mut v);
    v
}

/// Input mean and standard deviation per feature, output scale per output (per-axis RMS).
struct Normalisation {
    mean: Vec<f64>,
    std: Vec<f64>,
    scale: Vec<f64>,
}

impl Normalisation {
    fn of(w: &data::Windows) -> Self {
        let (ni, no) = (FEATURES_PER_STEP * w.n_t, 3 * w.n_t);
        let n = w.count as f64;
        let mut mean = vec![0.0; ni];
        for k in 0..w.count {
            mean.iter_mut().zip(network_input(w, k)).for_each(|(m, x)| *m += x / n);
        }
        let mut var = vec![0.0; ni];
        for k in 0..w.count {
            var.iter_mut().zip(network_input(w, k)).zip(&mean).for_each(|((v, x), m)| *v += (x - m) * (x - m) / n);
        }
        // A feature that never varies (none in practice) is passed through unscaled.
        let std = var.iter().map(|v| if v.sqrt() > 1e-9 { v.sqrt() } else { 1.0 }).collect();
        let mut sq = [0.0; 3];
        for k in 0..w.count {
            for (o, t) in w.target(k).iter().enumerate() {
                sq[o % 3] += t * t / (n * w.n_t as f64);
            }
        }
        let scale = (0..no).map(|o| sq[o % 3].sqrt().max(1e-3)).collect();
        Self { mean, std, scale }
    }

    fn tensors(&self, w: &data::Windows, dev: &Device) -> candle_core::Result<model::Data> {
        let (ni, no) = (self.mean.len(), self.scale.len());
        let mut x = Vec::with_capacity(w.count * ni);
        let mut y = Vec::with_capacity(w.count * no);
        for k in 0..w.count {
            x.extend(network_input(w, k).iter().zip(&self.mean).zip(&self.std).map(|((v, m), s)| ((v - m) / s) as f32));
            y.extend(w.target(k).iter().zip(&self.scale).map(|(t, s)| (t / s) as f32));
        }
        Ok(model::Data {
            x: Tensor::from_vec(x, (w.count, ni), dev)?,
            y: Tensor::from_vec(y, (w.count, no), dev)?,
            n: w.count,
        })
    }
}

/// Held-out errors of one forecast, N.
#[derive(Debug, Clone, serde::Serialize)]
struct Errors {
    rms_n: f64,
    rms_by_step_n: Vec<f64>,
    max_abs_n: f64,
    /// Share of the components with |T| > SLACK_N that the forecast under-predicts in magnitude
    /// (sign(T)·(T − T̂) > 0).
    under_share: f64,
    /// The same on the first predicted step only (where the asymmetric term (10) acts).
    under_share_first_step: f64,
    /// Share of the vectors with ‖T‖ > SLACK_N whose forecast has a smaller norm.
    under_share_norm: f64,
}

fn errors(w: &data::Windows, predict: impl Fn(usize) -> Vec<f64>) -> Errors {
    let n_t = w.n_t;
    let (mut sq, mut sq_step, mut max) = (0.0, vec![0.0; n_t], 0.0f64);
    let (mut under, mut taut, mut under1, mut taut1, mut under_norm, mut taut_norm) =
        (0u64, 0u64, 0u64, 0u64, 0u64, 0u64);
    for k in 0..w.count {
        let (t, p) = (w.target(k), predict(k));
        for n in 0..n_t {
            let (tn, pn) = (&t[3 * n..3 * n + 3], &p[3 * n..3 * n + 3]);
            for a in 0..3 {
                let e = tn[a] - pn[a];
                sq += e * e;
                sq_step[n] += e * e;
                max = max.max(e.abs());
                if tn[a].abs() > SLACK_N {
                    let short = tn[a].signum() * e > 0.0;
                    taut += 1;
                    under += u64::from(short);
                    if n == 0 {
                        taut1 += 1;
                        under1 += u64::from(short);
                    }
                }
            }
            let norm = |v: &[f64]| v.iter().map(|x| x * x).sum::<f64>().sqrt();
            if norm(tn) > SLACK_N {
                taut_norm += 1;
                under_norm += u64::from(norm(pn) < norm(tn));
            }
        }
    }
    let c = w.count as f64;
    let share = |a: u64, b: u64| if b == 0 { 0.0 } else { a as f64 / b as f64 };
    Errors {
        rms_n: (sq / (c * 3.0 * n_t as f64)).sqrt(),
        rms_by_step_n: sq_step.iter().map(|s| (s / (c * 3.0)).sqrt()).collect(),
        max_abs_n: max,
        under_share: share(under, taut),
        under_share_first_step: share(under1, taut1),
        under_share_norm: share(under_norm, taut_norm),
    }
}

/// Run the whole pipeline; returns the report's Markdown.
pub fn run(o: &Options, command: &str) -> Result<String, String> {
    let e = |what: &'static str| move |err: candle_core::Error| format!("{what}: {err}");
    if o.trajectories < 5 {
        return Err(format!("--trajectories {}: at least 5 (one fifth is held out)", o.trajectories));
    }
    if o.epochs == 0 || o.n_t == 0 || o.n_t > 50 {
        return Err("--epochs must be ≥ 1 and N_t in 1..=50".into());
    }
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get());
    let held_out = ((o.trajectories as f64 * HELD_OUT_SHARE).round() as u64).max(1);
    let n_train = o.trajectories - held_out;

    let t_data = Instant::now();
    let trajectories = data::simulate_all(o.seed, 0..o.trajectories, threads);
    let saturated: usize = trajectories.iter().map(|t| t.saturated_steps).sum();
    let (train_tr, test_tr) = trajectories.split_at(n_train as usize);
    let train_w = data::windows(train_tr, o.n_t);
    let test_w = data::windows(test_tr, o.n_t);
    let data_s = t_data.elapsed().as_secs_f64();
    tracing::info!(
        "data: {} trajectories ({} train, {held_out} held out), {} + {} windows, {data_s:.1} s",
        o.trajectories,
        n_train,
        train_w.count,
        test_w.count
    );

    let t_train = Instant::now();
    let dev = Device::Cpu;
    let norm = Normalisation::of(&train_w);
    let train_d = norm.tensors(&train_w, &dev).map_err(e("training tensors"))?;
    let hyper = model::Hyper::default();
    let mut sizes = vec![FEATURES_PER_STEP * o.n_t];
    sizes.extend(&hyper.hidden);
    sizes.push(3 * o.n_t);
    let mut rng = model::rng(o.seed);
    let mlp = model::Mlp::new(&sizes, &mut rng, &dev).map_err(e("network"))?;
    let losses = model::train(&mlp, &train_d, &hyper, o.n_t, o.epochs, &mut rng, |ep, l| {
        tracing::info!("epoch {}/{}: loss {l:.5} ({:.0} s)", ep + 1, o.epochs, t_train.elapsed().as_secs_f64())
    })
    .map_err(e("training"))?;
    let train_s = t_train.elapsed().as_secs_f64();

    // Held-out errors with the f64 inference the agents run, from the file as written.
    let t_eval = Instant::now();
    let layers = mlp.export().map_err(e("export"))?;
    let candle_test = {
        let d = norm.tensors(&test_w, &dev).map_err(e("held-out tensors"))?;
        let y = mlp.forward(&d.x).map_err(e("held-out forward"))?;
        y.to_vec2::<f32>().map_err(e("held-out forward"))?
    };
    let mut meta = base_metadata(o.n_t, data::DT_S);
    meta.insert("hidden".into(), json!(hyper.hidden));
    meta.insert("normalisation".into(), json!("z = (x - input_mean) / input_std; T = output_scale * y"));
    meta.insert(
        "loss".into(),
        json!({"gamma": hyper.gamma, "eta": hyper.eta, "alpha": hyper.alpha, "beta": hyper.beta,
               "form": "alpha * L_e(10) on step 1 + beta * sum_n eta^(n-1) |e_n| (11), L1 on T / output_scale"}),
    );
    meta.insert(
        "training".into(),
        json!({"seed": o.seed, "trajectories": o.trajectories, "held_out_trajectories": held_out,
               "train_windows": train_w.count, "epochs": o.epochs, "batch": hyper.batch,
               "lr": [hyper.lr_start, hyper.lr_end], "optimiser": "AdamW (no weight decay), cosine lr",
               "final_loss": losses.last().copied().unwrap_or(f64::NAN),
               "data": "cohort_paper_tsnr::net with our net (11x11, EA 200 N, c 0.1, 1 ms RK4), random \
                        three-phase capture paths tracked by a saturated PD (papers/tsnr/src/train/data.rs)"}),
    );
    meta.insert("command".into(), json!(command));
    let meta_value = serde_json::Value::Object(meta.clone().into_iter().collect());
    let bytes = weights_file_bytes(&layers, &norm.mean, &norm.std, &norm.scale, &meta_value)?;
    let predictor = TensionPredictor::from_bytes(&bytes, &o.out).map_err(|e| e.to_string())?;
    let predicted: Vec<Vec<f64>> = (0..test_w.count)
        .map(|k| predictor.predict(test_w.input(k)).map(|t| t.into_iter().flatten().collect()))
        .collect::<Result<_, _>>()?;
    let dnn = errors(&test_w, |k| predicted[k].clone());
    let hold = errors(&test_w, |k| test_w.target(k)[0..3].repeat(o.n_t));
    let zero = errors(&test_w, |_| vec![0.0; 3 * o.n_t]);
    // f32 candle against f64 inference on the same held-out inputs.
    let mut candle_gap = 0.0f64;
    for (k, row) in candle_test.iter().enumerate() {
        for (o_i, y) in row.iter().enumerate() {
            candle_gap = candle_gap.max((*y as f64 * norm.scale[o_i] - predicted[k][o_i]).abs());
        }
    }
    let signal_rms = (test_w.targets.iter().map(|t| t * t).sum::<f64>() / test_w.targets.len() as f64).sqrt();
    let eval_s = t_eval.elapsed().as_secs_f64();

    if let Some(dir) = o.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(dir).map_err(|e| format!("{}: {e}", dir.display()))?;
    }
    std::fs::write(&o.out, &bytes).map_err(|e| format!("{}: {e}", o.out.display()))?;

    let timing = json!({"threads": threads, "data_s": data_s, "train_s": train_s, "eval_s": eval_s,
                        "total_s": data_s + train_s + eval_s});
    let report = json!({
        "weights": o.out.display().to_string(), "bytes": bytes.len(), "command": command,
        "metadata": meta_value, "epoch_losses": losses, "saturated_mu_steps_share":
            saturated as f64 / (o.trajectories as f64 * data::STEPS as f64),
        "held_out": {"windows": test_w.count, "signal_rms_n": signal_rms, "dnn": dnn, "hold_measured": hold,
                     "zero": zero, "max_abs_candle_f32_vs_f64_n": candle_gap},
        "wall_clock": timing,
    });
    let md = markdown(o, command, &report, &dnn, &hold, &zero, bytes.len(), signal_rms, candle_gap);
    let (json_path, md_path) = report_paths(&o.out);
    std::fs::write(&json_path, serde_json::to_string_pretty(&report).map_err(|e| e.to_string())? + "\n")
        .map_err(|e| format!("{}: {e}", json_path.display()))?;
    std::fs::write(&md_path, &md).map_err(|e| format!("{}: {e}", md_path.display()))?;
    Ok(md)
}

/// `DIR/NAME.safetensors` → (`DIR/NAME-report.json`, `DIR/NAME-report.md`).
pub fn report_paths(weights: &Path) -> (PathBuf, PathBuf) {
    let stem = weights.file_stem().map_or("tension".into(), |s| s.to_string_lossy().into_owned());
    (weights.with_file_name(format!("{stem}-report.json")), weights.with_file_name(format!("{stem}-report.md")))
}

#[allow(clippy::too_many_arguments)]
fn markdown(
    o: &Options,
    command: &str,
    report: &serde_json::Value,
    dnn: &Errors,
    hold: &Errors,
    zero: &Errors,
    bytes: usize,
    signal_rms: f64,
    candle_gap: f64,
) -> String {
    let w = &report["wall_clock"];
    let held = &report["metadata"]["training"];
    let mut s = String::new();
    s += "# TSNR tension predictor: training report\n\n";
    s += &format!(
        "Written by `orchestrator train tsnr-tension` together with `{}` ({bytes} bytes). Reproduce with\n\n\
         ```sh\n{command}\n```\n\n\
         (same arguments, same weights file byte for byte; only the wall-clock times below change).\n\n",
        o.out.file_name().map_or(String::new(), |f| f.to_string_lossy().into_owned())
    );
    s += "## Set-up\n\n";
    s += &format!(
        "- Data: {} trajectories of 30 s from our net plant (`cohort_paper_tsnr::net`, our net, 1 ms \
         RK4 sub-steps), random three-phase capture paths flown by a saturated PD tracker \
         (`papers/tsnr/src/train/data.rs`); the last {} are held out. {} training windows \
         (every MU, every step), {} held-out windows. The paper used 1000 MuJoCo trajectories.\n",
        o.trajectories, held["held_out_trajectories"], held["train_windows"], report["held_out"]["windows"]
    );
    s += &format!(
        "- Features (eq. (7)): N_t = {} samples of 27 values (own state, the two adjacent MUs' states, the \
         three thrusts), Δt = {} s; outputs T_i(t_e + nΔt), n = 1…{} (N). Layout: \
         `papers/tsnr/src/predictor.rs`.\n",
        o.n_t,
        data::DT_S,
        o.n_t
    );
    let h = model::Hyper::default();
    s += &format!(
        "- Network (eq. (8)): ReLU MLP {} → {:?} → {}, f32; loss (9)–(11) with γ = {}, η_n = {}^(n−1), α = {}, \
         β = {}; AdamW, batch {}, lr {} → {} (cosine), {} epochs, seed {}.\n\n",
        FEATURES_PER_STEP * o.n_t,
        h.hidden,
        3 * o.n_t,
        h.gamma,
        h.eta,
        h.alpha,
        h.beta,
        h.batch,
        h.lr_start,
        h.lr_end,
        o.epochs,
        o.seed
    );
    s += "## Held-out errors against the plant's true tension (N)\n\n";
    s += &format!("RMS of the true tension components over the held-out horizons: {signal_rms:.3} N.\n\n");
    let mut t = MdTable::new([
        "forecast",
        "RMS",
        "RMS step 1",
        "RMS step N_t",
        "max abs",
        "under-predicted (taut components)",
        "step 1 only",
        "by norm",
    ]);
    for (name, e) in [("DNN (this file, f64 inference)", dnn), ("hold the measured T(t_k)", hold), ("zero", zero)] {
        let pct = |x: f64| format!("{:.1} %", 100.0 * x);
        t.row([
            name.to_string(),
            format!("{:.3}", e.rms_n),
            format!("{:.3}", e.rms_by_step_n[0]),
            format!("{:.3}", e.rms_by_step_n[o.n_t - 1]),
            format!("{:.2}", e.max_abs_n),
            pct(e.under_share),
            pct(e.under_share_first_step),
            pct(e.under_share_norm),
        ]);
    }
    s += &t.to_string();
    s += "\nRMS by predicted step n (DNN / hold):";
    for n in 0..o.n_t {
        s += &format!(" {}: {:.3} / {:.3};", n + 1, dnn.rms_by_step_n[n], hold.rms_by_step_n[n]);
    }
    s += "\n\nUnder-predicted: the share of the components with |T| > 0.1 N whose forecast falls short of T in \
          magnitude (sign(T)·(T − T̂) > 0); \"step 1 only\" is where the asymmetric term (10) acts (γ = 0.3 aims \
          at the 70 % quantile of |T|); \"by norm\": ‖T̂‖ < ‖T‖ among the vectors with ‖T‖ > 0.1 N. Counting \
          only where the net is taut conditions on large true values, which pushes these shares up for any \
          forecast that is not exact.";
    s += "\n\n\"Hold the measured T(t_k)\" is what an agent knows without a model: the tension it measures when it \
          decides (the first predicted step), held over the horizon (`cohort_paper_tsnr::forecast::HoldMeasured`). \
          It is exact at step 1 by construction.\n\n";
    s += &format!(
        "f32 candle forward pass vs the f64 inference of `cohort_paper_tsnr::predictor` on every held-out window: max \
         difference {candle_gap:.2e} N.\n\n"
    );
    s += "## Wall-clock time\n\n";
    s += &format!(
        "{} threads for the data, candle's CPU threads for training: data {:.0} s, training {:.0} s, evaluation {:.0} s, \
         total {:.0} s.\n",
        w["threads"],
        w["data_s"].as_f64().unwrap_or(0.0),
        w["train_s"].as_f64().unwrap_or(0.0),
        w["eval_s"].as_f64().unwrap_or(0.0),
        w["total_s"].as_f64().unwrap_or(0.0)
    );
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use rand::{Rng, SeedableRng};

    #[test]
    fn f64_inference_equals_the_candle_forward_pass() {
        // A briefly trained network on random data: the file written from it, read back by
        // `crate::predictor`, must give candle's outputs to f32 precision.
        let dev = Device::Cpu;
        let n_t = 2;
        let (ni, no) = (FEATURES_PER_STEP * n_t, 3 * n_t);
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(3);
        let n = 256;
        let x: Vec<f32> = (0..n * ni).map(|_| rng.random_range(-2.0..2.0)).collect();
        let y: Vec<f32> = (0..n * no).map(|_| rng.random_range(-1.0..1.0)).collect();
        let data = model::Data {
            x: Tensor::from_vec(x.clone(), (n, ni), &dev).unwrap(),
            y: Tensor::from_vec(y, (n, no), &dev).unwrap(),
            n,
        };
        let h = model::Hyper { hidden: vec![16, 16], batch: 64, ..Default::default() };
        let mlp = model::Mlp::new(&[ni, 16, 16, no], &mut rng, &dev).unwrap();
        let losses = model::train(&mlp, &data, &h, n_t, 3, &mut rng, |_, _| {}).unwrap();
        assert!(losses.iter().all(|l| l.is_finite()));
        let (mean, std, scale) = (vec![0.0; ni], vec![1.0; ni], vec![1.5; no]);
        let meta = serde_json::Value::Object(base_metadata(n_t, 0.1).into_iter().collect());
        let bytes = weights_file_bytes(&mlp.export().unwrap(), &mean, &std, &scale, &meta).unwrap();
        let p = TensionPredictor::from_bytes(&bytes, Path::new("t.safetensors")).unwrap();
        // The predictor applies its fixed relative transform first: feed candle the same.
        let rel: Vec<f32> = x
            .chunks(ni)
            .flat_map(|h| {
                let mut v = Vec::new();
                relative_features(&h.iter().map(|v| *v as f64).collect::<Vec<_>>(), &mut v);
                v.into_iter().map(|v| v as f32)
            })
            .collect();
        let rel = Tensor::from_vec(rel, (n, ni), &dev).unwrap();
        let want = mlp.forward(&rel).unwrap().to_vec2::<f32>().unwrap();
        let mut worst = 0.0f64;
        for k in 0..n {
            let hist: Vec<f64> = x[k * ni..(k + 1) * ni].iter().map(|v| *v as f64).collect();
            let got: Vec<f64> = p.predict(&hist).unwrap().into_iter().flatten().collect();
            for o in 0..no {
                let c = want[k][o] as f64 * 1.5;
                worst = worst.max((got[o] - c).abs() / (1.0 + c.abs()));
            }
        }
        assert!(worst < 1e-5, "largest relative difference {worst:e}");
    }

    #[test]
    fn the_asymmetric_loss_charges_under_prediction_more() {
        let dev = Device::Cpu;
        let h = model::Hyper { gamma: 0.2, eta: 0.5, alpha: 1.0, beta: 0.0, ..Default::default() };
        let y = Tensor::from_vec(vec![2.0f32, -2.0, 0.0], (1, 3), &dev).unwrap();
        let l = |yhat: [f32; 3]| {
            let yh = Tensor::from_vec(yhat.to_vec(), (1, 3), &dev).unwrap();
            model::loss(&yh, &y, &h, 1).unwrap().to_scalar::<f32>().unwrap() as f64
        };
        // Short of |T| by 1 on each taut axis: weight 1 − γ = 0.8 each.
        assert!((l([1.0, -1.0, 0.0]) - 1.6).abs() < 1e-6);
        // Beyond |T| by 1: weight γ = 0.2 each; a slack axis predicted non-zero counts as over.
        assert!((l([3.0, -3.0, 0.0]) - 0.4).abs() < 1e-6);
        assert!((l([2.0, -2.0, 1.0]) - 0.2).abs() < 1e-6);
        // L_p alone: η_n = η^(n−1)/Σ weights the later steps less: (1·1 + 0.5·1) / 1.5.
        let hp = model::Hyper { alpha: 0.0, beta: 1.0, eta: 0.5, ..h };
        let y2 = Tensor::from_vec(vec![0.0f32; 6], (1, 6), &dev).unwrap();
        let yh2 = Tensor::from_vec(vec![1.0f32, 0.0, 0.0, 1.0, 0.0, 0.0], (1, 6), &dev).unwrap();
        let lp = model::loss(&yh2, &y2, &hp, 2).unwrap().to_scalar::<f32>().unwrap() as f64;
        assert!((lp - 1.0).abs() < 1e-6, "{lp}");
        let yh3 = Tensor::from_vec(vec![0.0f32, 0.0, 0.0, 1.0, 0.0, 0.0], (1, 6), &dev).unwrap();
        let lp3 = model::loss(&yh3, &y2, &hp, 2).unwrap().to_scalar::<f32>().unwrap() as f64;
        assert!((lp3 - 1.0 / 3.0).abs() < 1e-6, "{lp3}");
    }
}
