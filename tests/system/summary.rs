//! What a launch leaves a user: a small `summary.json` (latency percentiles per link, the
//! histograms once, in the receivers' latency logs `timing/<proc>.hlog`, never in `status/`),
//! timing files in the telemetry's format, the verdict against the paper, `--json` on stdout,
//! and the end-of-run table with 4 significant digits. Short runs (`--duration`) only.
//! Run with `scripts/test` (it builds the release binaries).

use std::collections::BTreeMap;
use std::path::Path;

use cohort::OutputWithin;
use cohort::{describe_output, heavy_scratch, orchestrator_command, read_json, summary};
use serde_json::Value;

/// The bound on a short fig1 run's summary.json. What it holds scales with the processes (7
/// end reports of ≈ 1.4 kB pretty-printed: counters by reason, fault counters, received-from
/// maps), the links (24 of ≈ 120 B of percentiles) and the metrics (≈ 20 of ≈ 60 B), ≈ 15 kB in
/// all — against ≈ 4.5 MB when each process's histogram buckets were in it. 20 kB leaves room
/// for a few more counters, and fails if a histogram (hundreds of buckets per link) comes back.
const SUMMARY_MAX_BYTES: usize = 20_000;

/// Whether a table cell is a number with 4 significant digits (or a whole number, which the
/// table prints whole).
fn has_4_significant_digits(cell: &str) -> bool {
    let Ok(x) = cell.parse::<f64>() else { return false };
    if !cell.contains(['.', 'e']) {
        return x.fract() == 0.0;
    }
    let mantissa = cell.split('e').next().unwrap_or_default();
    let digits: String = mantissa.chars().filter(|c| c.is_ascii_digit()).collect();
    digits.trim_start_matches('0').len() == 4
}

/// The `per agent:` table of the end-of-run text: header cells and rows of cells.
fn agent_table(text: &str) -> (Vec<String>, Vec<Vec<String>>) {
    let mut lines = text.lines().skip_while(|l| *l != "per agent:").skip(1);
    let header: Vec<String> = lines.next().unwrap_or_default().split_whitespace().map(String::from).collect();
    let rows = lines
        .take_while(|l| l.starts_with("  ") && l.split_whitespace().next().is_some_and(|c| c.parse::<u32>().is_ok()))
        .map(|l| l.split_whitespace().map(String::from).collect())
        .collect();
    (header, rows)
}

