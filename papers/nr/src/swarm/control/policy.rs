//! The swarm's learned distributed policy (Sec. 7.2 of "Neural-Rendezvous", arXiv:2208.04883):
//! a deep set over the local observation ([`SwarmObservation`], after GLAS, the paper's [42]),
//!
//!   u = a_max · tanh-net ρ([g − p, v, τ, Σⱼ φ(Δpⱼ, Δvⱼ)]),
//!
//! with φ summed over the observed neighbours (≤ 6 within R_comm; none gives the zero sum) and
//! both φ and ρ spectrally normalised SN-DNNs ([`SnDnn`]: W_l = C_sn Ω_l/‖Ω_l‖₂, tanh after every
//! layer). The sum makes the policy independent of the neighbours' order. Lipschitz: C_sn^L_ρ
//! from ρ's normalised input, so ≤ C_sn^L_ρ (1 + 6 C_sn^L_φ) from the normalised observation.
//!
//! Ours (the paper's architecture is lost): φ 6 → 32 → 32, ρ 39 → 64 → 64 → 3, C_sn = 2;
//! inputs divided by fixed scales (not training maxima, so the normalisation does not depend on
//! the data): Δp / [`DP_SCALE_M`], Δv / [`DV_SCALE_MPS`], g − p / [`GOAL_SCALE_M`],
//! v / [`V_SCALE_MPS`], τ / [`TAU_SCALE_S`], Σφ / 1; output × a_max = 2 m/s² (tanh keeps it in the
//! box).
//!
//! Departure: τ = max(T − t, 0), the time to the reconfiguration time, is an input (GLAS's policy
//! and the reference's ρ([g − p, v, Σφ]) see no time). The global solutions the policy imitates
//! are plans that end at T, so their commands depend on the time left; without τ the policy
//! averages over it, and a vehicle that a conflict (or the safety filter) delayed does not make
//! the time up. Measured: with the safety filter, every vehicle within 0.1 m at T + 2 s in 22 of
//! the campaign's 30 cases without τ, 30 of 30 with it (papers/nr/README.md).
//!
//! **Weights file** (ONE safetensors file): the tensors of the two networks in the layout of
//! [`crate::nn::sn_dnn`], prefixed `phi.` and `rho.`: `phi.layers.<l>.weight` ([out, in], F64, the
//! normalised W_l), `phi.layers.<l>.bias`, `phi.input_scale`, `phi.output_scale` (all ones), and
//! the same under `rho.` (`rho.output_scale` = a_max); one metadata entry [`METADATA_KEY`]
//! holding a JSON object with `format` = [`FORMAT`], `c_sn`, and the training's description.
//! Loading checks every shape, every number, each network's layer chain and ‖W_l‖₂ ≤ C_sn
//! ([`SnDnn::new`]), and the chain between them (φ takes 6, ρ takes 7 + φ's outputs and gives
//! 3); any failure is a [`WeightsError`] naming the file, the tensor and the reason.

use std::path::Path;

use cohort_runtime::weights;

use crate::nn::sn_dnn::{SnDnn, WeightsError, open, push_tensors, read_net, serialise};
use crate::swarm::control::obs::{Neighbour, SwarmObservation, SwarmPolicy};
use crate::swarm::dynamics::setup::A_MAX_MPS2;

/// The model name of its weights errors.
pub const MODEL: &str = "swarm deep-set policy";
/// The one metadata key of a swarm-policy file.
pub const METADATA_KEY: &str = "cohort_swarm_policy";
/// Value of the metadata's `format`.
pub const FORMAT: &str = "cohort-swarm-deep-set-v2";
/// Scale of a neighbour's relative position, m.
pub const DP_SCALE_M: f64 = 0.5;
/// Scale of a neighbour's relative velocity, m/s.
pub const DV_SCALE_MPS: f64 = 1.0;
/// Scale of the goal offset, m.
pub const GOAL_SCALE_M: f64 = 1.0;
/// Scale of the own velocity, m/s.
pub const V_SCALE_MPS: f64 = 1.0;
/// Scale of the time to go, s (T).
pub const TAU_SCALE_S: f64 = 8.0;
/// Inputs of φ and of ρ's own part.
pub const PHI_IN: usize = 6;
pub const OWN_IN: usize = 7;

