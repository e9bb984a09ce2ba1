//! `cargo run --release -p cohort-paper-nr --example nr_backward -- WEIGHTS`: how well the two backward passes of `desired` agree with the policy along x_d: the residual
//! ‖u_ℓ(x_d(t_j)) − u_d(j)‖ per node, for a desired trajectory built at t_s.
use cohort_paper_nr::iso::dynamics::constants::{ISO_SET_SEED, T_F_S};
use cohort_paper_nr::iso::dynamics::iso_set;
use cohort_paper_nr::iso::dynamics::lvlh::IsoFrame;
use cohort_paper_nr::iso::dynamics::navigation::{NavSigmas, draw};
use cohort_paper_nr::iso::dynamics::two_body::V3;
use cohort_paper_nr::iso::guidance::desired::{self, Backward};
use cohort_paper_nr::iso::guidance::features::features;
use cohort_paper_nr::iso::guidance::scp::ScpInput;
use cohort_paper_nr::nn::sn_dnn::SnDnn;
use rand::SeedableRng;

fn main() {
    let path = std::env::args().nth(1).unwrap();
    let net = SnDnn::load(std::path::Path::new(&path)).unwrap();
    let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(1);
    for iso_i in [3u32, 7, 11] {
        let ideal = iso_set::ideal(ISO_SET_SEED, iso_i, 0, T_F_S, 100e3);
        let (iso, sc) = ideal.at(64_800.0);
        let s = NavSigmas::default().at(64_800.0, T_F_S, 1.0);
        let (iso, sc) = (draw(&iso, &s, &mut rng), draw(&sc, &s, &mut rng));
        let inp = ScpInput {
            x0: IsoFrame::of(&iso).relative(&sc),
            iso0: iso,
            m0_kg: 500.0,
            t0_s: 64_800.0,
            t_f_s: T_F_S,
            dt_s: 600.0,
            rho_f_m: ideal.rho_f_m,
            u_max_n: 1.0,
            isp_s: 220.0,
        };
        let pol = |x: &cohort_paper_nr::iso::dynamics::lvlh::X6,
                   iso: &cohort_paper_nr::iso::dynamics::two_body::Inertial,
                   t: f64| {
            let mut u = [0.0; 3];
            net.forward(&features(x, iso, t, T_F_S, &ideal.rho_f_m), &mut u);
            V3::from(u)
        };
        for b in [Backward::Replay, Backward::Policy] {
            let d = desired::build(&inp, b, &mut |x, i, t| pol(x, i, t));
            let res: Vec<f64> =
                (0..36).map(|j| (pol(&d.x[j], &d.iso[j], d.t0_s + j as f64 * 600.0) - d.u_n[j]).norm()).collect();
            let shift = (d.x[0] - inp.x0).fixed_rows::<3>(0).norm();
            println!(
                "ISO {iso_i} {b:?}: |x_d(t_s) − x̂| = {shift:.1} m; residual ‖u_ℓ(x_d) − u_d‖ (mN) at nodes 0, 18, 33, 34, 35: {:.3} {:.3} {:.3} {:.3} {:.3}",
                res[0] * 1e3,
                res[18] * 1e3,
                res[33] * 1e3,
                res[34] * 1e3,
                res[35] * 1e3
            );
        }
    }
}
