//! `cargo run --release -p cohort-paper-nr --example nr_train -- [--seed N] [--out FILE]
//! [--gamma G] [--epochs E] [--isos A..B] [--samples S] [--cache DIR] [--report FILE]`: the
//! library's `train::train` with the reference options (what `orchestrator train nr-iso` runs).

use std::path::PathBuf;

use cohort_paper_nr::train::{TrainOptions, train};

fn main() -> Result<(), String> {
    // candle's CPU matmuls thread by RAYON_NUM_THREADS; on these tiny matrices one thread is
    // faster and gives the same bytes. Set before any thread exists.
    if std::env::var_os("RAYON_NUM_THREADS").is_none() {
        // SAFETY: single-threaded here, at the very start of main.
        unsafe { std::env::set_var("RAYON_NUM_THREADS", "1") };
    }
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).cloned();
    let seed: u64 = get("--seed").map_or(Ok(1), |s| s.parse()).map_err(|_| "--seed")?;
    let out = PathBuf::from(get("--out").unwrap_or("papers/nr/weights/sn-dnn.safetensors".into()));
    let mut o = TrainOptions::reference(out, seed);
    o.cache_dir = Some(PathBuf::from(get("--cache").unwrap_or("target/nr-cache".into())));
    if let Some(g) = get("--gamma") {
        o.gamma = g.parse().map_err(|_| "--gamma")?;
    }
    if let Some(e) = get("--epochs") {
        o.epochs = e.parse().map_err(|_| "--epochs")?;
    }
    if let Some(s) = get("--samples") {
        o.data.samples_per_iso = s.parse().map_err(|_| "--samples")?;
    }
    if let Some(n) = get("--inputs") {
        o.inputs = n.parse().map_err(|_| "--inputs")?;
    }
    if let Some(c) = get("--c-sn") {
        o.c_sn = c.parse().map_err(|_| "--c-sn")?;
    }
    if let Some(r) = get("--isos") {
        let (a, b) = r.split_once("..").ok_or("--isos A..B")?;
        o.data.isos = a.parse().map_err(|_| "--isos")?..b.parse().map_err(|_| "--isos")?;
    }
    let report = train(&o).map_err(|e| e.to_string())?;
    let md = report.markdown();
    println!("{md}");
    if let Some(path) = get("--report") {
        std::fs::write(&path, md).map_err(|e| format!("{path}: {e}"))?;
    }
    Ok(())
}
