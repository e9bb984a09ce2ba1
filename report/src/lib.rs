//! Post-run plots: read a run directory's telemetry CSVs and draw PNG figures into
//! `run_dir/plots/`; with the chart kit ([`chart`], [`chart3d`]) and the one telemetry reader
//! ([`table`]) that every paper's figures and analysis use.
//!
//! The reader knows only the shape every telemetry file shares: a header row whose first two
//! columns are `k` (step, integer) and `t_s` (simulated time in seconds), then one `f64` column
//! per quantity. Everything else is inferred from the column names, so new scenarios get plots
//! without changes here:
//!
//! * A column name is `[a<i>_]<name>[_<axis>][_<unit>]`. The `a<i>_` prefix (plant-side files
//!   only) says which agent the column belongs to; `<axis>` is `x`, `y` or `z`; `<unit>` is one
//!   of the suffixes [`columns::unit_label`] knows (`m`, `mps`, `mps2`, ...).
//! * Columns sharing agent, name and unit, and having two or more axes, form a vector, plotted
//!   as its Euclidean norm. Any other column is a scalar, plotted as is.
//! * Telemetry files are `<stem>.parquet` or `<stem>.csv` (see [`table`]); below, `plant.csv`
//!   stands for either.
//! * One figure per family (name and unit): `plant.csv` gives `plant_<name>.png` with one line
//!   per agent; the `agent-<id>.csv` files together give `agents_<name>.png`, overlaying all
//!   agents. Any other `<stem>.csv` gives `<stem>_<name>.png`.
//! * A file with agent positions (`a<i>_r_x_<unit>`, `a<i>_r_y_<unit>`) also gets an x–y path
//!   plot, `trajectories_xy.png` for `plant.csv`.
//!
//! Every series is reduced to at most [`chart::MAX_POINTS`] points (min/max per bucket, so spikes
//! survive), and a figure whose values are all positive and span more than
//! [`chart::LOG_SCALE_RATIO`] gets a logarithmic y axis (formation error converging to zero, say).
//! Non-finite values are accepted and leave gaps in the lines.
//!
//! All files are read and checked before any figure is drawn, so a malformed file leaves no
//! half-written set of plots behind.
//!
//! A paper adds its own figures through a [`FigureSource`] (the orchestrator asks the papers of
//! the run's scenario for theirs): they are drawn first, and plant columns the paper claims
//! ([`ColumnUse`]) are left out of the generic figures.

#[cfg(feature = "figures")]
pub mod chart;
#[cfg(feature = "figures")]
pub mod chart3d;
#[cfg(feature = "figures")]
pub mod columns;
#[cfg(feature = "figures")]
mod figures;
#[cfg(feature = "figures")]
mod generic;
pub mod markdown;
mod parquet_in;
#[cfg(feature = "figures")]
pub mod samples;
pub mod stats;
pub mod table;

use std::path::PathBuf;

#[cfg(feature = "figures")]
pub use chart::DrawResult;
#[cfg(feature = "figures")]
pub use figures::{ColumnUse, FigureSource, PaperFigure, Telemetry, report};
pub use table::{Column, Table};

