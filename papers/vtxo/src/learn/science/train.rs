//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! `orchestrator train vtxo-science`: the science DNN of Sec. 3.2.2 trained with candle (f32, CPU)
//! on the Pareto tables of [`crate::learn::science::data`], one network per law, written together as the
//! weights file of [`crate::learn::science::dnn`]; the report beside it (`<stem>-report.md`) gives the
//! held-out accuracy and the Table 3 analogue ([`crate::learn::science::stats`]).
//!
//! As printed: 10–5–3 sigmoid layers (then the linear output layer, see `science_dnn`), stochastic
//! gradient descent on the MSE, at most 1000 epochs.
//!
//! Choices where the print is silent: the rows are split once, seeded, into 20 % held out for the
//! report (never seen in training), and of the rest 20 % validation, on which the best epoch is
//! kept (the weights written are that epoch's, so the held-out numbers are those of the file);
//! plain SGD (no momentum), learning rate 0.3 (the best summed validation MSE of 0.03, 0.1, 0.3
//! and 1 with seed 1), batch 16, Xavier-uniform initial weights, zero
//! biases; the loss is the MSE of the standardised log-outputs (the quantity the network
//! predicts), which is also the MSE reported beside Sec. 6.1's 0.0434 (PD) and 0.0124 (SMC) — the
//! print does not say on what scale its MSE is.
//!
//! Deterministic: one seed drives the split, the initial weights and the batch order, and the
//! orchestrator runs the trainer with `RAYON_NUM_THREADS=1`; the same arguments write the same
//! bytes (the report holds no wall-clock time).

use std::path::{Path, PathBuf};

use candle_core::{Device, Tensor, Var};
use candle_nn::{Optimizer, SGD};
use rand::seq::SliceRandom;
use rand::{Rng, SeedableRng};
use rand_chacha::ChaCha8Rng;

use crate::learn::science::data::{INPUT_COLUMNS, OBJECTIVE_COLUMNS, table_path};
use crate::learn::science::dnn::{N_IN, Net, ScienceDnn, layer_shapes, n_out};
use crate::learn::science::sim::ScienceLaw;

/// Settings of one training run.
#[derive(Debug, Clone)]
pub struct Options {
    /// Directory of `science-pd.csv` and `science-smc.csv`.
    pub data_dir: PathBuf,
    pub out: PathBuf,
    pub seed: u64,
    pub epochs: usize,
    pub batch: usize,
    pub lr: f64,
}

impl Options {
    pub fn reference(data_dir: PathBuf, out: PathBuf, seed: u64) -> Self {
        Self { data_dir, out, seed, epochs: 1000, batch: 16, lr: 0.3 }
    }
}

/// One law's table: network inputs and the positive outputs (E, e, k̂).
pub struct Table {
    pub x: Vec<[f64; N_IN]>,
    pub y: Vec<Vec<f64>>,
    /// ω_f per row, rad/s.
    pub omega_end_rad_s: Vec<[f64; 3]>,
}

/// Read `law`'s table from `dir`.
pub fn read_table(dir: &Path, law: ScienceLaw) -> Result<Table, String> {
    let path = table_path(dir, law);
    let names: Vec<&str> = INPUT_COLUMNS
        .iter()
        .chain(&OBJECTIVE_COLUMNS)
        .chain(law.gain_columns())
        .chain(&crate::learn::science::data::OMEGA_END_COLUMNS)
        .copied()
        .collect();
    let cols = crate::learn::transient::stats::read_columns(&path, &names)?;
    let n = cols[0].len();
    let n_y = n_out(law);
    let mut t = Table { x: Vec::with_capacity(n), y: Vec::with_capacity(n), omega_end_rad_s: Vec::with_capacity(n) };
    for r in 0..n {
        let y: Vec<f64> = (0..n_y).map(|k| cols[N_IN + k][r]).collect();
        let positive = |v: f64| v > 0.0 && v.is_finite();
        if let Some(k) = (0..n_y).find(|&k| !(positive(y[k]) && positive(cols[7][r]))) {
            return Err(format!(
                "{}: data line {}: {} = {} and w = {}: outputs and w must be positive",
                path.display(),
                r + 1,
                names[N_IN + k],
                y[k],
                cols[7][r]
            ));
        }
        let mut x: [f64; N_IN] = std::array::from_fn(|i| cols[i][r]);
        x[7] = x[7].ln();
        t.x.push(x);
        t.y.push(y);
        t.omega_end_rad_s.push(std::array::from_fn(|i| cols[N_IN + n_y + i][r]));
    }
    Ok(t)
}

