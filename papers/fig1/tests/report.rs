//! The servicing run's figures, drawn by the generic report with the paper's figure source: a
//! synthetic run shaped like fig1's (per-body ECI and LVLH plant columns, `derived/fig1.csv`).

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use cohort::{Scratch, scratch_dir};
use cohort_paper_fig1::host::figures::Fig1Figures;
use cohort_report::{ReportError, report};

/// A scratch run directory with an empty `telemetry/` (removed on drop unless the test fails).
struct TempRun(Scratch);

impl TempRun {
    fn new(tag: &str) -> Self {
        let dir = scratch_dir(&format!("fig1-report-{tag}"));
        std::fs::create_dir_all(dir.join("telemetry")).unwrap();
        TempRun(dir)
    }

    fn write(&self, name: &str, contents: &str) -> PathBuf {
        let path = self.0.join("telemetry").join(name);
        std::fs::write(&path, contents).unwrap();
        path
    }
}

const AXES: [&str; 3] = ["x", "y", "z"];

fn file_names(paths: &[PathBuf]) -> Vec<String> {
    paths.iter().map(|p| p.file_name().unwrap().to_string_lossy().into_owned()).collect()
}

/// With `COHORT_REPORT_KEEP=<dir>` set, copies the figures to `<dir>/<tag>/` to be looked at.
fn keep_for_inspection(tag: &str, written: &[PathBuf]) {
    let Some(dir) = std::env::var_os("COHORT_REPORT_KEEP") else {
        return;
    };
    let dir = PathBuf::from(dir).join(tag);
    std::fs::create_dir_all(&dir).unwrap();
    for path in written {
        std::fs::copy(path, dir.join(path.file_name().unwrap())).unwrap();
    }
}

fn assert_png(path: &Path) {
    let bytes = std::fs::read(path).unwrap();
    assert!(bytes.len() > 1024, "{} is only {} bytes", path.display(), bytes.len());
    assert_eq!(&bytes[..8], b"\x89PNG\r\n\x1a\n", "{} is not a PNG", path.display());
}

