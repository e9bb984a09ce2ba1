//! `cargo run --release -p cohort-paper-nr --example nr_profile -- WEIGHTS`: micro-timings of the NR
//! agent's pieces (input transform, SN-DNN forward pass, desired-trajectory build at t_s).
use std::time::Instant;

use cohort_paper_nr::constants::{ISO_SET_SEED, T_F_S};
use cohort_paper_nr::desired;
use cohort_paper_nr::features::features;
use cohort_paper_nr::iso_set;
use cohort_paper_nr::lvlh::IsoFrame;
use cohort_paper_nr::scp::ScpInput;
use cohort_paper_nr::sn_dnn::SnDnn;
use cohort_paper_nr::two_body::V3;

fn main() {
    let path = std::env::args().nth(1).unwrap_or("papers/nr/weights/sn-dnn.safetensors".into());
    let net = SnDnn::load(std::path::Path::new(&path)).unwrap();
    let ideal = iso_set::ideal(ISO_SET_SEED, 3, 0, T_F_S, 100e3);
    let (iso, sc) = ideal.at(64_800.0);
    let x = IsoFrame::of(&iso).relative(&sc);
    let n = 20_000;
    let t0 = Instant::now();
    let mut acc = 0.0;
    for k in 0..n {
        let f = features(&x, &iso, 64_800.0 + k as f64 * 1e-3, T_F_S, &ideal.rho_f_m);
        acc += f[6];
    }
    let tf = t0.elapsed().as_secs_f64() / n as f64;
    let f = features(&x, &iso, 64_800.0, T_F_S, &ideal.rho_f_m);
    let t0 = Instant::now();
    let mut u = [0.0; 3];
    for _ in 0..n {
        net.forward(&f, &mut u);
        acc += u[0];
    }
    let tn = t0.elapsed().as_secs_f64() / n as f64;
    let inp = ScpInput {
        x0: x,
        iso0: iso,
        m0_kg: 500.0,
        t0_s: 64_800.0,
        t_f_s: T_F_S,
        dt_s: 600.0,
        rho_f_m: ideal.rho_f_m,
        u_max_n: 1.0,
        isp_s: 220.0,
    };
    let t0 = Instant::now();
    let reps = 50;
    for _ in 0..reps {
        let d = desired::build(&inp, desired::Backward::Replay, &mut |x, iso, t| {
            let f = features(x, iso, t, T_F_S, &ideal.rho_f_m);
            let mut u = [0.0; 3];
            net.forward(&f, &mut u);
            V3::from(u)
        });
        acc += d.x[0][0];
    }
    let tb = t0.elapsed().as_secs_f64() / reps as f64;
    println!(
        "features {:.2} µs, forward {:.2} µs, desired build (36 steps) {:.3} ms  [{acc:e}]",
        tf * 1e6,
        tn * 1e6,
        tb * 1e3
    );
}