/// Mean and standard deviation (population; 1 where a column is constant) of rows `rows`.
fn moments(v: &[Vec<f64>], rows: &[usize]) -> (Vec<f64>, Vec<f64>) {
    let (n, w) = (rows.len() as f64, v[rows[0]].len());
    let mean: Vec<f64> = (0..w).map(|k| rows.iter().map(|&r| v[r][k]).sum::<f64>() / n).collect();
    let std = (0..w)
        .map(|k| {
            let s = (rows.iter().map(|&r| (v[r][k] - mean[k]).powi(2)).sum::<f64>() / n).sqrt();
            if s > 1e-12 { s } else { 1.0 }
        })
        .collect();
    (mean, std)
}

/// The network as candle variables: [w1, b1, …, w4, b4].
struct Model {
    vars: Vec<Var>,
    law: ScienceLaw,
}

impl Model {
    fn new(law: ScienceLaw, rng: &mut ChaCha8Rng, dev: &Device) -> candle_core::Result<Self> {
        let mut vars = Vec::new();
        for (i, o) in layer_shapes(law) {
            let bound = (6.0 / (i + o) as f64).sqrt();
            let w: Vec<f32> = (0..i * o).map(|_| rng.random_range(-bound..bound) as f32).collect();
            vars.push(Var::from_tensor(&Tensor::from_vec(w, (i, o), dev)?)?);
            vars.push(Var::from_tensor(&Tensor::zeros(o, candle_core::DType::F32, dev)?)?);
        }
        Ok(Self { vars, law })
    }

    /// Standardised outputs [B, n] of standardised inputs [B, 8].
    fn forward(&self, x: &Tensor) -> candle_core::Result<Tensor> {
        let mut a = x.clone();
        for l in 0..4 {
            let z = a.matmul(self.vars[2 * l].as_tensor())?.broadcast_add(self.vars[2 * l + 1].as_tensor())?;
            // σ(z) = 1/(1 + e^{−z}) from differentiable primitives.
            a = if l < 3 { (z.neg()?.exp()? + 1.0)?.recip()? } else { z };
        }
        Ok(a)
    }

    fn snapshot(&self) -> candle_core::Result<Vec<Tensor>> {
        self.vars.iter().map(|v| v.as_tensor().copy()).collect()
    }

    fn export(&self, s: &[Tensor], xn: &(Vec<f64>, Vec<f64>), yn: &(Vec<f64>, Vec<f64>)) -> candle_core::Result<Net> {
        let f = |i: usize| -> candle_core::Result<Vec<f64>> {
            Ok(s[i].flatten_all()?.to_vec1::<f32>()?.into_iter().map(f64::from).collect())
        };
        Ok(Net {
            law: self.law,
            w: [f(0)?, f(2)?, f(4)?, f(6)?],
            b: [f(1)?, f(3)?, f(5)?, f(7)?],
            input_mean: xn.0.clone(),
            input_std: xn.1.clone(),
            output_mean: yn.0.clone(),
            output_std: yn.1.clone(),
        })
    }
}

fn mse(yhat: &Tensor, y: &Tensor) -> candle_core::Result<Tensor> {
    (yhat - y)?.sqr()?.mean_all()
}