/// A run shaped like the seed-000 servicing scenario: `servicers` servicers closing on a
/// defunct spacecraft, `rows` rows `dt` seconds apart. `plant.csv` has per-body ECI and LVLH
/// columns and per-agent `e_norm`, `zeta`, `u`; `agent-<i>.csv` has `zeta_hat` and
/// `theta_norm`; with `derived`, `derived/fig1.csv` is computed from them the way the
/// orchestrator does. Returns the path of `derived/fig1.csv`.
fn write_fig1_run(run: &TempRun, servicers: u32, rows: usize, dt: f64, derived: bool) -> PathBuf {
    let mut plant = String::from("k,t_s");
    for b in 0..=servicers {
        for q in ["r_eci", "v_eci", "q_lvlh"] {
            let unit = if q == "v_eci" { "mps" } else { "m" };
            for a in AXES {
                write!(plant, ",b{b}_{q}_{a}_{unit}").unwrap();
            }
        }
    }
    for i in 1..=servicers {
        write!(plant, ",a{i}_e_norm_m").unwrap();
        for q in ["zeta", "u"] {
            let unit = if q == "zeta" { "mps" } else { "mps2" };
            for a in AXES {
                write!(plant, ",a{i}_{q}_{a}_{unit}").unwrap();
            }
        }
    }
    plant.push('\n');
    let mut agents: Vec<String> = (1..=servicers)
        .map(|_| "k,t_s,u_x_mps2,u_y_mps2,u_z_mps2,theta_norm,zeta_hat_x_mps,zeta_hat_y_mps,zeta_hat_z_mps\n".into())
        .collect();
    let mut fig1 = String::from("k,t_s");
    for i in 1..=servicers {
        write!(fig1, ",a{i}_e_norm_m,a{i}_zeta_err_norm_mps,a{i}_u_norm_mps2,a{i}_theta_norm").unwrap();
    }
    fig1.push('\n');
    let norm = |v: [f64; 3]| v.iter().map(|c| c * c).sum::<f64>().sqrt();
    for k in 0..rows {
        let t = k as f64 * dt;
        write!(plant, "{k},{t:?}").unwrap();
        write!(fig1, "{k},{t:?}").unwrap();
        let q0 = [-0.004 * t * t, 0.01 * t, 0.0];
        let q: Vec<[f64; 3]> = (0..=servicers)
            .map(|b| {
                if b == 0 {
                    return q0;
                }
                let phase = f64::from(b) * 2.0;
                let size = 3000.0 * (-t / 40.0).exp() + 2.0 + (0.3 * t + phase).sin();
                [q0[0] + size * phase.cos(), q0[1] + size * phase.sin(), q0[2] + 0.4 * size]
            })
            .collect();
        for qb in &q {
            let r = [6.678e6 + qb[0], qb[1], qb[2]];
            let v = [0.0, 7.7e3, 0.1 * qb[2]];
            for value in r.iter().chain(&v).chain(qb) {
                write!(plant, ",{value:?}").unwrap();
            }
        }
        for i in 1..=servicers {
            let e = norm([0, 1, 2].map(|a| q[i as usize][a] - q0[a]));
            let zeta = [10.0 * (0.1 * t).cos(), 3.0, -1.0];
            let err = 1e4 * (-t / 5.0).exp() + 0.5 * (t * f64::from(i)).sin().abs();
            let zeta_hat = [zeta[0] - err, zeta[1], zeta[2]];
            // One exact zero for the log axis to floor.
            let u = if k == 3 { [0.0; 3] } else { [-0.01 * e, 1e-3, 2e-3 * (t / 7.0).sin()] };
            let theta = 6.0 + 0.01 * t;
            write!(plant, ",{e:?}").unwrap();
            for value in zeta.iter().chain(&u) {
                write!(plant, ",{value:?}").unwrap();
            }
            let file = &mut agents[i as usize - 1];
            write!(file, "{k},{t:?}").unwrap();
            for value in u.iter().chain([&theta]).chain(&zeta_hat) {
                write!(file, ",{value:?}").unwrap();
            }
            file.push('\n');
            let zeta_err = norm([0, 1, 2].map(|a| zeta[a] - zeta_hat[a]));
            // One NaN, a gap in the line.
            let e_out = if k == 5 && i == 1 { f64::NAN } else { e };
            write!(fig1, ",{e_out:?},{zeta_err:?},{:?},{theta:?}", norm(u)).unwrap();
        }
        plant.push('\n');
        fig1.push('\n');
    }
    run.write("plant.csv", &plant);
    for (i, contents) in agents.iter().enumerate() {
        run.write(&format!("agent-{}.csv", i + 1), contents);
    }
    let derived_path = run.0.join("derived").join("fig1.csv");
    if derived {
        std::fs::create_dir_all(derived_path.parent().unwrap()).unwrap();
        std::fs::write(&derived_path, fig1).unwrap();
    }
    derived_path
}

const FIG1_FIGURES: [&str; 5] = [
    "fig2_trajectories_3d.png",
    "fig3_zeta_error.png",
    "fig4_tracking_error.png",
    "fig4_tracking_error_late.png",
    "u_norm.png",
];

#[test]
fn fig1_run_gets_the_paper_figures() {
    let run = TempRun::new("fig1");
    write_fig1_run(&run, 2, 73, 5.0, true);
    let written = report(&run.0, &[&Fig1Figures]).unwrap();
    let names = file_names(&written);
    assert_eq!(names[..5], FIG1_FIGURES, "{names:?}");
    // The generic figures stay, but not the per-body ECI/LVLH ones, nor the agents' own
    // command components (the plant's applied command and u_norm.png show them already).
    assert_eq!(
        names[5..],
        ["plant_e_norm.png", "plant_zeta.png", "plant_u.png", "agents_theta_norm.png", "agents_zeta_hat.png"]
    );
    written.iter().for_each(|p| assert_png(p));
    keep_for_inspection("fig1", &written);
}

#[test]
fn short_fig1_run_still_gets_every_figure() {
    // 20 s: shorter than Fig. 2's window and than the late view's 150 s start.
    let run = TempRun::new("fig1short");
    write_fig1_run(&run, 2, 5, 5.0, true);
    let written = report(&run.0, &[&Fig1Figures]).unwrap();
    assert_eq!(file_names(&written)[..5], FIG1_FIGURES);
    written.iter().for_each(|p| assert_png(p));
}

