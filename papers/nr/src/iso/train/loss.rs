//! The imitation loss (10)–(12) of "Neural-Rendezvous" (arXiv:2208.04883) on a mini-batch:
//!
//!   L = mean ‖u_ℓ − u_mpc‖²_{C_u}  +  mean ‖φ_ℓ(t+Δτ) − φ_mpc(t+Δτ)‖²_{C_x},
//!
//! C_u = I on the normalised command (u / training max|uᵢ|), C_x = γI on the scaled state
//! (position / ½a_sΔτ², velocity / a_sΔτ, a_s = max|uᵢ|/m₀: the state change one unit of
//! normalised command makes over Δτ — ours, so that γ weighs terms of one size). The SN-DNN's
//! closed loop is rolled through the linearised dynamics about the MPC plan, as deviations δx
//! (kept in f32 without the 10⁹ m states): δx₀ = 0, z_j = z_mpc,j + F̃_j δx_j,
//! δx_{j+1} = Ã_j δx_j + B̃_j (u_ℓ(z_j) − u_mpc,j), differentiated through every step.

use candle_core::{D, Tensor};

use crate::nn::sn_mlp::SnMlp;

/// One batch on the device (all f32, scaled): control samples and state samples.
pub struct Batch {
    /// (B, n_in) normalised inputs and (B, 3) normalised MPC commands.
    pub z0: Tensor,
    pub y0: Tensor,
    /// State samples, per node j: (B', n_in), (B', 6, n_in) = F̃ᵀ, (B', 6, 6) = Ãᵀ, (B', 3, 6) = B̃ᵀ,
    /// (B', 3) normalised MPC commands.
    pub z: Vec<Tensor>,
    pub ft: Vec<Tensor>,
    pub at: Vec<Tensor>,
    pub bt: Vec<Tensor>,
    pub y: Vec<Tensor>,
}

/// (control term, state term) of the batch with the weights `ws`.
pub fn terms(net: &SnMlp, ws: &[Tensor], b: &Batch) -> candle_core::Result<(Tensor, Tensor)> {
    let n0 = b.z0.dims2()?.0 as f64;
    let lu = ((net.forward(ws, &b.z0)? - &b.y0)?.sqr()?.sum_all()? / n0)?;
    let ns = b.z.first().map(|z| z.dims2().map(|d| d.0)).transpose()?.unwrap_or(0);
    if ns == 0 {
        return Ok((lu.clone(), (lu * 0.0)?));
    }
    let mut dx = Tensor::zeros((ns, 1, 6), candle_core::DType::F32, b.z0.device())?;
    for j in 0..b.z.len() {
        let zj = (&b.z[j] + dx.matmul(&b.ft[j])?.squeeze(1)?)?;
        let du = (net.forward(ws, &zj)? - &b.y[j])?.unsqueeze(1)?;
        dx = (dx.matmul(&b.at[j])? + du.matmul(&b.bt[j])?)?;
    }
    let lx = (dx.sqr()?.sum(D::Minus1)?.sum_all()? / ns as f64)?;
    Ok((lu, lx))
}
