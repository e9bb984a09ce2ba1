//! Seed 002's hand-off scenario (`topologies/vtxo-handoff.toml`: s1 stabilisation → s2 transient →
//! s3 science with the full dynamics) through the orchestrator (build the binaries first:
//! `scripts/test` does): the plant and both agents as three processes, bit-identical to the
//! in-process reference; the attitude law switching exactly at the supervisor's transitions (every
//! step of both agents: one law, the one the location prescribes, and the torque that law gives on
//! the logged estimate); the transitions at the steps the automaton gives with u2 = max(T̂_L, T̂_F)
//! from the transient DNN at each spacecraft's estimate; the science gains from the science DNN at
//! each spacecraft's estimate at its entry to s3; the summary; and bad weights files.

use std::path::Path;
use std::process::Output;

use cohort::{describe_output, heavy, orchestrator_command, scratch_dir, summary, telemetry_bits, telemetry_table};
use cohort_paper_vtxo::automaton::table::{S1, S2, S3};
use cohort_paper_vtxo::flight::attitude_control::{AttitudeLaw, torque};
use cohort_paper_vtxo::learn::science::dnn::ScienceDnn;
use cohort_paper_vtxo::learn::science::sim::ScienceLaw;
use cohort_paper_vtxo::learn::transient::dnn::TransientDnn;
use cohort_paper_vtxo::learn::transient::gains::u2_ticks;
use cohort_paper_vtxo::model::quaternion::{Quat, V3};
use cohort_report::Table;
use nalgebra::Matrix3;

const FILE: &str = "topologies/vtxo-handoff.toml";
/// The scenario's u1 = 30 s at dt = 10 ms, the transient's w, the u2 clamp and the science DNN's w.
const U1_TICKS: usize = 3000;
const DT_S: f64 = 0.01;
const W: f64 = 5.0;
const SCIENCE_W_DEG_PER_J: f64 = 100.0;
/// The SMC gain columns (z, k_SMC, ε) of the agents' telemetry.
const SMC_COLUMNS: [&str; 3] = ["science_z_1_s2", "science_k_smc_1_s", "science_eps_rad_s"];
/// J̄ (Table E.1), the agents' nominal inertia.
const J_BAR: [f64; 3] = [0.1383, 0.1577, 0.1039];

fn orchestrator(args: &[&str], out: &Path) -> Output {
    orchestrator_command().args(args).arg("--out").arg(out).output().expect("running the orchestrator")
}

fn metric(s: &serde_json::Value, key: &str) -> f64 {
    s["metrics"][key].as_f64().unwrap_or_else(|| panic!("summary.json has no metric {key}: {}", s["metrics"]))
}

fn v3(t: &Table, prefix: &str, unit: &str, r: usize) -> V3 {
    let c = |ax: &str| t.col(&format!("{prefix}_{ax}_{unit}"))[r];
    V3::new(c("x"), c("y"), c("z"))
}

fn q_hat(t: &Table, r: usize) -> Quat {
    let c = |n: &str| t.col(&format!("q_hat_{n}"))[r];
    Quat::new(c("q1"), c("q2"), c("q3"), c("q4"))
}

/// The SMC of a row's logged science gains.
fn smc(a: &Table, r: usize) -> AttitudeLaw {
    let [z, k, epsilon] = SMC_COLUMNS.map(|c| a.col(c)[r]);
    AttitudeLaw::Smc { z, k, epsilon }
}