/// Why [`report`] could not draw the plots. Every message names the file concerned.
#[derive(Debug, thiserror::Error)]
pub enum ReportError {
    #[error("no telemetry directory at {} (did the run write any telemetry?)", .path.display())]
    MissingTelemetryDir { path: PathBuf },
    #[error("telemetry directory {} holds no .parquet or .csv files", .path.display())]
    NoTelemetry { path: PathBuf },
    #[error("cannot read {}: {error}", .path.display())]
    Io { path: PathBuf, error: std::io::Error },
    /// Neither format of a telemetry file exists (`path` without its extension).
    #[error("cannot read {}.parquet or .csv: neither exists", .path.display())]
    MissingTelemetryFile { path: PathBuf },
    #[error("{}: bad header: {reason}", .path.display())]
    BadHeader { path: PathBuf, reason: String },
    #[error(
        "{}:{line}: expected {expected} columns (as in the header), found {found}",
        .path.display()
    )]
    ColumnCount { path: PathBuf, line: usize, expected: usize, found: usize },
    #[error("{}:{line}: column `{column}`: cannot parse {value:?} as a number", .path.display())]
    BadNumber { path: PathBuf, line: usize, column: String, value: String },
    #[error("cannot create plot directory {}: {error}", .path.display())]
    CreatePlotDir { path: PathBuf, error: std::io::Error },
    #[error("cannot register the embedded plot font (report/assets/DejaVuSans.ttf)")]
    Font,
    #[error("cannot draw {}: {message}", .path.display())]
    Plot { path: PathBuf, message: String },
    #[error("{}: not a readable telemetry Parquet file: {reason}", .path.display())]
    BadParquet { path: PathBuf, reason: String },
    #[error("{}: no column {column:?}", .path.display())]
    MissingColumn { path: PathBuf, column: String },
    /// An input of a paper's figures that cannot be drawn; `line` is 1-based, when known.
    #[error("{}{}: {reason}", .path.display(), .line.map(|l| format!(":{l}")).unwrap_or_default())]
    PaperInput { path: PathBuf, line: Option<usize>, reason: String },
}

#[cfg(all(test, feature = "figures"))]
mod tests {
    use super::*;
    use crate::chart::{MAX_POINTS, downsample_min_max, downsample_stride, finite_runs, format_tick, is_finite_point};
    use crate::columns::classify_columns;
    use crate::columns::{ColumnName, parse_column_name};
    use crate::table::read_table_with;
    use std::fmt::Write as _;
    use std::path::Path;
    use std::sync::atomic::{AtomicU32, Ordering};

    /// A scratch run directory, removed on drop.
    struct TempRun(PathBuf);

    impl TempRun {
        fn new(tag: &str) -> Self {
            static COUNTER: AtomicU32 = AtomicU32::new(0);
            let dir = std::env::temp_dir().join(format!(
                "cohort-report-{tag}-{}-{}",
                std::process::id(),
                COUNTER.fetch_add(1, Ordering::Relaxed)
            ));
            let _ = std::fs::remove_dir_all(&dir);
            std::fs::create_dir_all(dir.join("telemetry")).unwrap();
            TempRun(dir)
        }

        fn write(&self, name: &str, contents: &str) -> PathBuf {
            let path = self.0.join("telemetry").join(name);
            std::fs::write(&path, contents).unwrap();
            path
        }
    }

    impl Drop for TempRun {
        fn drop(&mut self) {
            let _ = std::fs::remove_dir_all(&self.0);
        }
    }

    const AXES: [&str; 3] = ["x", "y", "z"];

    /// A double-integrator run of `agents` agents converging onto a ring, `rows` rows.
    fn write_synthetic_run(run: &TempRun, agents: u32, rows: usize) {
        let dt = 0.1;
        let mut plant = String::from("k,t_s,formation_error_m");
        for i in 1..=agents {
            for q in ["r", "v"] {
                let unit = if q == "r" { "m" } else { "mps" };
                for a in AXES {
                    write!(plant, ",a{i}_{q}_{a}_{unit}").unwrap();
                }
            }
            for a in AXES {
                write!(plant, ",a{i}_u_{a}_mps2").unwrap();
            }
        }
        plant.push('\n');
        let mut agent_files: Vec<String> = (1..=agents)
            .map(|_| {
                "k,t_s,r_hat_x_m,r_hat_y_m,r_hat_z_m,v_hat_x_mps,v_hat_y_mps,v_hat_z_mps,\
                 u_x_mps2,u_y_mps2,u_z_mps2\n"
                    .to_string()
            })
            .collect();
        for k in 0..rows {
            let t = k as f64 * dt;
            let decay = (-0.05 * t).exp();
            // Falls over five decades, so its figure gets a log axis.
            write!(plant, "{k},{t:?},{:?}", 10.0 * (-0.25 * t).exp() + 1e-7).unwrap();
            for i in 1..=agents {
                let phase = f64::from(i) * std::f64::consts::TAU / f64::from(agents);
                let radius = 20.0 + 15.0 * decay * f64::from(i);
                let r =
                    [radius * (phase + 0.02 * t).cos(), radius * (phase + 0.02 * t).sin(), 0.5 * decay * f64::from(i)];
                let v = [
                    -0.02 * radius * (phase + 0.02 * t).sin(),
                    0.02 * radius * (phase + 0.02 * t).cos(),
                    -0.025 * decay * f64::from(i),
                ];
                let u = [-1e-3 * r[0], -1e-3 * r[1], 1e-4 * decay];
                for value in r.iter().chain(&v).chain(&u) {
                    write!(plant, ",{value:?}").unwrap();
                }
                let noise = 0.1 * (t * f64::from(i)).sin();
                let file = &mut agent_files[i as usize - 1];
                write!(file, "{k},{t:?}").unwrap();
                for value in r.iter().map(|x| x + noise).chain(v).chain(u) {
                    write!(file, ",{value:?}").unwrap();
                }
                file.push('\n');
            }
            plant.push('\n');
        }
        run.write("plant.csv", &plant);
        for (i, contents) in agent_files.iter().enumerate() {
            run.write(&format!("agent-{}.csv", i + 1), contents);
        }
    }

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

