//! Seed 004: how much the published Table 4 depends on how the paper's set-up is read. The
//! appendix code and the printed text disagree on the initial rates (the code's z0 has 15 entries
//! for 16 states, Table 3 prints ω(0) = [.02, .03, .01]), on the original law's gain (1 in (3),
//! 1.5 in the code) and on the specific law's torque (the modified (8) its proof needs, or the
//! code's feedforward (2)). `dai tables` runs Table 4 (original law, specific law at r = 0.5, 1,
//! 2, 4; continuous-time) under each reading, changing one thing from `topologies/dai.toml` at a
//! time, so the note can say whether any reading brings the published deviations within reach —
//! none is chosen by this table; `dai.toml` states the reading the project uses and why.

use std::fmt::Write as _;
use std::path::Path;

use cohort_host::Launcher;
use cohort_report::markdown::MdTable;
use cohort_runtime::paper::{Setup, table_of};

use crate::config::{DaiAttitude, Law, RigidBodyPlant, SpecificTorque};
use crate::host::campaign::{Run, T4_TRACK_DEV, T4_TRACK_MEAN, g, rel, run, variant};

/// Which of the Table 4 cases a reading changes (the others keep the project's runs).
#[derive(Clone, Copy, PartialEq)]
enum Changes {
    Original,
    Specific,
    Both,
}

/// One reading: a name, what it changes, and the change.
struct Reading {
    name: &'static str,
    what: &'static str,
    changes: Changes,
    apply: fn(&mut RigidBodyPlant, &mut DaiAttitude),
}

fn set_rates(p: &mut RigidBodyPlant, a: &mut DaiAttitude, w0: [f64; 3], wd0: [f64; 3]) {
    p.omega0_body_rad_s = w0;
    a.reference.omega_d0_rad_s = wd0;
}

const TABLE3_W0: [f64; 3] = [0.02, 0.03, 0.01];
const CODE_Z0_RATES: [f64; 3] = [0.08, 0.08, 0.04];

/// Each reading is one change from `dai.toml` (the project's reading: ω(0) from Table 3, ω_d(0)
/// from z0, original gain 1, torque (8)).
const READINGS: [Reading; 5] = [
    Reading {
        name: "original gain 1.5",
        what: "the code's `dth = 1.5*pinv(P)*(tau-P*th)`",
        changes: Changes::Original,
        apply: |_, a| a.original_gain = 1.5,
    },
    Reading {
        name: "ω(0) = 0",
        what: "z0 read as q, ω = 0 (one zero lost), ω_d(0) = [.08, .08, .04]",
        changes: Changes::Both,
        apply: |p, a| set_rates(p, a, [0.0; 3], CODE_Z0_RATES),
    },
    Reading {
        name: "ω(0) = ω_d(0) = z0",
        what: "both rates [.08, .08, .04]: no initial error",
        changes: Changes::Both,
        apply: |p, a| set_rates(p, a, CODE_Z0_RATES, CODE_Z0_RATES),
    },
    Reading {
        name: "rates swapped",
        what: "ω(0) = [.08, .08, .04] (the \"initial ω in the code\"), ω_d(0) from Table 3",
        changes: Changes::Both,
        apply: |p, a| set_rates(p, a, CODE_Z0_RATES, TABLE3_W0),
    },
    Reading {
        name: "specific torque (2)",
        what: "specific law with the code's feedforward torque Îω̇_d + ω_d × Îω_d",
        changes: Changes::Specific,
        apply: |_, a| a.specific_torque = Some(SpecificTorque::Feedforward),
    },
];

/// Run every reading; `project` holds the project's Table 4 runs (original, then the specific
/// law at each r of `T4_R`), already measured. Returns the Markdown section and the CSV.
pub(crate) fn study(
    launcher: &dyn Launcher,
    cont: &Setup,
    project: &[Run],
    out: &Path,
) -> Result<(String, String), String> {
    tracing::info!("readings of the set-up (continuous-time, Table 4 cases):");
    let mut md = String::new();
    let mut csv = String::from("reading,case,tracking_error_mean,tracking_error_dev,published_dev,difference_pct\n");
    let _ = writeln!(md, "## Readings of the set-up — Table 4 under each, continuous-time\n");
    let _ = writeln!(
        md,
        "Tracking-error deviation (rad/s) with its difference to the published value; one change \
         from `dai.toml` per row (cases a reading does not change repeat the project's runs). The \
         last column counts the five cases within 30 %.\n"
    );
    let mut table = MdTable::new([
        "reading",
        "what changes",
        "original (mean; pub. −0.0401)",
        "original dev (pub. 0.1761)",
        "r = 0.5 (0.0296)",
        "r = 1 (0.0246)",
        "r = 2 (0.0189)",
        "r = 4 (0.0143)",
        "within 30 %",
    ]);
    let project_row = ("project (dai.toml)", "ω(0) from Table 3, ω_d(0) from z0, gain 1, torque (8)", project.to_vec());
    let mut rows = vec![project_row];
    for (i, reading) in READINGS.iter().enumerate() {
        let mut plant = cont.plant_as::<RigidBodyPlant>().ok_or("dai.toml: not a rigid-body plant")?.clone();
        let mut algorithm = cont.algorithm_as::<DaiAttitude>().ok_or("dai.toml: not dai-attitude")?.clone();
        (reading.apply)(&mut plant, &mut algorithm);
        let mut scenario = cont.parsed.clone();
        scenario.plant.body = table_of(&plant).map_err(|e| e.to_string())?;
        scenario.algorithm.body = table_of(&algorithm).map_err(|e| e.to_string())?;
        let base = launcher.configure(scenario, reading.name).map_err(|e| e.to_string())?;
        let mut runs: Vec<Run> = Vec::new();
        for (j, kept) in project.iter().enumerate() {
            let (law, affected) = if j == 0 {
                (Law::Original, reading.changes != Changes::Specific)
            } else {
                (Law::Specific, reading.changes != Changes::Original)
            };
            if !affected {
                runs.push(kept.clone());
                continue;
            }
            let s = variant(launcher, &base, &format!("dai-reading{i}-{j}"), law, kept.r, None)?;
            let label = format!("{}: {} r = {}", reading.name, law.name(), kept.r);
            runs.push(run(launcher, &s, out, &label, false)?);
        }
        rows.push((reading.name, reading.what, runs));
    }
    for (name, what, runs) in &rows {
        let mut row = vec![name.to_string(), what.to_string(), g(runs[0].m("tracking_error_mean"))];
        let mut within = 0;
        for (j, run) in runs.iter().enumerate() {
            let (dev, published) = (run.m("tracking_error_dev"), T4_TRACK_DEV[j]);
            within += usize::from(((dev - published) / published).abs() <= 0.3);
            row.push(format!("{} ({})", g(dev), rel(dev, published)));
            let case = if j == 0 { "original".to_string() } else { format!("specific_r{}", run.r) };
            let _ = writeln!(
                csv,
                "\"{name}\",{case},{:e},{dev:e},{published:e},{:.1}",
                run.m("tracking_error_mean"),
                100.0 * (dev - published) / published
            );
        }
        row.push(format!("{within} / 5"));
        table.row(row);
    }
    let _ = write!(md, "{table}");
    let _ = writeln!(
        md,
        "\nPublished mean tracking error: original {}, specific {} (every r).\n",
        g(T4_TRACK_MEAN[0]),
        g(T4_TRACK_MEAN[1])
    );
    Ok((md, csv))
}
