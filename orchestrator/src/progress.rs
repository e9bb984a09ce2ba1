//! The launch progress bar: sim time, steps/s and ETA (hidden when stderr is not a terminal).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

pub struct Progress {
    bar: ProgressBar,
    dt_s: f64,
    started: std::time::Instant,
}

impl Progress {
    pub fn new(n_steps: u64, dt_s: f64, label: &str, visible: bool) -> Self {
        let target = if visible { ProgressDrawTarget::stderr_with_hz(10) } else { ProgressDrawTarget::hidden() };
        let bar = ProgressBar::with_draw_target(Some(n_steps), target);
        let style = ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} steps  {msg}  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
        bar.set_style(style);
        bar.set_prefix(label.to_string());
        Self { bar, dt_s, started: std::time::Instant::now() }
    }
    pub fn set(&self, step: u64) {
        // For the live view's progress channel (`--live`); a relaxed store, live or not.
        crate::live::STEP.store(step, std::sync::atomic::Ordering::Relaxed);
        if step != self.bar.position() {
            self.bar.set_position(step);
            let rate = step as f64 / self.started.elapsed().as_secs_f64().max(1e-9);
            self.bar.set_message(format!("t = {:.2} s  {rate:.0} steps/s", step as f64 * self.dt_s));
        }
    }
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
