//! `cargo run --release -p cohort-paper-nr --example nr_campaign -- [--methods a,b] [--isos 200..300]
//! [--weights FILE] [--nav-scale X] [--dt S] [--threads N] [--repeats R] [--seed-base B]
//! [--rebuild-every S] [--backward replay|policy] [--t-s-fraction F] [--json FILE]`: the in-process
//! evaluation of `campaign`, printed as Markdown.

use std::sync::Arc;

use cohort_paper_nr::campaign::{CampaignOptions, comparisons, markdown, run_all, summarise};
use cohort_paper_nr::config::Method;
use cohort_paper_nr::sn_dnn::SnDnn;

fn method(name: &str) -> Result<Method, String> {
    Method::ALL.into_iter().find(|m| m.name() == name).ok_or(format!("unknown method {name:?}"))
}

fn main() -> Result<(), String> {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let get = |flag: &str| args.iter().position(|a| a == flag).and_then(|i| args.get(i + 1)).cloned();
    let weights = get("--weights").unwrap_or("papers/nr/weights/sn-dnn.safetensors".into());
    let methods: Vec<Method> = match get("--methods") {
        Some(m) => m.split(',').map(method).collect::<Result<_, _>>()?,
        None => Method::ALL.to_vec(),
    };
    let net = if methods.iter().any(|m| m.needs_weights()) {
        Some(Arc::new(SnDnn::load(std::path::Path::new(&weights)).map_err(|e| e.to_string())?))
    } else {
        None
    };
    let mut o = CampaignOptions::new(methods, net);
    o.algorithm.weights = Some(weights.into());
    if let Some(r) = get("--isos") {
        let (a, b) = r.split_once("..").ok_or("--isos A..B")?;
        o.isos = a.parse().map_err(|_| "--isos")?..b.parse().map_err(|_| "--isos")?;
    }
    if let Some(x) = get("--nav-scale") {
        o.plant.nav_scale = x.parse().map_err(|_| "--nav-scale")?;
    }
    if let Some(x) = get("--dt") {
        o.dt_s = x.parse().map_err(|_| "--dt")?;
    }
    if let Some(x) = get("--threads") {
        o.threads = x.parse().map_err(|_| "--threads")?;
    }
    if let Some(x) = get("--repeats") {
        o.timing_repeats = x.parse().map_err(|_| "--repeats")?;
    }
    if let Some(x) = get("--seed-base") {
        o.seed_base = x.parse().map_err(|_| "--seed-base")?;
    }
    if let Some(x) = get("--rebuild-every") {
        o.algorithm.rebuild_every_s = x.parse().map_err(|_| "--rebuild-every")?;
    }
    if let Some(x) = get("--backward") {
        o.algorithm.backward = serde_json::from_value(serde_json::Value::String(x)).map_err(|e| e.to_string())?;
    }
    if let Some(x) = get("--t-s-fraction") {
        o.algorithm.t_s_fraction = x.parse().map_err(|_| "--t-s-fraction")?;
    }
    let started = std::time::Instant::now();
    let runs = run_all(&o)?;
    let s = summarise(&o, &runs);
    println!("{}", markdown(&s));
    println!("{}", comparisons(&runs));
    println!(
        "wall {:.1} s, ISOs {:?}, nav_scale {}, dt {} s",
        started.elapsed().as_secs_f64(),
        o.isos,
        o.plant.nav_scale,
        o.dt_s
    );
    if let Some(path) = get("--json") {
        let text = serde_json::to_string_pretty(&serde_json::json!({"summaries": s, "runs": runs}))
            .map_err(|e| e.to_string())?;
        std::fs::write(&path, text).map_err(|e| format!("{path}: {e}"))?;
    }
    Ok(())
}