#[test]
fn a_short_fig1_run_has_a_small_summary_its_histograms_a_verdict_and_json_on_stdout() {
    let (_g, dir) = heavy_scratch("summary-fig1");
    let run = dir.join("run");
    let o = orchestrator_command()
        .args(["launch", "topologies/fig1.toml", "--duration", "2", "--no-plots", "--json", "--out"])
        .arg(&run)
        .output_within(cohort::RUN_LIMIT, "a launch with --json");
    assert!(o.status.success(), "{}", describe_output(&o));
    // --json: stdout is the summary and nothing else.
    let printed: Value = serde_json::from_slice(&o.stdout).unwrap_or_else(|e| panic!("{e}\n{}", describe_output(&o)));
    let text = std::fs::read_to_string(run.join("summary.json")).unwrap();
    let s = summary(&run);
    assert_eq!(printed, s, "--json printed something else than summary.json");
    assert!(text.len() < SUMMARY_MAX_BYTES, "summary.json is {} bytes (bound {SUMMARY_MAX_BYTES})", text.len());
    assert!(!text.contains("latency_from_ns"), "histograms are back in summary.json");

    // Percentiles per link: the plant hears 6 agents, each agent the plant and 2 ring neighbours.
    let links = s["link_latency_ns"].as_object().expect("link_latency_ns");
    assert_eq!(links.len(), 6 + 6 * 3, "{links:?}");
    for (name, q) in links {
        for k in ["samples", "p50", "p99", "p99.9", "max"] {
            assert!(q[k].as_u64().is_some(), "{name}: no {k}: {q}");
        }
        let (p50, p99, p999, max) = (q["p50"].as_u64(), q["p99"].as_u64(), q["p99.9"].as_u64(), q["max"].as_u64());
        assert!(p50 <= p99 && p99 <= p999 && p999 <= max, "{name}: {q}");
    }
    assert_eq!(s["process_latency_ns"].as_object().map(|m| m.len()), Some(7), "{}", s["process_latency_ns"]);

    // The histograms: each process's latency log parses, one histogram per link, agreeing with
    // the percentiles (the same percentiles the histograms gave when status/ carried them).
    let hist: BTreeMap<String, Vec<(u64, u64)>> = cohort_runtime::record::read_latency_histograms(&run)
        .unwrap()
        .into_iter()
        .map(|((from, to), b)| (format!("{from} → {to}"), b.0))
        .collect();
    assert_eq!(hist.keys().collect::<Vec<_>>(), links.keys().collect::<Vec<_>>());
    for (name, b) in &hist {
        let q = &links[name];
        assert!(b.windows(2).all(|w| w[0].0 < w[1].0), "{name}: buckets not ascending");
        let total: u64 = b.iter().map(|x| x.1).sum();
        assert_eq!(Some(total), q["samples"].as_u64(), "{name}");
        assert_eq!(b.last().map(|x| x.0), q["max"].as_u64(), "{name}: the last bucket is the max");
        let p50 = q["p50"].as_u64().unwrap();
        let below: u64 = b.iter().filter(|x| x.0 <= p50).map(|x| x.1).sum();
        assert!(2 * below >= total && b.iter().any(|x| x.0 == p50), "{name}: p50 {p50} is not the median bucket");
        let h = cohort_runtime::record::LatencyHist::from_buckets(&cohort_runtime::record::LatencyBuckets(b.clone()));
        for (k, v) in [("p99", h.quantile(0.99)), ("p99.9", h.quantile(0.999)), ("max", h.max())] {
            assert_eq!(q[k].as_u64(), Some(v), "{name}: {k}");
        }
    }
    // status/ is the end report without a second copy of the histograms; the timing files are
    // Parquet (the telemetry's format), one per process, a row per step.
    status_and_timing(&run, "parquet", 200);

    // The verdict: fig1's lines, each pass, fail or n/a; a 2 s run cannot speak to a 360 s claim.
    let verdict = s["verdict"].as_array().expect("a verdict block");
    assert!(verdict.len() >= 2, "{verdict:?}");
    for l in verdict {
        assert!(["pass", "fail", "n/a"].contains(&l["verdict"].as_str().unwrap_or_default()), "{l}");
        assert!(l["paper"].as_f64().is_some() && l["source"].as_str().is_some_and(|x| !x.is_empty()), "{l}");
        assert_eq!(l["verdict"], "n/a", "{l}");
        assert!(l["note"].as_str().is_some_and(|n| n.contains("shortened")), "{l}");
    }
    assert_eq!(s["verdict_overall"], "n/a");

    // The human text went to stderr: a per-agent table with 4 significant digits, the verdict.
    let err = String::from_utf8_lossy(&o.stderr);
    let (header, rows) = agent_table(&err);
    assert_eq!(header.first().map(String::as_str), Some("agent"), "{err}");
    assert!(header.iter().any(|h| h == "u_peak_mps2"), "{header:?}");
    assert_eq!(rows.len(), 6, "{err}");
    for r in &rows {
        assert_eq!(r.len(), header.len(), "{r:?}");
        for cell in &r[1..] {
            assert!(has_4_significant_digits(cell), "{cell:?} in {r:?}");
        }
    }
    let dv = s["metrics"]["servicer_1.dv_total_mps"].as_f64().unwrap();
    let col = header.iter().position(|h| h == "dv_total_mps").unwrap();
    let shown: f64 = rows[0][col].parse().unwrap();
    assert!((shown - dv).abs() <= 5e-4 * dv.abs(), "servicer 1 Δv {dv} shown as {shown}");
    assert!(err.contains("verdict against the paper: N/A"), "{err}");
    assert!(!err.lines().any(|l| l.trim_start().starts_with("servicer_1.dv_total_mps = ")), "old output: {err}");
}