/// How one law's network was trained and what it scores on the held-out rows.
#[derive(Debug, Clone)]
pub struct LawReport {
    pub law: ScienceLaw,
    pub rows: [usize; 3],
    pub best_epoch: usize,
    pub val_mse: f64,
    /// MSE of the standardised log-outputs per output, held out.
    pub heldout_mse: Vec<f64>,
    /// MAPE (%) per output in physical units, held out.
    pub heldout_mape: Vec<f64>,
}

impl LawReport {
    pub fn mean_mse(&self) -> f64 {
        self.heldout_mse.iter().sum::<f64>() / self.heldout_mse.len() as f64
    }
}

/// Train one law's network; returns it and its report.
fn fit_law(t: &Table, law: ScienceLaw, o: &Options, rng: &mut ChaCha8Rng) -> Result<(Net, LawReport), String> {
    let n = t.x.len();
    if n < 10 {
        return Err(format!("{}: {n} rows, too few (at least 10)", table_path(&o.data_dir, law).display()));
    }
    let ce = |e: candle_core::Error| format!("training {}: {e}", law.name());
    let mut perm: Vec<usize> = (0..n).collect();
    perm.shuffle(rng);
    let n_test = (n / 5).max(1);
    let n_val = ((n - n_test) / 5).max(1);
    let (test, rest) = perm.split_at(n_test);
    let (val, train) = rest.split_at(n_val);
    let xs: Vec<Vec<f64>> = t.x.iter().map(|x| x.to_vec()).collect();
    let ys: Vec<Vec<f64>> = t.y.iter().map(|y| y.iter().map(|v| v.ln()).collect()).collect();
    let (xn, yn) = (moments(&xs, train), moments(&ys, train));
    let dev = Device::Cpu;
    let tensor = |v: &[Vec<f64>], m: &(Vec<f64>, Vec<f64>), rows: &[usize]| -> candle_core::Result<Tensor> {
        let w = m.0.len();
        let data: Vec<f32> =
            rows.iter().flat_map(|&r| (0..w).map(move |k| ((v[r][k] - m.0[k]) / m.1[k]) as f32)).collect();
        Tensor::from_vec(data, (rows.len(), w), &dev)
    };
    let (xt, yt) = (tensor(&xs, &xn, train).map_err(ce)?, tensor(&ys, &yn, train).map_err(ce)?);
    let (xv, yv) = (tensor(&xs, &xn, val).map_err(ce)?, tensor(&ys, &yn, val).map_err(ce)?);
    let model = Model::new(law, rng, &dev).map_err(ce)?;
    let mut opt = SGD::new(model.vars.clone(), o.lr).map_err(ce)?;
    let mut order: Vec<u32> = (0..train.len() as u32).collect();
    let (mut best, mut best_epoch, mut snap) = (f64::INFINITY, 0, model.snapshot().map_err(ce)?);
    for epoch in 0..o.epochs {
        order.shuffle(rng);
        for chunk in order.chunks(o.batch) {
            let idx = Tensor::from_slice(chunk, chunk.len(), &dev).map_err(ce)?;
            let xb = xt.index_select(&idx, 0).map_err(ce)?;
            let yb = yt.index_select(&idx, 0).map_err(ce)?;
            let l = mse(&model.forward(&xb).map_err(ce)?, &yb).map_err(ce)?;
            opt.backward_step(&l).map_err(ce)?;
        }
        let v =
            mse(&model.forward(&xv).map_err(ce)?, &yv).and_then(|l| l.to_scalar::<f32>()).map(f64::from).map_err(ce)?;
        if v < best {
            (best, best_epoch, snap) = (v, epoch + 1, model.snapshot().map_err(ce)?);
        }
    }
    let net = model.export(&snap, &xn, &yn).map_err(ce)?;
    let k = n_out(law);
    let (mut m2, mut mape) = (vec![0.0; k], vec![0.0; k]);
    for &r in test {
        let z = net.forward_standardised(&t.x[r]);
        let p = net.forward(&t.x[r]);
        for j in 0..k {
            m2[j] += (z[j] - (ys[r][j] - yn.0[j]) / yn.1[j]).powi(2) / test.len() as f64;
            mape[j] += 100.0 * (p[j] - t.y[r][j]).abs() / t.y[r][j] / test.len() as f64;
        }
    }
    tracing::info!("vtxo-science: {} best epoch {best_epoch}, validation MSE {best:.4}", law.name());
    let report = LawReport {
        law,
        rows: [train.len(), val.len(), test.len()],
        best_epoch,
        val_mse: best,
        heldout_mse: m2,
        heldout_mape: mape,
    };
    Ok((net, report))
}