/// φ's raw input for one neighbour: [Δp, Δv].
pub fn phi_input(n: &Neighbour) -> [f64; PHI_IN] {
    [n.dp_m[0], n.dp_m[1], n.dp_m[2], n.dv_mps[0], n.dv_mps[1], n.dv_mps[2]]
}

/// ρ's raw own input: [g − p, v, time to go].
pub fn own_input(obs: &SwarmObservation) -> [f64; OWN_IN] {
    let (g, v) = (obs.goal_offset_m, obs.v_mps);
    [g[0], g[1], g[2], v[0], v[1], v[2], obs.t_to_go_s]
}

/// φ's input scales.
pub fn phi_scales() -> Vec<f64> {
    vec![DP_SCALE_M, DP_SCALE_M, DP_SCALE_M, DV_SCALE_MPS, DV_SCALE_MPS, DV_SCALE_MPS]
}

/// ρ's input scales for φ with `phi_out` outputs.
pub fn rho_scales(phi_out: usize) -> Vec<f64> {
    let mut s = vec![GOAL_SCALE_M, GOAL_SCALE_M, GOAL_SCALE_M, V_SCALE_MPS, V_SCALE_MPS, V_SCALE_MPS, TAU_SCALE_S];
    s.extend(std::iter::repeat_n(1.0, phi_out));
    s
}

/// The learned policy: φ and ρ, checked.
#[derive(Debug, Clone, PartialEq)]
pub struct DeepSetPolicy {
    phi: SnDnn,
    rho: SnDnn,
    metadata: serde_json::Value,
}

impl DeepSetPolicy {
    /// Check the chain between the two networks; the reason names what is wrong.
    pub fn new(phi: SnDnn, rho: SnDnn, metadata: serde_json::Value) -> Result<Self, String> {
        if phi.n_in() != PHI_IN {
            return Err(format!("phi takes {} inputs, expected {PHI_IN} (Δp, Δv)", phi.n_in()));
        }
        if rho.n_in() != OWN_IN + phi.n_out() {
            return Err(format!(
                "rho takes {} inputs, expected {OWN_IN} (g − p, v, time to go) + phi's {} outputs",
                rho.n_in(),
                phi.n_out()
            ));
        }
        if rho.n_out() != 3 {
            return Err(format!("rho gives {} outputs, expected 3 (the acceleration)", rho.n_out()));
        }
        if phi.c_sn() != rho.c_sn() {
            return Err(format!("phi's C_sn {} differs from rho's {}", phi.c_sn(), rho.c_sn()));
        }
        Ok(Self { phi, rho, metadata })
    }

    pub fn phi(&self) -> &SnDnn {
        &self.phi
    }
    pub fn rho(&self) -> &SnDnn {
        &self.rho
    }
    pub fn metadata(&self) -> &serde_json::Value {
        &self.metadata
    }

    /// The weights file's bytes (deterministic: one metadata key).
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut tensors = Vec::new();
        push_tensors(&self.phi, "phi.", &mut tensors);
        push_tensors(&self.rho, "rho.", &mut tensors);
        serialise(MODEL, &tensors, METADATA_KEY, FORMAT, &self.metadata, self.phi.c_sn())
    }

    /// Read and check a weights file.
    pub fn load(path: &Path) -> Result<Self, WeightsError> {
        Self::from_bytes(&weights::read(MODEL, path)?, path)
    }

    /// Check and load a weights file's bytes; `file` only names it in errors.
    pub fn from_bytes(bytes: &[u8], file: &Path) -> Result<Self, WeightsError> {
        let (st, metadata, c_sn) = open(MODEL, bytes, file, METADATA_KEY, FORMAT, "a swarm-policy")?;
        let phi = read_net(&st, "phi.", c_sn)?;
        let rho = read_net(&st, "rho.", c_sn)?;
        Self::new(phi, rho, metadata).map_err(|e| st.invalid(e))
    }

    /// Σⱼ φ over the observed neighbours (normalised φ outputs; zero without neighbours).
    fn phi_sum(&self, obs: &SwarmObservation, out: &mut [f64]) {
        out.iter_mut().for_each(|x| *x = 0.0);
        let mut y = vec![0.0; self.phi.n_out()];
        for n in obs.observed() {
            self.phi.forward(&phi_input(n), &mut y);
            out.iter_mut().zip(&y).for_each(|(o, v)| *o += v);
        }
    }
}

