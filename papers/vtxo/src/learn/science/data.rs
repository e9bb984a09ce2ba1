//! "Explainable AI-Enhanced Supervisory Control for High-Precision Spacecraft Formation"
//! (R. Pirayeshshirazinezhad, arXiv:2509.13331).
//!
//! `orchestrator train vtxo-science-data`: the science-phase Pareto data of Sec. 3.1 and 3.2.2 —
//! for each random science start (84) and its disturbance realisation ([`crate::learn::science::sim`]), the
//! Pareto-optimal gains of the PD (54) and of the SMC (58)–(60) for χ = [E, e] (72)
//! ([`crate::learn::science::moga`]) — written as two CSV tables, `science-pd.csv` and `science-smc.csv`,
//! one row per Pareto-optimal design.
//!
//! A row is what the science DNN learns from: the inputs x₀ = (q₀, ω₀) and w, the outputs E, e
//! and k̂, and ω_f (the body rate at the end of the phase, for the Table 3 analogue). The paper's
//! w "= e/E is a weight for e over E" (Sec. 3.1): on a Pareto front each design is the optimum of
//! the scalarised loss for one trade-off, so each row's w is its own e/E (deg/J), which is also how
//! Table 4's inputs relate to Table 5 (0.2219/0.0353 = 6.29 ≈ w_PD = 6.28).
//!
//! Draw i of seed s takes the ChaCha8 stream (s, i) for its start, its environment, and then the
//! two searches (PD, then SMC) in that order, so the tables do not depend on the threads.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use cohort_host::campaign::Campaign;

use crate::learn::science::moga::{self, Design, Settings};
use crate::learn::science::sim::{self, ScienceLaw, Start};

/// The trainer's name.
pub const NAME: &str = "vtxo-science-data";
/// Input columns, in the network's order (q scalar last).
pub const INPUT_COLUMNS: [&str; 8] = ["q0", "q1", "q2", "q3", "w0_rad_s", "w1_rad_s", "w2_rad_s", "w_deg_per_J"];
/// The objective columns.
pub const OBJECTIVE_COLUMNS: [&str; 2] = ["E_J", "e_deg"];
/// The end-of-phase rate columns.
pub const OMEGA_END_COLUMNS: [&str; 3] = ["wf0_rad_s", "wf1_rad_s", "wf2_rad_s"];

/// What to generate.
#[derive(Debug, Clone, PartialEq)]
pub struct Options {
    pub draws: usize,
    pub seed: u64,
    pub population: usize,
    pub generations: usize,
    pub phase_s: f64,
    pub dt_s: f64,
    pub threads: usize,
    /// Directory of `science-pd.csv` and `science-smc.csv`.
    pub out_dir: PathBuf,
}

impl Options {
    /// The first line of a table: what produced it.
    pub fn provenance(&self, law: ScienceLaw) -> String {
        format!(
            "# {NAME} law {} seed {} draws {} population {} generations {} phase_s {} dt_s {}",
            law.name(),
            self.seed,
            self.draws,
            self.population,
            self.generations,
            self.phase_s,
            self.dt_s
        )
    }
}

/// The table of `law` in `dir`.
pub fn table_path(dir: &Path, law: ScienceLaw) -> PathBuf {
    dir.join(format!("science-{}.csv", law.name()))
}

/// The header of `law`'s table.
pub fn header(law: ScienceLaw) -> String {
    let cols: Vec<&str> = ["draw"]
        .iter()
        .chain(&INPUT_COLUMNS)
        .chain(&OBJECTIVE_COLUMNS)
        .chain(law.gain_columns())
        .chain(&OMEGA_END_COLUMNS)
        .copied()
        .collect();
    cols.join(",")
}

/// One draw's fronts (PD, SMC).
#[derive(Debug, Clone)]
pub struct DrawFronts {
    pub start: Start,
    pub fronts: [Vec<Design>; 2],
}

/// Draw `index` and search both laws.
pub fn draw_fronts(o: &Options, index: u64) -> DrawFronts {
    let steps = sim::steps(o.phase_s, o.dt_s);
    let (start, env, mut rng) = sim::draw(o.seed, index, steps, o.dt_s);
    let s = Settings { population: o.population, generations: o.generations, dt_s: o.dt_s };
    let pd = moga::pareto(&start, &env, ScienceLaw::Pd, &s, &mut rng);
    let smc = moga::pareto(&start, &env, ScienceLaw::Smc, &s, &mut rng);
    DrawFronts { start, fronts: [pd, smc] }
}