/// Train both laws' networks and write the weights file; returns the reports (PD, SMC).
pub fn train(o: &Options) -> Result<Vec<LawReport>, String> {
    let mut rng = ChaCha8Rng::seed_from_u64(o.seed);
    let pd_t = read_table(&o.data_dir, ScienceLaw::Pd)?;
    let smc_t = read_table(&o.data_dir, ScienceLaw::Smc)?;
    let (pd, rp) = fit_law(&pd_t, ScienceLaw::Pd, o, &mut rng)?;
    let (smc, rs) = fit_law(&smc_t, ScienceLaw::Smc, o, &mut rng)?;
    if let Some(d) = o.out.parent().filter(|d| !d.as_os_str().is_empty()) {
        std::fs::create_dir_all(d).map_err(|e| format!("{}: {e}", d.display()))?;
    }
    let dnn = ScienceDnn { pd, smc };
    std::fs::write(&o.out, dnn.to_bytes()).map_err(|e| format!("{}: {e}", o.out.display()))?;
    Ok(vec![rp, rs])
}

/// The report's accuracy section.
pub fn accuracy_markdown(reports: &[LawReport], o: &Options) -> String {
    let mut md = format!(
        "## Accuracy (held out)\n\nNetworks 8-10-5-3-n, sigmoid hidden layers, linear output layer, SGD lr {}, batch {}, \
         ≤ {} epochs (best validation epoch kept), MSE on standardised ln-outputs.\n\n\
         | law | rows train / val / held out | best epoch | held-out MSE per output (standardised ln) | mean | \
         held-out MAPE % per output | paper MSE (Sec. 6.1) |\n|---|---|---|---|---|---|---|\n",
        o.lr, o.batch, o.epochs
    );
    for r in reports {
        let names: Vec<&str> = OBJECTIVE_COLUMNS.iter().chain(r.law.gain_columns()).copied().collect();
        let m: Vec<String> = names.iter().zip(&r.heldout_mse).map(|(n, v)| format!("{n} {v:.3}")).collect();
        let p: Vec<String> = names.iter().zip(&r.heldout_mape).map(|(n, v)| format!("{n} {v:.1}")).collect();
        let paper = if r.law == ScienceLaw::Pd { "0.0434" } else { "0.0124" };
        md += &format!(
            "| {} | {} / {} / {} | {} | {} | {:.3} | {} | {paper} |\n",
            r.law.name(),
            r.rows[0],
            r.rows[1],
            r.rows[2],
            r.best_epoch,
            m.join(", "),
            r.mean_mse(),
            p.join(", ")
        );
    }
    md
}

