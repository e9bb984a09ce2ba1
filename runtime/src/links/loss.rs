//! How likely a share in view is lost, by the `[links.loss]` law.
//!
//! The budget law is the textbook one (Wertz & Larson, *Space Mission Analysis and Design*,
//! ch. 13): received power from the Friis equation, Pr = Pt·Gt·Gr·(λ/4πd)²; Eb/N0 = Pr/(k·T·R);
//! the bit error rate of coherent BPSK, ½·erfc(√(Eb/N0)), after a coding gain chosen so that the
//! configured `required_ebn0_db` gives a bit error rate of 1e-5 (uncoded BPSK needs 9.59 dB for
//! that); a share is lost when any of its bits is wrong, 1 − (1 − BER)^bits.

use cohort_scenario::links::{C_MPS, Loss};

/// Boltzmann's constant, J/K.
const K_BOLTZMANN: f64 = 1.380_649e-23;
/// Eb/N0 uncoded BPSK needs for a bit error rate of 1e-5, dB.
const BPSK_EBN0_AT_1E5_DB: f64 = 9.59;

/// The loss probability of a share of `bits` bits over `range_m`, at `rate_bps` (the budget's).
pub fn probability(loss: &Loss, range_m: f64, bits: f64, rate_bps: f64) -> f64 {
    match loss {
        Loss::Constant { p } => *p,
        Loss::Table { range_m: r, p } => table(r, p, range_m),
        Loss::Budget { tx_power_w, tx_gain_dbi, rx_gain_dbi, frequency_hz, noise_temperature_k, required_ebn0_db } => {
            let lambda_m = C_MPS / frequency_hz;
            let gains = 10f64.powf((tx_gain_dbi + rx_gain_dbi) / 10.0);
            let free_space = (lambda_m / (4.0 * std::f64::consts::PI * range_m.max(1e-3))).powi(2);
            let ebn0 = tx_power_w * gains * free_space / (K_BOLTZMANN * noise_temperature_k * rate_bps);
            let coding_gain = 10f64.powf((BPSK_EBN0_AT_1E5_DB - required_ebn0_db) / 10.0);
            let ber = 0.5 * libm::erfc((ebn0 * coding_gain).sqrt());
            // 1 − (1 − BER)^bits without losing a tiny BER to rounding.
            -(bits.max(1.0) * (-ber).ln_1p()).exp_m1()
        }
    }
}

/// Linear interpolation in a range table, held beyond its ends.
fn table(r: &[f64], p: &[f64], x: f64) -> f64 {
    match r.iter().position(|&ri| ri >= x) {
        None => *p.last().unwrap_or(&0.0),
        Some(0) => p[0],
        Some(i) => p[i - 1] + (p[i] - p[i - 1]) * (x - r[i - 1]) / (r[i] - r[i - 1]),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn budget(required_ebn0_db: f64) -> Loss {
        Loss::Budget {
            tx_power_w: 1.0,
            tx_gain_dbi: 0.0,
            rx_gain_dbi: 0.0,
            frequency_hz: 2.2e9,
            noise_temperature_k: 290.0,
            required_ebn0_db,
        }
    }

    #[test]
    fn a_table_interpolates_and_holds_its_ends() {
        let l = Loss::Table { range_m: vec![1e3, 3e3], p: vec![0.0, 0.5] };
        assert_eq!(probability(&l, 10.0, 1.0, 1.0), 0.0);
        assert_eq!(probability(&l, 2e3, 1.0, 1.0), 0.25);
        assert_eq!(probability(&l, 1e6, 1.0, 1.0), 0.5);
    }

    #[test]
    fn the_budget_gives_1e5_per_bit_where_eb_n0_meets_the_requirement() {
        // Find the range where Eb/N0 equals the requirement, by hand: Pr/(kTR) = 10^(req/10).
        let (req_db, rate) = (4.0, 1e5);
        let lambda = C_MPS / 2.2e9;
        let ebn0 = 10f64.powf(req_db / 10.0);
        let pr = ebn0 * K_BOLTZMANN * 290.0 * rate;
        let d = lambda / (4.0 * std::f64::consts::PI) / pr.sqrt();
        let p_bit = probability(&budget(req_db), d, 1.0, rate);
        assert!((p_bit / 1e-5 - 1.0).abs() < 0.02, "{p_bit}");
        // Farther is worse, nearer better; a 1000-bit share is lost ≈ 1000 times as often.
        assert!(probability(&budget(req_db), 2.0 * d, 1.0, rate) > 1e-3);
        assert!(probability(&budget(req_db), 0.5 * d, 1.0, rate) < 1e-9);
        let p_share = probability(&budget(req_db), d, 1000.0, rate);
        assert!((p_share / (1000.0 * p_bit) - 1.0).abs() < 0.01, "{p_share}");
    }
}