/// Every process's status has its counters but no histogram, its latency log is in `timing/`,
/// and its timing file is in `format` (and not the other), readable, `steps` rows long, with
/// units in a Parquet file's schema.
fn status_and_timing(run: &Path, format: &str, steps: usize) {
    let other = if format == "csv" { "parquet" } else { "csv" };
    let timing = run.join("timing");
    for p in ["plant", "agent-1", "agent-2", "agent-3", "agent-4", "agent-5", "agent-6"] {
        let path = run.join(format!("status/{p}.json"));
        let text = std::fs::read_to_string(&path).unwrap();
        assert!(!text.contains("latency_from_ns"), "{p}: histograms in status/");
        // ≈ 2 kB of counters; one histogram alone is hundreds of buckets.
        assert!(text.len() < 8_000, "{p}: status is {} bytes", text.len());
        let status = read_json(&path);
        assert!(status["steps_completed"].as_u64() == Some(steps as u64), "{p}: {status}");
        assert!(status["received_from"].as_object().is_some_and(|m| !m.is_empty()), "{p}: {status}");
        assert!(timing.join(format!("{p}.hlog")).is_file(), "{p}: no latency log");
        let file = timing.join(format!("{p}.{format}"));
        assert!(file.is_file() && !timing.join(format!("{p}.{other}")).exists(), "{}", file.display());
        let column = if p == "plant" { "round_ns" } else { "compute_ns" };
        let values = cohort_runtime::record::timing_column(&timing, p, column);
        assert_eq!(values.len(), steps, "{p}: {column}");
        assert!(values.iter().all(|&v| v > 0), "{p}: {column}: {values:?}");
        assert_eq!(cohort_runtime::record::timing_column(&timing, p, "k"), (0..steps as u64).collect::<Vec<_>>());
        if format == "parquet" {
            let units = cohort_runtime::parquet_out::units(&file).unwrap();
            assert!(units.iter().any(|(c, u)| c == column && u.as_deref() == Some("ns")), "{p}: {units:?}");
        }
    }
    assert!(!timing.join("latency_histograms.csv").exists(), "a second copy of the histograms");
    // The summary's wall-clock percentiles come from the timing files, whatever their format.
    let s = summary(run);
    for k in ["plant_round", "share_to_plant", "measurement_to_agent", "agent_neighbour_wait", "agent_compute"] {
        let q = &s["latency_ns"][k];
        let want = if k.starts_with("agent") || k.starts_with("measurement") { 6 * steps } else { steps };
        assert_eq!(q["samples"].as_u64(), Some(want as u64), "{k}: {q}");
    }
}

/// With `--telemetry csv` the timing files are CSV and the summary's timing percentiles read
/// them as they read Parquet.
#[test]
fn a_csv_fig1_run_writes_its_timing_as_csv_and_the_summary_reads_it() {
    let (_g, dir) = heavy_scratch("summary-fig1-csv");
    let run = dir.join("run");
    let o = orchestrator_command()
        .args(["launch", "topologies/fig1.toml", "--duration", "2", "--no-plots", "--telemetry", "csv", "--out"])
        .arg(&run)
        .output_within(cohort::RUN_LIMIT, "a launch with csv telemetry");
    assert!(o.status.success(), "{}", describe_output(&o));
    status_and_timing(&run, "csv", 200);
    let s = summary(&run);
    assert_eq!(s["link_latency_ns"].as_object().map(|m| m.len()), Some(24), "{}", s["link_latency_ns"]);
}

#[test]
fn dai_and_nr_main_scenarios_get_a_verdict_with_pass_or_fail() {
    let (_g, dir) = heavy_scratch("summary-verdict");
    // Both whole runs are short: dai 5 s of sim in-process, nr one day in 144 steps.
    for file in ["topologies/dai.toml", "topologies/nr-iso.toml"] {
        let run = dir.join(Path::new(file).file_stem().unwrap());
        let o = orchestrator_command()
            .args(["launch", file, "--no-plots", "--out"])
            .arg(&run)
            .output_within(cohort::RUN_LIMIT, "a launch of a shipped scenario");
        assert!(o.status.success(), "{file}: {}", describe_output(&o));
        let s = summary(&run);
        let verdict = s["verdict"].as_array().unwrap_or_else(|| panic!("{file}: no verdict"));
        assert!(verdict.len() >= 2, "{file}: {verdict:?}");
        for l in verdict {
            let v = l["verdict"].as_str().unwrap_or_default();
            assert!(v == "pass" || v == "fail", "{file}: a whole fault-free run is judged: {l}");
            assert!(l["ours"].as_f64().is_some(), "{file}: {l}");
        }
        let stdout = String::from_utf8_lossy(&o.stdout);
        assert!(stdout.contains("verdict against the paper: "), "{file}: {stdout}");
        let shown = stdout.lines().filter(|l| l.starts_with("  PASS") || l.starts_with("  FAIL")).count();
        assert_eq!(shown, verdict.len(), "{file}: {stdout}");
    }
}