/// `<stem>-report.md` beside the weights file.
pub fn report_path(weights: &Path) -> PathBuf {
    let stem = weights.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_else(|| "science".into());
    weights.with_file_name(format!("{stem}-report.md"))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_plain_forward_pass_matches_candle() {
        let dev = Device::Cpu;
        for law in ScienceLaw::ALL {
            let m = Model::new(law, &mut ChaCha8Rng::seed_from_u64(5), &dev).expect("model");
            // Non-zero biases so the check sees them.
            for l in 0..4 {
                let b = m.vars[2 * l + 1].as_tensor();
                let v: Vec<f32> = (0..b.dims1().unwrap()).map(|i| 0.1 * (i as f32 + 1.0) - 0.2).collect();
                m.vars[2 * l + 1].set(&Tensor::from_vec(v, b.dims1().unwrap(), &dev).unwrap()).unwrap();
            }
            let xn =
                (vec![0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 5.0], vec![3e-4, 3e-4, 3e-4, 1e-7, 9e-4, 8e-4, 1e-3, 2.0]);
            let k = n_out(law);
            let yn = ((0..k).map(|i| -3.0 + i as f64).collect(), vec![0.7; k]);
            let net = m.export(&m.snapshot().unwrap(), &xn, &yn).expect("export");
            let mut rng = ChaCha8Rng::seed_from_u64(6);
            let xs: Vec<[f64; N_IN]> =
                (0..40).map(|_| std::array::from_fn(|i| xn.0[i] + xn.1[i] * rng.random_range(-2.0..2.0))).collect();
            let z: Vec<f32> = xs.iter().flat_map(|x| (0..N_IN).map(|i| ((x[i] - xn.0[i]) / xn.1[i]) as f32)).collect();
            let out: Vec<Vec<f32>> =
                m.forward(&Tensor::from_vec(z, (xs.len(), N_IN), &dev).unwrap()).unwrap().to_vec2().unwrap();
            let spread =
                out.iter().map(|r| r[0]).fold(f32::MIN, f32::max) - out.iter().map(|r| r[0]).fold(f32::MAX, f32::min);
            assert!(spread > 1e-3, "the check must see the inputs move the output ({spread})");
            for (x, c) in xs.iter().zip(&out) {
                let p = net.forward_standardised(x);
                for j in 0..k {
                    assert!((p[j] - f64::from(c[j])).abs() <= 1e-5, "{law:?} output {j}: {} vs candle {}", p[j], c[j]);
                }
            }
        }
    }

    #[test]
    fn training_is_byte_identical_and_the_file_loads() {
        let dir = std::env::temp_dir().join(format!("vtxo-science-train-{}", std::process::id()));
        let data = crate::learn::science::data::Options {
            draws: 8,
            seed: 2,
            population: 6,
            generations: 1,
            phase_s: 10.0,
            dt_s: 0.01,
            threads: 2,
            out_dir: dir.clone(),
        };
        crate::learn::science::data::run(&data).expect("tiny tables");
        let mut o = Options::reference(dir.clone(), dir.join("w.safetensors"), 3);
        o.epochs = 5;
        let r = train(&o).expect("train");
        assert_eq!(r.len(), 2);
        assert!(r.iter().all(|l| l.best_epoch >= 1 && l.heldout_mse.iter().all(|m| m.is_finite())), "{r:?}");
        let first = std::fs::read(&o.out).expect("weights");
        train(&o).expect("train again");
        assert_eq!(first, std::fs::read(&o.out).expect("weights again"), "training is not byte-identical");
        let d = ScienceDnn::load(&o.out).expect("the written weights load");
        assert_eq!(d.smc.output_mean.len(), 5);
        // Another seed: other weights.
        o.seed = 4;
        train(&o).expect("train, seed 4");
        assert_ne!(first, std::fs::read(&o.out).expect("weights seed 4"));
        // A table with a non-positive output is refused naming file, line and column.
        let pd = table_path(&dir, ScienceLaw::Pd);
        let text = std::fs::read_to_string(&pd).unwrap();
        let mut lines: Vec<String> = text.lines().map(String::from).collect();
        let mut f: Vec<String> = lines[2].split(',').map(String::from).collect();
        f[9] = "0".into();
        lines[2] = f.join(",");
        std::fs::write(&pd, lines.join("\n") + "\n").unwrap();
        let e = train(&o).expect_err("E = 0");
        assert!(e.contains("science-pd.csv") && e.contains("line 1") && e.contains("E_J"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
