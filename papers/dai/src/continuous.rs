//! Seed 004's continuous-time reproduction (`algorithm.coupling = "continuous"`): the plant's
//! Euler equations, the trajectory generator (14) and the learning law integrated together as
//! one ODE, as the paper's appendix does with ode45 at 1e-10 tolerances. This exists only
//! in-process — a message exchange every step would make it sampled-data, which is what the
//! default coupling is for — so `launch` runs it here (with or without `--reference`) and says so.
//!
//! State (16): q (4, scalar first), ω (3), ω_d (3), θ̂ (6) — the appendix code's z without the
//! original law's unused error integral z(17:19). Dormand–Prince 5(4) (ode45's pair) for the
//! original and specific laws; Radau IIA 5 for the general law, whose θ̂ dynamics have
//! eigenvalues up to −r σ_max(Φ)² (≈ −10⁶…−10⁷ s⁻¹ here), where an explicit method is held to
//! steps of ~10⁻⁷ s by stability alone. Output at t = k·dt_s for k = 0..=N (the code's
//! t = 0:0.001:5), by each method's dense output.
//!
//! The dynamics and the laws are not written here: [`crate::rigid_body`] and [`crate::attitude`]
//! provide them, the same functions the sampled-data processes run. The run directory has the layout of every run (telemetry/plant.csv and
//! agent-1.csv with the same columns, status/, logs/), so `summary.json`, the analysis and the
//! plots work unchanged.

use std::cell::Cell;
use std::collections::BTreeMap;
use std::time::Instant;

use cohort_runtime::model::PlantModel;
use cohort_runtime::paper::{CoupledCtx, CoupledOutcome, CoupledRun, Setup};
use cohort_runtime::record::{CsvWriter, ErrorKind, ProcessError, ProcessReport, RunDirs};
use differential_equations::prelude::*;
use differential_equations::solout::TEvalSolout;
use nalgebra::{Matrix3, Vector3, Vector4};

use crate::attitude::{DaiAttitudeAgent, LawParams, Reference, Theta, phi, phi_dot, regression, theta_rate};
use crate::config::{DaiAttitude, Integrator, Law};
use crate::rigid_body::{RigidBodyPlant, euler_rate, quaternion_rate};

pub const N_STATE: usize = 16;
pub type Y = [f64; N_STATE];

/// The coupled plant + learner.
pub struct Coupled {
    j: Matrix3<f64>,
    j_inv: Matrix3<f64>,
    reference: Reference,
    p: LawParams,
    evals: Cell<u64>,
}

/// Everything derived at one state.
pub struct Eval {
    pub u: Vector3<f64>,
    pub dw: Vector3<f64>,
    pub dwd: Vector3<f64>,
    pub dtheta: Theta,
}

fn parts(y: &Y) -> (Vector4<f64>, Vector3<f64>, Vector3<f64>, Theta) {
    (
        Vector4::new(y[0], y[1], y[2], y[3]),
        Vector3::new(y[4], y[5], y[6]),
        Vector3::new(y[7], y[8], y[9]),
        Theta::from_column_slice(&y[10..16]),
    )
}

impl Coupled {
    pub fn new(j: &[[f64; 3]; 3], a: &DaiAttitude) -> Self {
        let j = Matrix3::from_fn(|r, c| j[r][c]);
        let j_inv = j.try_inverse().expect("validated: the inertia is positive definite");
        Self { j, j_inv, reference: Reference::new(&a.reference), p: LawParams::of(a), evals: Cell::new(0) }
    }

    pub fn y0(q0: &[f64; 4], w0: &[f64; 3], a: &DaiAttitude) -> Y {
        let mut y = [0.0; N_STATE];
        y[0..4].copy_from_slice(q0);
        y[4..7].copy_from_slice(w0);
        y[7..10].copy_from_slice(&a.reference.omega_d0_rad_s);
        y[10..16].copy_from_slice(&a.inertia_estimate0_kg_m2);
        y
    }