    #[test]
    fn plots_a_double_integrator_run() {
        let run = TempRun::new("ok");
        write_synthetic_run(&run, 3, 600);
        let written = report(&run.0, &[]).unwrap();
        assert_eq!(
            file_names(&written),
            [
                "plant_formation_error.png",
                "plant_r.png",
                "plant_v.png",
                "plant_u.png",
                "trajectories_xy.png",
                "agents_r_hat.png",
                "agents_v_hat.png",
                "agents_u.png",
            ]
        );
        for path in &written {
            assert_eq!(path.parent().unwrap(), run.0.join("plots"));
            assert_png(path);
        }
        keep_for_inspection("double_integrator", &written);
    }

    #[test]
    fn long_runs_are_downsampled_and_still_plotted() {
        let run = TempRun::new("long");
        write_synthetic_run(&run, 2, 12_000);
        let written = report(&run.0, &[]).unwrap();
        assert_eq!(written.len(), 8);
        written.iter().for_each(|p| assert_png(p));
        keep_for_inspection("long", &written);
    }

    #[test]
    fn odd_values_and_empty_files_do_not_panic() {
        let run = TempRun::new("odd");
        run.write(
            "plant.csv",
            "k,t_s,formation_error_m,a1_r_x_m,a1_r_y_m,mystery\n\
             0,0.0,NaN,1e308,-1e308,5\n\
             1,0.1,inf,-inf,NaN,5\n\
             2,0.2,1.0,0.0,0.0,5\n\
             \n\
             3,0.3,-2.5,1.0,1.0,5\r\n",
        );
        run.write("agent-1.csv", "k,t_s,u_x_mps2,u_y_mps2\n");
        run.write("agent-2.csv", "k,t_s,u_x_mps2,u_y_mps2\n0,0.0,NaN,NaN\n");
        let written = report(&run.0, &[]).unwrap();
        // `mystery` is constant and the agents' u has no finite value: no figure for either.
        assert_eq!(file_names(&written), ["plant_formation_error.png", "plant_r.png", "trajectories_xy.png"]);
        written.iter().for_each(|p| assert_png(p));
        keep_for_inspection("odd", &written);
    }

    #[test]
    fn bad_number_names_file_line_and_column() {
        let run = TempRun::new("badnum");
        let path = run.write("plant.csv", "k,t_s,formation_error_m,a1_r_x_m\n0,0.0,1.0,2.0\n1,0.1,1.0e,2.0\n");
        let err = report(&run.0, &[]).unwrap_err();
        match &err {
            ReportError::BadNumber { path: p, line, column, value } => {
                assert_eq!(p, &path);
                assert_eq!(*line, 3);
                assert_eq!(column, "formation_error_m");
                assert_eq!(value, "1.0e");
            }
            other => panic!("expected BadNumber, got {other:?}"),
        }
        let msg = err.to_string();
        assert!(msg.contains("plant.csv:3"), "{msg}");
        assert!(msg.contains("formation_error_m"), "{msg}");
        assert!(msg.contains("\"1.0e\""), "{msg}");
        assert!(!run.0.join("plots").exists(), "no plots after a read error");
    }