/// Every step of one agent: exactly one law flag is on, the one the location prescribes, and the
/// commanded torque is that law's on the row's estimate (s1: the gravity-gradient feed-forward,
/// which at apogee is below 1e-8 N·m; s2: (57) with the row's k1, k2; s3: the SMC with the row's
/// science gains, the same at every row of s3).
fn check_laws(a: &Table, who: &str) {
    let j = Matrix3::from_diagonal(&V3::from(J_BAR));
    let qf = Quat::new(0.0, 0.0, 0.0, 1.0);
    let state = a.col("sup_state");
    let s3 = state.iter().position(|x| *x as usize == S3);
    for (r, st) in state.iter().enumerate() {
        let s = *st as usize;
        let flags = ["law_stabilisation_on", "law_transient_on", "law_science_on"].map(|n| a.col(n)[r]);
        let want = match s {
            S2 => [0.0, 1.0, 0.0],
            S3 => [0.0, 0.0, 1.0],
            _ => [1.0, 0.0, 0.0],
        };
        assert_eq!(flags, want, "{who} step {}: state s{s}, flags {flags:?}", a.steps()[r]);
        let tau = v3(a, "tau_cmd", "n_m", r);
        let (q, w) = (q_hat(a, r), v3(a, "omega_hat", "rad_s", r));
        let lyap = AttitudeLaw::Lyapunov { k1: a.col("transient_k1_n_m")[r], k2: a.col("transient_k2_n_m_s")[r] };
        match s {
            S2 => assert_eq!(tau, torque(&lyap, &q, &w, &qf, &j), "{who} step {}", a.steps()[r]),
            S3 => {
                let r3 = s3.expect("in s3");
                assert_eq!(smc(a, r), smc(a, r3), "{who} step {}: gains changed in s3", a.steps()[r]);
                assert_eq!(tau, torque(&smc(a, r), &q, &w, &qf, &j), "{who} step {}", a.steps()[r]);
            }
            _ => assert!(tau.norm() < 1e-8, "{who} step {}: τ = {tau}", a.steps()[r]),
        }
    }
}

/// The first row index in location `s`.
fn entry(a: &Table, s: usize) -> usize {
    a.col("sup_state").iter().position(|x| *x as usize == s).unwrap_or_else(|| panic!("never in s{s}"))
}