/// One CSV row (shortest round-trip formatting).
pub fn row(index: usize, start: &Start, d: &Design) -> String {
    let (q, w, o) = (start.q, start.omega_rad_s, &d.outcome);
    let weight = if o.energy_j > 0.0 { o.error_deg / o.energy_j } else { 0.0 };
    let mut vals = vec![q[0], q[1], q[2], q[3], w[0], w[1], w[2], weight, o.energy_j, o.error_deg];
    vals.extend(&d.gains);
    vals.extend(o.omega_end_rad_s.iter());
    let mut s = index.to_string();
    for v in vals {
        let _ = write!(s, ",{v}");
    }
    s
}

/// Why the tables could not be written.
#[derive(Debug, thiserror::Error)]
pub enum DataError {
    #[error("{path}: {source}")]
    Io { path: PathBuf, source: std::io::Error },
    #[error("{0}")]
    Options(String),
}

/// What a run did.
#[derive(Debug, Clone)]
pub struct Summary {
    pub rows: [usize; 2],
    pub seconds: f64,
    pub flights: usize,
}

/// Generate both tables.
pub fn run(o: &Options) -> Result<Summary, DataError> {
    if o.draws == 0 || o.population < 2 || o.threads == 0 {
        return Err(DataError::Options("--draws and --threads must be at least 1, --population at least 2".into()));
    }
    if !(o.dt_s > 0.0 && o.dt_s <= 0.1 && o.phase_s >= o.dt_s && o.phase_s <= 36_000.0) {
        return Err(DataError::Options(format!(
            "--dt {} s, --phase {} s: the step must be in (0, 0.1] s and the phase in [dt, 10 h]",
            o.dt_s, o.phase_s
        )));
    }
    let t0 = Instant::now();
    let progress = |n: usize, draws: usize| {
        tracing::info!("{NAME}: {n}/{draws} draws, {:.1} s", t0.elapsed().as_secs_f64());
    };
    let all: Vec<DrawFronts> =
        Campaign::new(o.draws).workers(o.threads).progress(&progress).map(|i| draw_fronts(o, i as u64));
    let io = |path: &Path| {
        let path = path.to_path_buf();
        move |source| DataError::Io { path, source }
    };
    std::fs::create_dir_all(&o.out_dir).map_err(io(&o.out_dir))?;
    let mut rows = [0; 2];
    for (l, law) in ScienceLaw::ALL.iter().enumerate() {
        let mut text = format!("{}\n{}\n", o.provenance(*law), header(*law));
        for (i, d) in all.iter().enumerate() {
            for design in &d.fronts[l] {
                text += &row(i, &d.start, design);
                text.push('\n');
                rows[l] += 1;
            }
        }
        let path = table_path(&o.out_dir, *law);
        std::fs::write(&path, text).map_err(io(&path))?;
    }
    let flights = o.draws * 2 * o.population * (o.generations + 1);
    Ok(Summary { rows, seconds: t0.elapsed().as_secs_f64(), flights })
}

#[cfg(test)]
mod tests {
    use super::*;

    pub(crate) fn tiny(out_dir: PathBuf, threads: usize) -> Options {
        Options { draws: 6, seed: 4, population: 6, generations: 2, phase_s: 20.0, dt_s: 0.01, threads, out_dir }
    }

    #[test]
    fn the_tables_do_not_depend_on_the_threads_and_name_their_columns() {
        let dir = std::env::temp_dir().join(format!("vtxo-science-data-{}", std::process::id()));
        let (a, b) = (dir.join("a"), dir.join("b"));
        let s = run(&tiny(a.clone(), 2)).expect("two threads");
        run(&tiny(b.clone(), 1)).expect("one thread");
        for law in ScienceLaw::ALL {
            let (ta, tb) = (std::fs::read(table_path(&a, law)).unwrap(), std::fs::read(table_path(&b, law)).unwrap());
            assert_eq!(ta, tb, "{law:?}: threads changed the table");
            let text = String::from_utf8(ta).unwrap();
            let mut lines = text.lines();
            assert_eq!(lines.next(), Some(tiny(a.clone(), 2).provenance(law).as_str()));
            let head = lines.next().unwrap();
            assert_eq!(head, header(law));
            let width = head.split(',').count();
            assert_eq!(width, 1 + 8 + 2 + law.n_gains() + 3);
            for l in lines {
                let f: Vec<f64> = l.split(',').map(|x| x.parse().unwrap()).collect();
                assert_eq!(f.len(), width);
                // w = e/E of the row itself.
                assert!((f[8] - f[10] / f[9]).abs() <= 1e-12 * f[8].abs(), "{l}");
            }
        }
        assert!(s.rows.iter().all(|r| *r >= 6), "a front per draw: {:?}", s.rows);
        let e = run(&Options { population: 1, ..tiny(a.clone(), 1) }).expect_err("population 1");
        assert!(e.to_string().contains("--population"), "{e}");
        std::fs::remove_dir_all(&dir).ok();
    }
}
