//! Navigation benchmark (not a timed test): run with
//! `cargo test --release -p qfa-lab --test nav_bench -- --ignored --nocapture`.
//!
//! * full 2.3 h closure with perfect sensors at 200 Hz (< 1 m asserted);
//! * the whole `navigate` at 200 Hz: calibration, then the flight of all five variants
//!   (the flight's wall time is the ≤ 30 s target), with the report printed.

use std::time::Instant;

use qfa_nav::{run, scenario::Scenario, NavigateArgs};

#[test]
#[ignore = "benchmark: run in release with --ignored"]
fn nav_bench_full_flight_200hz() {
    let sc = Scenario::builtin();
    let t = Instant::now();
    let (p, v) = run::closure(&sc);
    println!(
        "closure, perfect sensors, {:.2} h at {} Hz: max position error {p:.3e} m, max velocity error {v:.3e} m/s ({:.2} s)",
        sc.duration_s() / 3600.0,
        sc.imu_rate_hz,
        t.elapsed().as_secs_f64()
    );
    assert!(p < 1.0);
    let out = std::env::temp_dir().join(format!("qfa-nav-bench-{}", std::process::id()));
    let rep = qfa_nav::navigate(&NavigateArgs { out: out.clone(), ..NavigateArgs::default() }).unwrap();
    println!("{}", qfa_nav::summary(&rep));
    println!(
        "calibration {:.1} s, flight (5 variants, {} steps) {:.1} s",
        rep.meta.runtime_s[0],
        sc.steps(),
        rep.meta.runtime_s[1]
    );
    println!("{}", serde_json::to_string_pretty(&rep).unwrap());
    let _ = std::fs::remove_dir_all(&out);
}