#[test]
fn without_derived_fig1_csv_only_generic_plots() {
    let run = TempRun::new("nofig1");
    write_fig1_run(&run, 2, 20, 5.0, false);
    // A run without `derived/fig1.csv` is not given the paper's figures (see `Fig1::figures`).
    let names = file_names(&report(&run.0, &[]).unwrap());
    for fig in FIG1_FIGURES {
        assert!(!names.iter().any(|n| n == fig), "{fig} in {names:?}");
    }
    // Unchanged behaviour: every plant column family gets its generic figure.
    assert!(names.iter().any(|n| n == "plant_b0_r_eci.png"), "{names:?}");
    assert!(names.iter().any(|n| n == "plant_b2_q_lvlh.png"), "{names:?}");
    assert!(names.iter().any(|n| n == "plant_e_norm.png"), "{names:?}");
}

#[test]
fn malformed_derived_fig1_csv_names_file_and_line() {
    let run = TempRun::new("fig1bad");
    let derived = write_fig1_run(&run, 2, 10, 5.0, true);
    let good = std::fs::read_to_string(&derived).unwrap();
    let mut lines: Vec<String> = good.lines().map(str::to_string).collect();

    // A bad number on line 4 (the header is line 1).
    let mut bad = lines.clone();
    bad[3] = bad[3].replacen(",", ",x", 2).replacen(",x", ",", 1);
    std::fs::write(&derived, bad.join("\n")).unwrap();
    let err = report(&run.0, &[&Fig1Figures]).unwrap_err();
    assert!(matches!(&err, ReportError::BadNumber { path, line: 4, .. } if *path == derived), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("derived/fig1.csv:4"), "{msg}");
    assert!(!run.0.join("plots").exists(), "no plots after a read error");

    // A short row.
    let mut short = lines.clone();
    short[6] = short[6].rsplit_once(',').unwrap().0.to_string();
    std::fs::write(&derived, short.join("\n")).unwrap();
    let msg = report(&run.0, &[&Fig1Figures]).unwrap_err().to_string();
    assert!(msg.contains("derived/fig1.csv:7: expected 10 columns"), "{msg}");

    // A missing column.
    for line in &mut lines {
        *line = line.rsplitn(3, ',').nth(2).unwrap().to_string();
    }
    assert!(lines[0].ends_with("a2_zeta_err_norm_mps"), "{}", lines[0]);
    std::fs::write(&derived, lines.join("\n")).unwrap();
    let err = report(&run.0, &[&Fig1Figures]).unwrap_err();
    assert!(matches!(&err, ReportError::PaperInput { path, .. } if *path == derived), "{err:?}");
    let msg = err.to_string();
    assert!(msg.contains("derived/fig1.csv: missing column `a2_u_norm_mps2`"), "{msg}");

    // No agents at all; an empty file.
    std::fs::write(&derived, "k,t_s,theta\n0,0.0,1.0\n").unwrap();
    let msg = report(&run.0, &[&Fig1Figures]).unwrap_err().to_string();
    assert!(msg.contains("derived/fig1.csv: no `a<i>_e_norm_m` columns"), "{msg}");
    std::fs::write(&derived, "").unwrap();
    let msg = report(&run.0, &[&Fig1Figures]).unwrap_err().to_string();
    assert!(msg.contains("derived/fig1.csv: bad header"), "{msg}");
    assert!(!run.0.join("plots").exists(), "no plots after a read error");
}

#[test]
fn fig1_run_needs_the_lvlh_columns() {
    let run = TempRun::new("fig1nolvlh");
    write_fig1_run(&run, 2, 10, 5.0, true);
    let plant = run.0.join("telemetry").join("plant.csv");
    std::fs::write(&plant, "k,t_s,a1_e_norm_m\n0,0.0,1.0\n").unwrap();
    let err = report(&run.0, &[&Fig1Figures]).unwrap_err();
    assert!(matches!(&err, ReportError::PaperInput { path, .. } if *path == plant), "{err:?}");
    assert!(err.to_string().contains("q_lvlh"), "{err}");
    std::fs::remove_file(&plant).unwrap();
    let msg = report(&run.0, &[&Fig1Figures]).unwrap_err().to_string();
    assert!(msg.contains("plant.csv: missing"), "{msg}");
}