    #[test]
    fn bad_step_number_is_reported_against_k() {
        let run = TempRun::new("badk");
        run.write("agent-4.csv", "k,t_s,u_x_mps2\n0.5,0.0,1.0\n");
        let err = report(&run.0, &[]).unwrap_err();
        assert!(matches!(&err, ReportError::BadNumber { line: 2, column, .. } if column == "k"), "{err:?}");
        assert!(err.to_string().contains("agent-4.csv:2"), "{err}");
    }

    #[test]
    fn wrong_column_count_names_file_and_line() {
        let run = TempRun::new("cols");
        write_synthetic_run(&run, 2, 5);
        let path = run.write("agent-2.csv", "k,t_s,u_x_mps2,u_y_mps2\n0,0.0,1.0,2.0\n1,0.1,1.0\n");
        let err = report(&run.0, &[]).unwrap_err();
        match &err {
            ReportError::ColumnCount { path: p, line, expected, found } => {
                assert_eq!(p, &path);
                assert_eq!((*line, *expected, *found), (3, 4, 3));
            }
            other => panic!("expected ColumnCount, got {other:?}"),
        }
        let msg = err.to_string();
        assert!(msg.contains("agent-2.csv:3"), "{msg}");
        assert!(msg.contains("expected 4 columns"), "{msg}");
    }

    #[test]
    fn missing_telemetry_dir_is_reported() {
        let run = TempRun::new("missing");
        std::fs::remove_dir_all(run.0.join("telemetry")).unwrap();
        let err = report(&run.0, &[]).unwrap_err();
        assert!(matches!(err, ReportError::MissingTelemetryDir { .. }), "{err:?}");
        let msg = err.to_string();
        assert!(msg.contains(&run.0.join("telemetry").display().to_string()), "{msg}");
    }

    #[test]
    fn empty_telemetry_dir_is_reported() {
        let run = TempRun::new("empty");
        let err = report(&run.0, &[]).unwrap_err();
        assert!(matches!(err, ReportError::NoTelemetry { .. }), "{err:?}");
    }

    #[test]
    fn bad_headers_are_reported() {
        for (contents, needle) in [
            ("", "empty"),
            ("t_s,k,x_m\n", "`k,t_s`"),
            ("k\n", "`k,t_s`"),
            ("k,t_s,x_m,x_m\n", "duplicate column `x_m`"),
            ("k,t_s,,x_m\n", "column 3 has an empty name"),
        ] {
            let run = TempRun::new("header");
            run.write("plant.csv", contents);
            let err = report(&run.0, &[]).unwrap_err();
            assert!(matches!(err, ReportError::BadHeader { .. }), "{err:?}");
            let msg = err.to_string();
            assert!(msg.contains("plant.csv: bad header"), "{msg}");
            assert!(msg.contains(needle), "{msg} lacks {needle}");
        }
    }

    #[test]
    fn column_names_are_split_into_owner_name_axis_unit() {
        let parse = |s, owner| parse_column_name(s, owner);
        let cn = |owner, name: &str, axis, unit: Option<&str>| ColumnName {
            owner,
            name: name.to_string(),
            axis,
            unit: unit.map(str::to_string),
        };
        assert_eq!(parse("a12_r_x_m", true), cn(Some(12), "r", Some('x'), Some("m")));
        assert_eq!(parse("a12_r_x_m", false), cn(None, "a12_r", Some('x'), Some("m")));
        assert_eq!(parse("r_hat_z_m", false), cn(None, "r_hat", Some('z'), Some("m")));
        assert_eq!(parse("u_y_mps2", false), cn(None, "u", Some('y'), Some("mps2")));
        assert_eq!(parse("formation_error_m", true), cn(None, "formation_error", None, Some("m")));
        assert_eq!(parse("u_x", true), cn(None, "u", Some('x'), None));
        assert_eq!(parse("x_m", true), cn(None, "x", None, Some("m")));
        assert_eq!(parse("mystery", true), cn(None, "mystery", None, None));
        assert_eq!(parse("a_b", true), cn(None, "a_b", None, None));
        assert_eq!(parse("a1_", true), cn(None, "a1_", None, None));
    }

