//! Static-log compensation speed, the Rust side of the Python package's benchmark (not a
//! timed test): run with
//! `cargo test --release -p qfa-lab --test compensate_bench -- --ignored --nocapture`.
//!
//! [`qfa_calibrate::compensate::compensate_samples`] on the rows `python/bench/bench_compensate.py`
//! builds (1 000 000 rows, three axes, the same closed-form columns, bit for bit) with the
//! table it loads (`python/bench/bench_table.toml`); prints `key=value` lines, the best of
//! five runs after a warm-up, and a checksum of the outputs that the Python run prints too.

use std::time::Instant;

use qfa_calibrate::compensate::compensate_samples;

/// Rows per run.
const ROWS: usize = 1_000_000;
/// Triangle period of the temperature, rows (5 000 s up and down at 2 Hz).
const PERIOD: usize = 20_000;

/// The benchmark's columns: 2-Hz rows, a ±35 °C triangle about 25 °C, three axes in g.
fn columns() -> (Vec<f64>, Vec<f64>, [Vec<f64>; 3]) {
    let time_s: Vec<f64> = (0..ROWS).map(|i| i as f64 * 0.5).collect();
    let temp_c: Vec<f64> = (0..ROWS)
        .map(|i| {
            let phase = (i % PERIOD) as f64 / PERIOD as f64;
            let tri = if phase < 0.5 { 4.0 * phase - 1.0 } else { 3.0 - 4.0 * phase };
            25.0 + 35.0 * tri
        })
        .collect();
    let ax = temp_c.iter().map(|t| 1e-3 + 2e-5 * (t - 25.0)).collect();
    let ay = vec![-2e-3; ROWS];
    let az = temp_c.iter().map(|t| 1.0 + 3e-5 * (t - 25.0)).collect();
    (time_s, temp_c, [ax, ay, az])
}

#[test]
#[ignore = "benchmark: run in release with --ignored"]
fn compensate_a_million_static_rows() {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../python/bench/bench_table.toml");
    let table: qfa_thermal::Table = toml::from_str(&std::fs::read_to_string(&path).unwrap()).unwrap();
    table.validate().unwrap();
    let (time_s, temp_c, accel) = columns();
    let accel: Vec<&[f64]> = accel.iter().map(Vec::as_slice).collect();
    let mut times = Vec::new();
    let mut checksum = 0.0;
    for run in 0..6 {
        let t = Instant::now();
        let out = compensate_samples(&table, &time_s, &temp_c, &accel).unwrap();
        let s = t.elapsed().as_secs_f64();
        checksum = out.accel_g.iter().flatten().sum::<f64>();
        // The first run warms the caches and the allocator.
        if run > 0 {
            times.push(s);
        }
    }
    times.sort_by(f64::total_cmp);
    println!("rows={ROWS}");
    println!("axes=3");
    println!("rust_best_s={:.4}", times[0]);
    println!("rust_median_s={:.4}", times[times.len() / 2]);
    println!("checksum={checksum:.9e}");
}
