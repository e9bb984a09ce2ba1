//! Building and validating messages: what every send and every receive costs besides transport.

use std::hint::black_box;

use cohort_wire::msg::{Header, Measurement, Share};
use cohort_wire::validate::{Expect, validate_measurement, validate_share};
use criterion::{Criterion, criterion_group, criterion_main};

fn messages(c: &mut Criterion) {
    let values: Vec<f64> = (0..106).map(|i| i as f64 * 0.25).collect();
    let command = [0.1, -0.2, 0.3];
    c.bench_function("Share::new (3 + 106 values)", |b| {
        b.iter(|| Share::new(Header::new(7, 3, 100, 1.0), black_box(&command), black_box(&values)))
    });
    let share = Share::new(Header::new(7, 3, 100, 1.0), &command, &values);
    let e = Expect { run_id: 7, sender: 3, step_min: 100, step_max: 101, key: None };
    c.bench_function("validate_share (3 + 106 values)", |b| b.iter(|| validate_share(black_box(&share), &e)));
    let readings = [1.0; 9];
    let m = Measurement::new(Header::new(7, 0, 100, 1.0), &readings);
    let e0 = Expect { run_id: 7, sender: 0, step_min: 100, step_max: 100, key: None };
    c.bench_function("Measurement::new + validate (9 readings)", |b| {
        b.iter(|| {
            let m2 = Measurement::new(Header::new(7, 0, 100, 1.0), black_box(&readings));
            validate_measurement(&m2, &e0)
        })
    });
    let _ = m;
}

criterion_group!(benches, messages);
criterion_main!(benches);