    #[test]
    fn lone_axis_columns_are_scalars() {
        let table = Table {
            k: vec![0],
            t: vec![0.0],
            columns: ["r_x_m", "v_x_mps", "v_y_mps"]
                .iter()
                .map(|n| Column { name: n.to_string(), values: vec![3.0] })
                .collect(),
        };
        let qs = classify_columns(&table, Some(2));
        assert_eq!(qs.len(), 2);
        assert_eq!((qs[0].name.as_str(), qs[0].is_vector()), ("r_x", false));
        assert_eq!((qs[1].name.as_str(), qs[1].is_vector()), ("v", true));
        assert_eq!(qs[1].owner, Some(2));
        assert_eq!(qs[1].values(&table), vec![(18.0f64).sqrt()]);
    }

    #[test]
    fn min_max_downsampling_bounds_points_and_keeps_extremes() {
        let n = 36_000;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let mut y: Vec<f64> = (0..n).map(|i| (i as f64 * 0.01).sin()).collect();
        y[12_345] = 50.0;
        y[20_000] = -50.0;
        let out = downsample_min_max(&x, &y, MAX_POINTS);
        assert!(out.len() <= MAX_POINTS, "{}", out.len());
        assert!(out.contains(&(12_345.0, 50.0)));
        assert!(out.contains(&(20_000.0, -50.0)));
        assert!(out.windows(2).all(|w| w[0].0 < w[1].0), "x stays in order");

        y[30_000] = f64::NAN;
        let out = downsample_min_max(&x, &y, MAX_POINTS);
        assert_eq!(out.iter().filter(|p| !is_finite_point(p)).count(), 1);
        assert_eq!(finite_runs(&out).count(), 2);

        let short = downsample_min_max(&x[..10], &y[..10], MAX_POINTS);
        assert_eq!(short.len(), 10);
    }

    #[test]
    fn stride_downsampling_keeps_first_and_last() {
        let n = 36_001;
        let x: Vec<f64> = (0..n).map(|i| i as f64).collect();
        let out = downsample_stride(&x, &x, MAX_POINTS);
        assert!(out.len() <= MAX_POINTS + 1, "{}", out.len());
        assert_eq!(out.first(), Some(&(0.0, 0.0)));
        assert_eq!(out.last(), Some(&(36_000.0, 36_000.0)));
        assert!(downsample_stride(&[], &[], MAX_POINTS).is_empty());
    }

    #[test]
    fn column_filter_skips_unparsed_columns() {
        let run = TempRun::new("filter");
        let path = run.write("plant.csv", "k,t_s,b0_r_eci_x_m,b0_q_lvlh_x_m,a1_e_norm_m\n0,0.0,junk,1.0,2.0\n");
        let table = read_table_with(&path, &|name| !name.contains("eci")).unwrap();
        let names: Vec<&str> = table.columns.iter().map(|c| c.name.as_str()).collect();
        assert_eq!(names, ["b0_q_lvlh_x_m", "a1_e_norm_m"]);
        assert_eq!(table.columns[1].values, [2.0]);
        assert!(Table::read(&path).is_err(), "the full read still checks every field");
    }

    #[test]
    fn ticks_are_short() {
        assert_eq!(format_tick(&0.0), "0");
        assert_eq!(format_tick(&2.5), "2.5");
        assert_eq!(format_tick(&-40.0), "-40");
        assert_eq!(format_tick(&0.0012), "0.0012");
        assert_eq!(format_tick(&1e-7), "1e-7");
        assert_eq!(format_tick(&-2.5e-4), "-2.5e-4");
        assert_eq!(format_tick(&250_000.0), "2.5e5");
        assert_eq!(format_tick(&123_456_789.0), "1.23e8");
    }
}
