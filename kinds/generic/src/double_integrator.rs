//! Point masses with r̈ = u (3-D double integrators), the consensus-ring plant. Each agent senses
//! its own position with zero-mean Gaussian noise.

use cohort_runtime::model::PlantModel;
use rand::Rng;
use rand_chacha::ChaCha8Rng;
use rand_distr::StandardNormal;

pub struct DoubleIntegrator {
    r_m: Vec<[f64; 3]>,
    v_mps: Vec<[f64; 3]>,
    u_mps2: Vec<[f64; 3]>,
    noise_std_m: f64,
    /// Desired offset of each agent from the formation centre (for the formation-error metric).
    slots_m: Vec<[f64; 3]>,
    u_peak_mps2: f64,
    dv_total_mps: f64,
}

impl DoubleIntegrator {
    pub fn new(r0_m: Vec<[f64; 3]>, v0_mps: Vec<[f64; 3]>, noise_std_m: f64, slots_m: Vec<[f64; 3]>) -> Self {
        let n = r0_m.len();
        Self {
            r_m: r0_m,
            v_mps: v0_mps,
            u_mps2: vec![[0.0; 3]; n],
            noise_std_m,
            slots_m,
            u_peak_mps2: 0.0,
            dv_total_mps: 0.0,
        }
    }

    /// RMS over agents of the distance from each agent to its slot, the slots placed about the
    /// agents' centroid: zero exactly when the agents form the desired shape (any translation).
    pub fn formation_error_m(&self) -> f64 {
        let n = self.r_m.len() as f64;
        let mut c = [0.0; 3];
        let mut cs = [0.0; 3];
        for (r, s) in self.r_m.iter().zip(&self.slots_m) {
            for a in 0..3 {
                c[a] += r[a] / n;
                cs[a] += s[a] / n;
            }
        }
        let sum: f64 = self
            .r_m
            .iter()
            .zip(&self.slots_m)
            .map(|(r, s)| (0..3).map(|a| ((r[a] - c[a]) - (s[a] - cs[a])).powi(2)).sum::<f64>())
            .sum();
        (sum / n).sqrt()
    }
}

fn norm(x: &[f64; 3]) -> f64 {
    (x[0] * x[0] + x[1] * x[1] + x[2] * x[2]).sqrt()
}

impl PlantModel for DoubleIntegrator {
    fn columns(&self) -> Vec<String> {
        let mut c = vec!["formation_error_m".to_string()];
        for i in 1..=self.r_m.len() {
            for q in ["r", "v", "u"] {
                let unit = match q {
                    "r" => "m",
                    "v" => "mps",
                    _ => "mps2",
                };
                for ax in ["x", "y", "z"] {
                    c.push(format!("a{i}_{q}_{ax}_{unit}"));
                }
            }
        }
        c
    }

    fn readings(&mut self, agent: u32, rng: &mut ChaCha8Rng, out: &mut Vec<f64>) {
        let r = self.r_m[(agent - 1) as usize];
        for x in r {
            let n: f64 = rng.sample(StandardNormal);
            out.push(x + self.noise_std_m * n);
        }
    }

    fn apply_command(&mut self, agent: u32, command: &[f64]) {
        let u = &mut self.u_mps2[(agent - 1) as usize];
        // A short command (which validation of a well-formed scenario never produces) counts as
        // zero on the missing axes rather than reading out of bounds.
        for (a, x) in u.iter_mut().enumerate() {
            *x = command.get(a).copied().unwrap_or(0.0);
        }
    }

    fn advance(&mut self, dt_s: f64) {
        // Exact zero-order-hold solution of r̈ = u over one step.
        for ((r, v), u) in self.r_m.iter_mut().zip(&mut self.v_mps).zip(&self.u_mps2) {
            for a in 0..3 {
                r[a] += v[a] * dt_s + 0.5 * u[a] * dt_s * dt_s;
                v[a] += u[a] * dt_s;
            }
            let un = norm(u);
            self.u_peak_mps2 = self.u_peak_mps2.max(un);
            self.dv_total_mps += un * dt_s;
        }
    }

    fn row(&self, out: &mut Vec<f64>) {
        out.push(self.formation_error_m());
        for ((r, v), u) in self.r_m.iter().zip(&self.v_mps).zip(&self.u_mps2) {
            out.extend_from_slice(r);
            out.extend_from_slice(v);
            out.extend_from_slice(u);
        }
    }

    fn metrics(&self) -> Vec<(String, f64)> {
        vec![
            ("formation_error_final_m".into(), self.formation_error_m()),
            ("u_peak_mps2".into(), self.u_peak_mps2),
            ("dv_total_mps".into(), self.dv_total_mps),
        ]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn constant_command_matches_the_closed_form() {
        let mut p = DoubleIntegrator::new(vec![[1.0, 2.0, 3.0]], vec![[0.5, 0.0, -1.0]], 0.0, vec![[0.0; 3]]);
        p.apply_command(1, &[0.2, -0.1, 0.0]);
        for _ in 0..100 {
            p.advance(0.01);
        }
        let t: f64 = 1.0;
        let want = [1.0 + 0.5 * t + 0.1 * t * t, 2.0 - 0.05 * t * t, 3.0 - t];
        for a in 0..3 {
            assert!((p.r_m[0][a] - want[a]).abs() < 1e-12, "{:?} vs {want:?}", p.r_m[0]);
        }
    }

    #[test]
    fn formation_error_is_zero_on_the_shape_and_translation_invariant() {
        let slots = vec![[1.0, 0.0, 0.0], [-1.0, 0.0, 0.0]];
        let p = DoubleIntegrator::new(vec![[11.0, 5.0, 0.0], [9.0, 5.0, 0.0]], vec![[0.0; 3]; 2], 0.0, slots.clone());
        assert!(p.formation_error_m() < 1e-12);
        let q = DoubleIntegrator::new(vec![[10.0, 5.0, 0.0], [10.0, 5.0, 0.0]], vec![[0.0; 3]; 2], 0.0, slots);
        assert!((q.formation_error_m() - 1.0).abs() < 1e-12);
    }
}