    /// The controller's torque, the true accelerations, and the law's rate at (t, y): Φ from the
    /// true ω and ω̇ (the code's `P = p.P(w, dw, 0)`), τ the applied torque, Φ̇ with ω̈ = 0.
    pub fn eval(&self, t: f64, y: &Y) -> Eval {
        let (_, w, wd, theta) = parts(y);
        let dwd = self.reference.rate(t, &wd);
        let u = self.p.command(&theta, &wd, &dwd, &w);
        let dw = euler_rate(&self.j, &self.j_inv, &w, &u);
        let ph = phi(&w, &dw);
        let phd = if self.p.law == Law::General { phi_dot(&w, &dw, &Vector3::zeros()) } else { ph * 0.0 };
        let reg = regression(&self.p, ph, &phd, u);
        let dtheta = theta_rate(&self.p, &theta, Some(&reg), &w, &wd, &dwd);
        Eval { u, dw, dwd, dtheta }
    }
}

impl ODE<f64, Y> for Coupled {
    fn diff(&self, t: f64, y: &Y, dydt: &mut Y) {
        self.evals.set(self.evals.get() + 1);
        let e = self.eval(t, y);
        let (q, w, _, _) = parts(y);
        let dq = quaternion_rate(&q, &w);
        dydt[0..4].copy_from_slice(dq.as_slice());
        dydt[4..7].copy_from_slice(e.dw.as_slice());
        dydt[7..10].copy_from_slice(e.dwd.as_slice());
        dydt[10..16].copy_from_slice(e.dtheta.as_slice());
    }
}

/// Output at the grid points, progress, and Ctrl-C.
struct Watch<'a> {
    grid: TEvalSolout<f64>,
    dt_s: f64,
    ctx: Option<&'a CoupledCtx<'a>>,
    interrupted: &'a Cell<Option<i32>>,
}

impl Solout<f64, Y> for Watch<'_> {
    fn solout<I>(
        &mut self,
        t_curr: f64,
        t_prev: f64,
        y_curr: &Y,
        y_prev: &Y,
        interpolator: &mut I,
        solution: &mut Solution<f64, Y>,
    ) -> ControlFlag<f64, Y>
    where
        I: Interpolation<f64, Y> + ?Sized,
    {
        let flag = self.grid.solout(t_curr, t_prev, y_curr, y_prev, interpolator, solution);
        if let Some(ctx) = self.ctx {
            (ctx.progress)((t_curr / self.dt_s).floor() as u64);
            if let Some(sig) = (ctx.interrupted)() {
                self.interrupted.set(Some(sig));
                return ControlFlag::Terminate;
            }
        }
        flag
    }
}

/// A finished (or interrupted) integration.
pub struct Integrated {
    pub method: &'static str,
    pub t: Vec<f64>,
    pub y: Vec<Y>,
    pub steps_accepted: usize,
    pub steps_rejected: usize,
    pub rhs_evals: u64,
    pub wall_s: f64,
    /// The signal the integration stopped on, if it was interrupted.
    pub interrupted: Option<i32>,
}

/// Which method `auto` means for a law.
pub fn method_for(a: &DaiAttitude) -> &'static str {
    match a.continuous_settings().method {
        Integrator::Dopri5 => "dopri5",
        Integrator::Radau5 => "radau5",
        Integrator::Auto if a.law() == Law::General => "radau5",
        Integrator::Auto => "dopri5",
    }
}

/// The continuous coupling as the runtime sees it (see [`CoupledRun`]).
pub struct Continuous;

impl CoupledRun for Continuous {
    fn name(&self) -> &'static str {
        "continuous"
    }
    fn describe(&self) -> &'static str {
        "continuous: plant and learner integrated as one ODE in this process, no processes spawned"
    }
    fn run(&self, setup: &Setup, dirs: &RunDirs, ctx: &CoupledCtx<'_>) -> CoupledOutcome {
        launch(setup, dirs, ctx)
    }
}

