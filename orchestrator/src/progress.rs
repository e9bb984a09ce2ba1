//! The launch progress bar: sim time, steps/s and ETA (hidden when stderr is not a terminal).

use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

pub struct Progress {
    bar: ProgressBar,
    dt_s: f64,
}

impl Progress {
    pub fn new(n_steps: u64, dt_s: f64, label: &str) -> Self {
        let bar = ProgressBar::with_draw_target(Some(n_steps), ProgressDrawTarget::stderr_with_hz(10));
        let style = ProgressStyle::with_template("{prefix} [{bar:30}] {pos}/{len} steps  {msg}  {per_sec}  ETA {eta}")
            .unwrap_or_else(|_| ProgressStyle::default_bar())
            .progress_chars("=> ");
        bar.set_style(style);
        bar.set_prefix(label.to_string());
        Self { bar, dt_s }
    }
    pub fn set(&self, step: u64) {
        if step != self.bar.position() {
            self.bar.set_position(step);
            self.bar.set_message(format!("t = {:.2} s", step as f64 * self.dt_s));
        }
    }
    pub fn finish(&self) {
        self.bar.finish_and_clear();
    }
}