#[test]
fn handoff_multi_process_is_bit_identical_to_the_reference_and_switches_laws_at_the_transitions() {
    let _g = heavy();
    let dir = scratch_dir("vtxo-handoff");
    let (mp, rf) = (dir.join("mp"), dir.join("ref"));
    let o = orchestrator(&["launch", FILE, "--no-plots"], &mp);
    assert!(o.status.success(), "{}", describe_output(&o));
    let o = orchestrator(&["launch", FILE, "--no-plots", "--reference"], &rf);
    assert!(o.status.success(), "--reference: {}", describe_output(&o));
    let (a, b) = (summary(&mp), summary(&rf));
    assert_eq!((a["mode"].as_str(), b["mode"].as_str()), (Some("multi-process"), Some("reference")));
    let (x, y) = (telemetry_bits(&mp), telemetry_bits(&rf));
    assert_eq!(x.len(), y.len());
    if let Some((p, q)) = x.iter().zip(&y).find(|(p, q)| p != q) {
        panic!("telemetry differs (file, row, column, bits): multi-process {p:?}, reference {q:?}");
    }
    assert_eq!(a["metrics"], b["metrics"]);
    assert_eq!(a["labels"]["transient_predictor"], "dnn");
    assert_eq!(a["labels"]["science_gains"], "dnn");

    let (lead, fol) = (telemetry_table(&mp, "agent-1"), telemetry_table(&mp, "agent-2"));
    assert_eq!(lead.rows(), 13_200, "every step written");
    check_laws(&lead, "leader");
    check_laws(&fol, "follower");

    // The master: s1 until t1 = u1, then s2 for u2 = max(T̂_L, T̂_F) rounded up to a tick, then s3
    // to the end of the run.
    let f2 = entry(&fol, S2);
    assert_eq!(fol.steps()[f2], U1_TICKS as u64);
    assert!(fol.col("sup_state")[..f2].iter().all(|s| *s as usize == S1));
    let l2 = entry(&lead, S2);
    // Each spacecraft's (k1, k2, T) is the DNN's at its own estimate at its entry (q_f = identity).
    let dnn = TransientDnn::load(&cohort::repo_root().join("papers/vtxo/weights/transient.safetensors")).unwrap();
    let mut t_hat = [0.0; 2];
    for (i, (t, r)) in [(&lead, l2), (&fol, f2)].into_iter().enumerate() {
        let p = dnn.predict(&q_hat(t, r), &v3(t, "omega_hat", "rad_s", r), W);
        let got = ["transient_k1_n_m", "transient_k2_n_m_s", "transient_t_hat_entry_s"].map(|c| t.col(c)[r]);
        assert_eq!(got.map(f64::to_bits), [p.k1, p.k2, p.duration_s].map(f64::to_bits), "agent {}", i + 1);
        t_hat[i] = p.duration_s;
    }
    let u2 = u2_ticks(t_hat[0], t_hat[1], 7.2, 72.0, DT_S) as usize;
    let f3 = entry(&fol, S3);
    assert_eq!(fol.steps()[f3], (U1_TICKS + u2) as u64, "s3 at u1 + u2 = {U1_TICKS} + {u2} ticks");
    assert!(fol.col("sup_state")[f2..f3].iter().all(|s| *s as usize == S2));
    assert!(fol.col("sup_state")[f3..].iter().all(|s| *s as usize == S3), "the run ends in s3");
    assert_eq!(fol.col("sup_u2_s")[f3], u2 as f64 * DT_S);
    // Each spacecraft's science gains are the science DNN's (SMC, w = 100 deg/J) at its own
    // estimate at its entry to s3, bit for bit, with its predicted Ê and ê; none before s3.
    let sci = ScienceDnn::load(&cohort::repo_root().join("papers/vtxo/weights/science.safetensors")).unwrap();
    let l3 = entry(&lead, S3);
    let pe = telemetry_table(&mp, "plant");
    for (i, (t, r)) in [(&lead, l3), (&fol, f3)].into_iter().enumerate() {
        let p = sci.predict(ScienceLaw::Smc, &q_hat(t, r), &v3(t, "omega_hat", "rad_s", r), SCIENCE_W_DEG_PER_J);
        assert_eq!(smc(t, r), p.law, "agent {}", i + 1);
        let AttitudeLaw::Smc { z, k, epsilon } = p.law else { panic!("{p:?}") };
        let got = SMC_COLUMNS.map(|c| t.col(c)[r]);
        assert_eq!(got.map(f64::to_bits), [z, k, epsilon].map(f64::to_bits), "agent {}", i + 1);
        let hat = ["science_energy_hat_j", "science_error_hat_deg"].map(|c| t.col(c)[r]);
        assert_eq!(hat.map(f64::to_bits), [p.energy_j, p.error_deg].map(f64::to_bits), "agent {}", i + 1);
        assert!(t.col(SMC_COLUMNS[0])[..r].iter().all(|x| x.is_nan()), "agent {}: gains before s3", i + 1);
        let role = ["leader", "follower"][i];
        assert_eq!(metric(&a, &format!("{role}_handoff_science_z_1_s2")), z);
        assert_eq!(metric(&a, &format!("{role}_handoff_science_error_hat_deg")), p.error_deg);
        // e of (72) over the flown s3: the plant's error rows of the same steps.
        let err = pe.col(&format!("{role}_attitude_error_deg"));
        let p3 = pe.steps().iter().position(|k| *k == t.steps()[r]).unwrap();
        let mean = err[p3..].iter().sum::<f64>() / (err.len() - p3) as f64;
        assert_eq!(metric(&a, &format!("{role}_handoff_science_error_mean_deg")), mean, "{role}");
        let span = metric(&a, &format!("{role}_handoff_science_s"));
        assert!((span - (err.len() - p3) as f64 * DT_S).abs() < 1e-9, "{role}: {span}");
        assert!(metric(&a, &format!("{role}_handoff_science_energy_j")) > 0.0, "{role}");
        assert!(metric(&a, &format!("{role}_handoff_science_rate_rms_deg_s")) > 0.0, "{role}");
    }
    assert_ne!(smc(&lead, l3), smc(&fol, f3), "each spacecraft asks at its own estimate");

    // The leader adopts the master's location one step later, at every step.
    let (ls, fs) = (lead.col("sup_state"), fol.col("sup_state"));
    assert_eq!(ls[0] as usize, S1);
    for k in 1..ls.len() {
        assert_eq!(ls[k], fs[k - 1], "leader at step {k}");
    }

    // The summary: entry times, gains, the error at the end of the transient against 0.2°.
    assert_eq!(metric(&a, "follower_handoff_s2_entry_s"), 30.0);
    assert_eq!(metric(&a, "leader_handoff_s2_entry_s"), lead.t[l2]);
    assert_eq!(lead.steps()[l2], U1_TICKS as u64 + 1);
    assert_eq!(metric(&a, "follower_handoff_s3_entry_s"), fol.t[f3]);
    assert_eq!(metric(&a, "follower_handoff_u2_s"), u2 as f64 * DT_S);
    for role in ["leader", "follower"] {
        assert_eq!(metric(&a, &format!("{role}_handoff_law_mismatch_rows")), 0.0);
        assert_eq!(metric(&a, &format!("{role}_handoff_final_state")), S3 as f64);
        let e = metric(&a, &format!("{role}_handoff_error_window_transient_deg"));
        assert!(e.is_finite() && e >= 0.0, "{role}: {e}");
        assert!(metric(&a, &format!("{role}_handoff_error_end_transient_deg")) >= 0.0);
        assert_eq!(metric(&a, &format!("{role}_handoff_transient_within_bound")), f64::from(u8::from(e < 0.2)));
        for k in ["k1_n_m", "k2_n_m_s"] {
            let g = metric(&a, &format!("{role}_handoff_transient_{k}"));
            assert!((0.01..=0.5).contains(&g), "{role} {k} = {g}");
        }
    }
}