/// The continuous algorithm and the rigid-body plant of a setup.
fn parts_of(s: &Setup) -> Result<(&DaiAttitude, &crate::config::RigidBodyPlant), String> {
    let a = s.algorithm_as::<DaiAttitude>().filter(|a| a.is_continuous());
    let a = a.ok_or("not a coupling = \"continuous\" scenario")?;
    let pl = s.plant_as::<crate::config::RigidBodyPlant>().ok_or("plant.kind must be \"rigid-body\"")?;
    Ok((a, pl))
}

/// Integrate the coupled system of a validated continuous scenario over [0, duration] with
/// output every dt_s.
pub fn integrate(s: &Setup, ctx: Option<&CoupledCtx<'_>>) -> Result<(Coupled, Integrated), String> {
    let (a, pl) = parts_of(s)?;
    let ode = Coupled::new(&pl.inertia_kg_m2, a);
    let y0 = Coupled::y0(&pl.q0_inertial_body, &pl.omega0_body_rad_s, a);
    let n = s.n_steps();
    let dt = s.scenario.dt_s;
    let tf = n as f64 * dt;
    let grid: Vec<f64> = (0..=n).map(|k| k as f64 * dt).collect();
    let settings = a.continuous_settings();
    let interrupted = Cell::new(None);
    let watch = Watch { grid: TEvalSolout::new(grid, 0.0, tf), dt_s: dt, ctx, interrupted: &interrupted };
    let method = method_for(a);
    let started = Instant::now();
    let max_steps = 100_000_000;
    let solved = match method {
        "radau5" => IVP::ode(&ode, 0.0, tf, y0)
            .solout(watch)
            .method(ImplicitRungeKutta::radau5().rtol(settings.rtol).atol(settings.atol).max_steps(max_steps))
            .solve(),
        _ => IVP::ode(&ode, 0.0, tf, y0)
            .solout(watch)
            .method(ExplicitRungeKutta::dopri5().rtol(settings.rtol).atol(settings.atol).max_steps(max_steps))
            .solve(),
    };
    let wall_s = started.elapsed().as_secs_f64();
    let sol = solved.map_err(|e| format!("{method} failed: {e:?}"))?;
    let out = Integrated {
        method,
        t: sol.t,
        y: sol.y,
        steps_accepted: sol.steps.accepted,
        steps_rejected: sol.steps.rejected,
        rhs_evals: ode.evals.get(),
        wall_s,
        interrupted: interrupted.get(),
    };
    Ok((ode, out))
}

fn io(path: &std::path::Path) -> impl Fn(std::io::Error) -> String + '_ {
    move |e| format!("{}: {e}", path.display())
}

/// Write the run directory's telemetry and process reports for an integration.
fn write(s: &Setup, dirs: &RunDirs, ode: &Coupled, r: &Integrated) -> Result<BTreeMap<String, f64>, String> {
    let (_, pl) = parts_of(s)?;
    let mut truth = RigidBodyPlant::new(&pl.inertia_kg_m2, pl.omega0_body_rad_s, pl.q0_inertial_body, 1, 1, 0.0);
    let mut pcols = vec!["k".to_string(), "t_s".to_string()];
    pcols.extend(truth.columns());
    let mut acols = vec!["k".to_string(), "t_s".to_string()];
    acols.extend(DaiAttitudeAgent::column_names());
    let ppath = dirs.telemetry().join("plant.csv");
    let apath = dirs.telemetry().join("agent-1.csv");
    let mut ptel = CsvWriter::create(&ppath, &pcols).map_err(io(&ppath))?;
    let mut atel = CsvWriter::create(&apath, &acols).map_err(io(&apath))?;
    let (mut prow, mut arow) = (Vec::new(), Vec::new());
    for (k, (t, y)) in r.t.iter().zip(&r.y).enumerate() {
        let e = ode.eval(*t, y);
        let (q, w, wd, theta) = parts(y);
        {
            let b = truth.body_mut(1);
            b.q = q;
            b.omega_rad_s = w;
        }
        truth.apply_command(1, e.u.as_slice());
        prow.clear();
        prow.push(*t);
        truth.row(&mut prow);
        ptel.row(k as u64, &prow).map_err(io(&ppath))?;
        arow.clear();
        arow.push(*t);
        DaiAttitudeAgent::row_of(&wd, &e.dwd, &theta, &e.u, &mut arow);
        atel.row(k as u64, &arow).map_err(io(&apath))?;
    }
    ptel.flush().map_err(io(&ppath))?;
    atel.flush().map_err(io(&apath))?;
    let mut metrics: BTreeMap<String, f64> = truth.metrics().into_iter().collect();
    metrics.insert("solver_steps_accepted".into(), r.steps_accepted as f64);
    metrics.insert("solver_steps_rejected".into(), r.steps_rejected as f64);
    metrics.insert("solver_rhs_evals".into(), r.rhs_evals as f64);
    Ok(metrics)
}