impl SwarmPolicy for DeepSetPolicy {
    fn accel_mps2(&self, obs: &SwarmObservation) -> [f64; 3] {
        let mut input = vec![0.0; self.rho.n_in()];
        input[..OWN_IN].copy_from_slice(&own_input(obs));
        self.phi_sum(obs, &mut input[OWN_IN..]);
        let mut u = [0.0; 3];
        self.rho.forward(&input, &mut u);
        u.map(|x| x.clamp(-A_MAX_MPS2, A_MAX_MPS2))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::nn::sn_dnn::tests::random_net_scaled;
    use crate::swarm::dynamics::setup::R_COMM_M;
    use candle_core::{Device, Tensor};
    use rand::{Rng, SeedableRng};
    use rand_chacha::ChaCha8Rng;
    use safetensors::SafeTensors;
    use safetensors::tensor::TensorView;

    /// A random policy of the reference sizes.
    pub(crate) fn random_policy(seed: u64) -> DeepSetPolicy {
        let phi = random_net_scaled(&[6, 32, 32], 2.0, seed, phi_scales(), vec![1.0; 32]);
        let rho = random_net_scaled(&[39, 64, 64, 3], 2.0, seed + 1, rho_scales(32), vec![A_MAX_MPS2; 3]);
        DeepSetPolicy::new(phi, rho, serde_json::json!({})).unwrap()
    }

    /// Random observations with 0…6 neighbours.
    pub(crate) fn observations(seed: u64, count: usize) -> Vec<SwarmObservation> {
        let mut rng = ChaCha8Rng::seed_from_u64(seed);
        (0..count)
            .map(|c| {
                let mut r3 = |s: f64| -> [f64; 3] { std::array::from_fn(|_| rng.random_range(-s..s)) };
                let (p, v, g) = (r3(1.0), r3(0.5), r3(2.0));
                // Offsets within ±0.5 m per axis: all within R_comm, so c % 9 others, ≤ 6 observed.
                let others: Vec<_> = (0..c % 9)
                    .map(|_| {
                        let d = r3(0.5);
                        (std::array::from_fn(|k| p[k] + d[k]), r3(0.5))
                    })
                    .collect();
                // Times to go across 0…8 s (and past T, clamped to 0).
                SwarmObservation::local(p, v, g, &others, R_COMM_M).at(8.5 - 0.35 * c as f64)
            })
            .collect()
    }

    /// The policy evaluated by candle (f64 tensors): φ on a padded (B·6, 6) batch, masked sum.
    fn candle_policy(p: &DeepSetPolicy, obs: &[SwarmObservation]) -> Vec<[f64; 3]> {
        let dev = Device::Cpu;
        let net = |n: &SnDnn, z: Tensor| -> Tensor {
            let mut h = z;
            for l in n.layers() {
                let w = Tensor::from_vec(l.w.clone(), (l.n_out, l.n_in), &dev).unwrap();
                let b = Tensor::from_vec(l.b.clone(), l.n_out, &dev).unwrap();
                h = h.matmul(&w.t().unwrap()).unwrap().broadcast_add(&b).unwrap().tanh().unwrap();
            }
            h
        };
        let b = obs.len();
        let (mut nb, mut mask, mut own) = (Vec::new(), Vec::new(), Vec::new());
        for o in obs {
            for s in 0..6 {
                nb.extend(phi_input(&o.neighbours[s]).iter().zip(phi_scales()).map(|(x, k)| x / k));
                mask.push(if s < o.n_neighbours { 1.0 } else { 0.0 });
            }
            own.extend(own_input(o).iter().zip(rho_scales(0)).map(|(x, k)| x / k));
        }
        let f = net(p.phi(), Tensor::from_vec(nb, (b * 6, 6), &dev).unwrap()).reshape((b, 6, 32)).unwrap();
        let m = Tensor::from_vec(mask, (b, 6, 1), &dev).unwrap();
        let sum = f.broadcast_mul(&m).unwrap().sum(1).unwrap();
        let own = Tensor::from_vec(own, (b, OWN_IN), &dev).unwrap();
        let y = net(p.rho(), Tensor::cat(&[&own, &sum], 1).unwrap());
        let y: Vec<Vec<f64>> = y.to_vec2().unwrap();
        y.iter().map(|r| std::array::from_fn(|k| r[k] * A_MAX_MPS2)).collect()
    }

    #[test]
    fn the_f64_forward_pass_matches_candle_and_ignores_the_neighbours_order() {
        let p = random_policy(3);
        let obs = observations(4, 27);
        let theirs = candle_policy(&p, &obs);
        for (o, t) in obs.iter().zip(&theirs) {
            let mine = p.accel_mps2(o);
            for k in 0..3 {
                assert!((mine[k] - t[k]).abs() < 1e-12, "{mine:?} vs candle {t:?}");
                assert!(mine[k].abs() <= A_MAX_MPS2);
            }
            let mut rev = *o;
            rev.neighbours[..o.n_neighbours].reverse();
            let back = p.accel_mps2(&rev);
            assert!((0..3).all(|k| (back[k] - mine[k]).abs() < 1e-12), "order matters: {back:?} vs {mine:?}");
        }
        assert!(obs.iter().any(|o| o.n_neighbours == 0) && obs.iter().any(|o| o.n_neighbours == 6));
    }

    #[test]
    fn the_file_round_trips_exactly() {
        let p = random_policy(5);
        let bytes = p.to_bytes();
        assert_eq!(bytes, p.to_bytes());
        let back = DeepSetPolicy::from_bytes(&bytes, Path::new("w.safetensors")).unwrap();
        assert_eq!((back.phi(), back.rho()), (p.phi(), p.rho()));
        for o in observations(6, 9) {
            assert_eq!(back.accel_mps2(&o), p.accel_mps2(&o));
        }
    }

    #[test]
    fn a_missing_or_malformed_file_is_an_error_naming_the_file_and_the_reason() {
        let dir = std::env::temp_dir().join(format!("nr-swarm-weights-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let err = |path: &Path| DeepSetPolicy::load(path).unwrap_err().to_string();
        let e = err(&dir.join("missing.safetensors"));
        assert!(e.contains("missing.safetensors") && e.contains("cannot read"), "{e}");
        std::fs::write(dir.join("junk.safetensors"), b"not a weights file").unwrap();
        let e = err(&dir.join("junk.safetensors"));
        assert!(e.contains("junk.safetensors") && e.contains("not a safetensors file"), "{e}");
        // An ISO SN-DNN file is a safetensors file, but not a swarm policy.
        let iso = crate::nn::sn_dnn::tests::random_net(&[4, 8, 3], 2.0, 1).to_bytes();
        let e = DeepSetPolicy::from_bytes(&iso, Path::new("iso.safetensors")).unwrap_err().to_string();
        assert!(e.contains("iso.safetensors") && e.contains(METADATA_KEY), "{e}");
        // A broken chain: ρ built for φ with 16 outputs.
        let phi = random_net_scaled(&[6, 32, 32], 2.0, 1, phi_scales(), vec![1.0; 32]);
        let rho = random_net_scaled(&[23, 64, 3], 2.0, 2, rho_scales(16), vec![A_MAX_MPS2; 3]);
        let bad = DeepSetPolicy { phi: phi.clone(), rho, metadata: serde_json::json!({}) }.to_bytes();
        let e = DeepSetPolicy::from_bytes(&bad, Path::new("chain.safetensors")).unwrap_err().to_string();
        assert!(e.contains("chain.safetensors") && e.contains("rho takes 23 inputs"), "{e}");
        // A layer that breaks the normalisation; a missing tensor.
        let mut p = random_policy(2);
        let mut layers = p.rho.layers().to_vec();
        layers[1].w.iter_mut().for_each(|w| *w *= 3.0);
        p.rho = SnDnn::new(layers, rho_scales(32), vec![2.0; 3], 7.0, serde_json::json!({})).unwrap();
        let e = DeepSetPolicy::from_bytes(&p.to_bytes(), Path::new("big.safetensors")).unwrap_err().to_string();
        assert!(e.contains("big.safetensors") && e.contains("rho: layer 1") && e.contains("exceeds C_sn"), "{e}");
        let good = random_policy(2).to_bytes();
        let st = SafeTensors::deserialize(&good).unwrap();
        let kept: Vec<(String, TensorView<'_>)> =
            st.tensors().into_iter().filter(|(n, _)| n != "phi.input_scale").collect();
        let (_, header) = SafeTensors::read_metadata(&good).unwrap();
        let cut = safetensors::serialize(kept, header.metadata().clone()).unwrap();
        let e = DeepSetPolicy::from_bytes(&cut, Path::new("cut.safetensors")).unwrap_err().to_string();
        assert!(e.contains("cut.safetensors") && e.contains("\"phi.input_scale\" is missing"), "{e}");
        let _ = std::fs::remove_dir_all(&dir);
    }
}
