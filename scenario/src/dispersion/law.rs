//! The distributions a dispersion draws from, each as its quantile function: a draw is
//! `quantile(u)` of one uniform `u` in (0, 1). One uniform per drawn number keeps a case's draws a
//! fixed function of its random stream (the same in any worker), and makes correlation groups a
//! Gaussian copula: correlated normals mapped through Φ to uniforms, then through each member's
//! own quantile function (so every member keeps its own marginal distribution).

use statrs::function::erf::{erfc, erfc_inv};

/// One scalar's distribution (a vector key has one per component).
#[derive(Debug, Clone, PartialEq)]
pub enum Law {
    Normal {
        mean: f64,
        sigma: f64,
    },
    /// A normal restricted to `[low, high]` (by inverting its CDF there, no rejection).
    TruncatedNormal {
        mean: f64,
        sigma: f64,
        low: f64,
        high: f64,
    },
    Uniform {
        low: f64,
        high: f64,
    },
    LogUniform {
        low: f64,
        high: f64,
    },
    /// Whole numbers `low..=high`, each equally likely.
    UniformInt {
        low: i64,
        high: i64,
    },
    /// One of `values`, with probabilities `weights` (cumulated, last = 1).
    Choice {
        values: Vec<toml::Value>,
        cumulative: Vec<f64>,
    },
}

/// Standard normal CDF Φ.
pub fn phi(x: f64) -> f64 {
    0.5 * erfc(-x / std::f64::consts::SQRT_2)
}

/// Standard normal quantile Φ⁻¹, `p` in (0, 1).
pub fn phi_inv(p: f64) -> f64 {
    -std::f64::consts::SQRT_2 * erfc_inv(2.0 * p)
}

impl Law {
    /// The value of quantile `u` (0 < u < 1).
    pub fn quantile(&self, u: f64) -> toml::Value {
        use toml::Value::{Float, Integer};
        match self {
            Law::Normal { mean, sigma } => Float(mean + sigma * phi_inv(u)),
            Law::TruncatedNormal { mean, sigma, low, high } => {
                let (a, b) = (phi((low - mean) / sigma), phi((high - mean) / sigma));
                Float((mean + sigma * phi_inv(a + u * (b - a))).clamp(*low, *high))
            }
            Law::Uniform { low, high } => Float(low + u * (high - low)),
            Law::LogUniform { low, high } => Float((low.ln() + u * (high / low).ln()).exp().clamp(*low, *high)),
            Law::UniformInt { low, high } => {
                let n = (high - low) as f64 + 1.0;
                Integer(low + ((u * n).floor() as i64).min(high - low))
            }
            Law::Choice { values, cumulative } => {
                let k = cumulative.iter().position(|&c| u < c).unwrap_or(values.len() - 1);
                values[k].clone()
            }
        }
    }

    /// The probability a truncated normal keeps (Φ(b) − Φ(a)); 1 for the others.
    pub fn kept_mass(&self) -> f64 {
        match self {
            Law::TruncatedNormal { mean, sigma, low, high } => phi((high - mean) / sigma) - phi((low - mean) / sigma),
            _ => 1.0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn quantiles_match_the_closed_forms() {
        // statrs' erfc is good to ≈ 1e-12 here, plenty for drawing.
        assert!((phi(1.959963984540054) - 0.975).abs() < 1e-11);
        assert!((phi_inv(0.975) - 1.959963984540054).abs() < 1e-12);
        assert!((phi_inv(phi(-6.0)) + 6.0).abs() < 1e-9);
        let f = |l: Law, u: f64| l.quantile(u).as_float().unwrap();
        assert_eq!(f(Law::Uniform { low: 2.0, high: 4.0 }, 0.25), 2.5);
        assert!((f(Law::LogUniform { low: 1.0, high: 100.0 }, 0.5) - 10.0).abs() < 1e-12);
        assert!((f(Law::Normal { mean: 1.0, sigma: 2.0 }, 0.975) - (1.0 + 2.0 * 1.959963984540054)).abs() < 1e-12);
        let t = Law::TruncatedNormal { mean: 0.0, sigma: 1.0, low: 0.0, high: 10.0 };
        // The half-normal's median is Φ⁻¹(0.75).
        assert!((f(t.clone(), 0.5) - phi_inv(0.75)).abs() < 1e-12);
        assert!((t.kept_mass() - 0.5).abs() < 1e-12);
        let i = Law::UniformInt { low: -1, high: 1 };
        let ints: Vec<i64> = [0.01, 0.34, 0.99].iter().map(|&u| i.quantile(u).as_integer().unwrap()).collect();
        assert_eq!(ints, [-1, 0, 1]);
        let c = Law::Choice { values: vec!["a".into(), "b".into()], cumulative: vec![0.25, 1.0] };
        assert_eq!((c.quantile(0.2), c.quantile(0.3)), ("a".into(), "b".into()));
    }
}