/// `launch` of a continuous scenario: integrate, write the run directory, report.
pub fn launch(s: &Setup, dirs: &RunDirs, ctx: &CoupledCtx<'_>) -> CoupledOutcome {
    let started = Instant::now();
    let fail = |error: String| CoupledOutcome {
        error: Some(error),
        interrupted: None,
        wall_s: started.elapsed().as_secs_f64(),
    };
    let (ode, r) = match integrate(s, Some(ctx)) {
        Ok(x) => x,
        Err(e) => return fail(e),
    };
    let n = s.n_steps();
    let steps_completed = (r.t.len() as u64).saturating_sub(1);
    let metrics = match write(s, dirs, &ode, &r) {
        Ok(m) => m,
        Err(e) => return fail(e),
    };
    let error = if let Some(sig) = r.interrupted {
        Some(format!("interrupted by signal {sig} at t = {:.4} s", r.t.last().copied().unwrap_or(0.0)))
    } else if steps_completed < n {
        Some(format!("{} stopped at output {steps_completed} of {n}", r.method))
    } else {
        None
    };
    let report = |process: &str, metrics: BTreeMap<String, f64>| ProcessReport {
        steps_completed,
        wall_s: r.wall_s,
        metrics,
        error: error.clone().map(|e| {
            let kind = if r.interrupted.is_some() { ErrorKind::Stopped } else { ErrorKind::Diverged };
            ProcessError::new(kind, e)
        }),
        ..ProcessReport::new(process.to_string())
    };
    let mut write_errors = Vec::new();
    for rep in [report("plant", metrics), report("agent-1", BTreeMap::new())] {
        if let Err(e) = rep.write(dirs) {
            write_errors.push(format!("status/{}.json: {e}", rep.process));
        }
    }
    let settings = s.algorithm_as::<DaiAttitude>().map(|a| a.continuous_settings()).unwrap_or_default();
    let log = format!(
        "continuous coupling (in-process, one ODE of plant + learner): method {}, rtol {:e}, atol {:e}; \
         {} accepted and {} rejected steps, {} right-hand-side evaluations, {:.3} s\n",
        r.method, settings.rtol, settings.atol, r.steps_accepted, r.steps_rejected, r.rhs_evals, r.wall_s
    );
    for name in ["plant", "agent-1"] {
        if let Err(e) = std::fs::write(dirs.logs().join(format!("{name}.log")), &log) {
            write_errors.push(format!("logs/{name}.log: {e}"));
        }
    }
    (ctx.progress)(steps_completed);
    let wall_s = started.elapsed().as_secs_f64();
    let error = error.or_else(|| (!write_errors.is_empty()).then(|| write_errors.join("; ")));
    CoupledOutcome { error, interrupted: r.interrupted, wall_s }
}