/// A missing and a malformed transient weights file, and a missing, a malformed and another
/// model's science weights file, are refused by validation (exit 2), naming the key path and the
/// file.
#[test]
fn bad_weights_are_refused_naming_the_key_and_the_file() {
    let (t, s) = ("algorithm.handoff.transient_weights", "algorithm.handoff.science_weights");
    for (file, key, weights, why) in [
        ("invalid-vtxo-handoff-weights-missing.toml", t, "no-such-transient.safetensors", "cannot read"),
        ("invalid-vtxo-handoff-weights-malformed.toml", t, "transient-sa.csv", "not a safetensors file"),
        ("invalid-vtxo-handoff-science-weights-missing.toml", s, "no-such-science.safetensors", "cannot read"),
        ("invalid-vtxo-handoff-science-weights-malformed.toml", s, "science-smc.csv", "not a safetensors file"),
        ("invalid-vtxo-handoff-science-weights-kind.toml", s, "transient.safetensors", "holds no science DNN"),
    ] {
        let o = orchestrator_command().args(["check", &format!("papers/vtxo/tests/invalid/{file}")]).output().unwrap();
        assert_eq!(o.status.code(), Some(2), "{file}: {}", describe_output(&o));
        let err = String::from_utf8_lossy(&o.stderr);
        assert!(
            err.lines().any(|l| l.contains(file) && l.contains(key) && l.contains(weights) && l.contains(why)),
            "{file}: {err}"
        );
    }
}

/// The four trainers behind the hand-off's two networks (Secs. 3.2.1 and 3.2.2) through
/// `orchestrator train` on a tiny case (seconds; the committed weights come from the same commands
/// at full size, see the README): the transient table, the transient DNN on it, the science
/// tables, the science DNN on them — run twice into two directories, every table and weights file
/// byte-identical, and the weights load as their model.
#[test]
fn the_trainers_run_a_tiny_case_through_the_orchestrator_byte_identically() {
    let dir = scratch_dir("vtxo-train-smoke");
    let files = ["transient.csv", "transient.safetensors", "science-pd.csv", "science-smc.csv", "science.safetensors"];
    let mut bytes = Vec::new();
    for run in ["a", "b"] {
        let d = dir.join(run);
        std::fs::create_dir_all(&d).unwrap();
        let p = |f: &str| d.join(f).to_string_lossy().into_owned();
        let (t_csv, t_w, s_w, d_s) = (p("transient.csv"), p("transient.safetensors"), p("science.safetensors"), p(""));
        for args in [
            vec![
                "vtxo-transient-data",
                "--points",
                "40",
                "--seed",
                "3",
                "--iterations",
                "4",
                "--dt",
                "0.1",
                "--out",
                &t_csv,
            ],
            vec!["vtxo-transient", "--data", &t_csv, "--out", &t_w, "--epochs", "3", "--hidden", "4"],
            vec!["vtxo-science-data", "--draws", "8", "--seed", "2", "--population", "6", "--generations", "1"]
                .into_iter()
                .chain(["--phase", "10", "--out", &d_s])
                .collect(),
            vec![
                "vtxo-science",
                "--data",
                &d_s,
                "--transient-data",
                &t_csv,
                "--out",
                &s_w,
                "--seed",
                "3",
                "--epochs",
                "5",
            ],
        ] {
            let o = orchestrator_command().arg("train").args(&args).output().expect("running the orchestrator");
            assert!(o.status.success(), "train {args:?}: {}", describe_output(&o));
        }
        bytes.push(files.map(|f| std::fs::read(d.join(f)).unwrap_or_else(|e| panic!("{run}/{f}: {e}"))));
        TransientDnn::load(&d.join("transient.safetensors")).expect("transient weights load");
        ScienceDnn::load(&d.join("science.safetensors")).expect("science weights load");
    }
    for (i, f) in files.iter().enumerate() {
        assert!(bytes[0][i] == bytes[1][i], "{f} differs between two runs of the same command");
    }
}
