//! Helpers of the QFA batch tests: a simulated batch written and calibrated, and the
//! mistakes and faults a unit's log is given (a drifting sensor, programs left out).

#![allow(dead_code)]

use std::path::{Path, PathBuf};

use qfa_batch::fleet::Fleet;
use qfa_batch::input::from_manifest;
use qfa_batch::unit::{UnitOptions, UnitResult};
use qfa_batch::BatchOptions;
use qfa_log::open::ReadFlags;
use qfa_sim::qfa_population::{draw_qfa, write_qfa_manifest, QfaPopulationSpec, QfaPopulationTruth};

/// A fresh folder `name` in the tests' scratch space.
pub fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

/// `spec`'s batch simulated into `dir` and calibrated into `dir/out`.
pub fn run(dir: &Path, spec: &QfaPopulationSpec) -> (QfaPopulationTruth, Vec<UnitResult>, Fleet) {
    let truth = draw_qfa(spec);
    write_qfa_manifest(dir, &truth, 2).unwrap();
    let (results, fleet) = calibrate(dir, "out", 2);
    (truth, results, fleet)
}

/// The manifest in `dir` calibrated into `dir/out` on `threads` threads.
pub fn calibrate(dir: &Path, out: &str, threads: usize) -> (Vec<UnitResult>, Fleet) {
    let units = from_manifest(&dir.join("batch.toml"), &ReadFlags::default()).unwrap();
    let opts = BatchOptions { unit: UnitOptions::default(), threads, shard: None, progress: false };
    let run = qfa_batch::run(&units, &dir.join(out), &opts).unwrap();
    (run.results.into_iter().map(|(_, r)| r).collect(), run.fleet.unwrap())
}

/// Each reading of the cycling log at `path` plus `c_per_h` °C per hour of its runs taken
/// back to back: a sensor that drifts.
pub fn drift_sensor(path: &Path, c_per_h: f64) {
    let mut log = qfa_log::cycling::read_log(path).unwrap();
    let mut start_s = 0.0;
    for run in &mut log.runs {
        for s in &mut run.samples {
            s.temp_c = s.temp_c.map(|t| t + c_per_h * (start_s + s.time_s) / 3600.0);
        }
        start_s += run.samples.last().map_or(0.0, |s| s.time_s);
    }
    qfa_log::cycling::write_log(path, &log).unwrap();
}

/// Keep only the runs of `programs` in the cycling log at `path`: a unit taken off the index
/// head before its other programs ran.
pub fn keep_programs(path: &Path, programs: &[&str]) {
    let mut log = qfa_log::cycling::read_log(path).unwrap();
    log.runs.retain(|r| programs.contains(&r.program.as_str()));
    qfa_log::cycling::write_log(path, &log).unwrap();
}
