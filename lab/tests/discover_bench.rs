//! Speed benchmark of the discovery workflow (not a timed test; run it in release):
//! `cargo test --release -p qfa-lab --test discover_bench -- --ignored --nocapture`.
//! A full four-rate, four-position paper log (−60..70 °C, 120-min hold, 3-min dwells) at
//! 10-s rows, written as a lab-format CSV with I/F pulses, read back, and discovered.

use qfa_discover::{discover, Source, Start};
use qfa_sim::synth::{cycling_csv, kt8_1_scale, truth, SynthConfig};
use qfa_thermal::model::{Extensions, SensorLag};

#[test]
#[ignore = "benchmark: run in release"]
fn discover_full_paper_log_speed() {
    let cfg = SynthConfig::paper_full(2021);
    let ext = Extensions { sensor_lag: Some(SensorLag { tau_s: 400.0 }), ..Default::default() };
    let m = truth(kt8_1_scale(), [1.2e-4, 2.5e-6, 1.5e-8], ext);
    let csv = cycling_csv(&cfg, &m, 20.0);
    let rows = csv.lines().count() - 1;
    let dir = std::env::temp_dir().join("qfa-discover-bench");
    let log = dir.join("log.csv");
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(&log, &csv).unwrap();
    let t0 = std::time::Instant::now();
    let ch = Source::read(&log, 60.0).unwrap();
    let t_read = t0.elapsed().as_secs_f64();
    let r = discover(&ch, Start::Paper, &dir.join("out")).unwrap();
    let total = t0.elapsed().as_secs_f64();
    eprintln!("{rows} rows, {} bins: read {t_read:.2} s, total {total:.2} s", ch.channels().n_bins());
    eprintln!("{}", serde_json::to_string_pretty(&r).unwrap());
    assert_eq!(r.effects.iter().map(|e| e.name.as_str()).collect::<Vec<_>>(), ["sensor_lag"]);
}
