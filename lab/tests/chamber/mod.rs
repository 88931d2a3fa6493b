//! The simulator's chamber cycle as a static log, for the static-log tests and the
//! selection study: the 0 g run of JB-KT8 #1 under 22 → −20 → 75 → 35 °C at about
//! 2 °C/min (the real tofupilot log's shape), written as a static TSV and read back through
//! the lab's static reader.

use qfa_log::static_log::{read_static_from, AccelUnit, StaticLog, StaticOptions, TimeUnit};
use qfa_sim::profile::{Position, Program};
use qfa_sim::simulate_run;
use qfa_sim::truth::Truth;

/// The 0 g run of JB-KT8 #1 (with `effect`) under the chamber cycle, as a static log.
pub fn chamber_log(effect: Option<&str>, seed: u64) -> StaticLog {
    let mut truth = Truth::jb_kt8(1);
    if let Some(e) = effect {
        truth = truth.with_effect(e).unwrap();
    }
    let min = 60.0;
    let program = Program {
        id: "chamber".into(),
        points: vec![(0.0, 22.0), (21.0 * min, -20.0), (68.5 * min, 75.0), (88.5 * min, 35.0), (100.0 * min, 35.0)],
    };
    let run = simulate_run(&truth, &program, Position { run: 1, input_g: 0.0 }, 1, seed);
    let gamma = f64::from(truth.scale.gamma);
    let mut text = String::from("time_s\ttemp_c\taz\n");
    for s in &run.samples {
        if let Some(t) = s.temp_c {
            text.push_str(&format!("{}\t{t}\t{:.12}\n", s.time_s, s.pulses as f64 / (s.interval_s * gamma)));
        }
    }
    let opts = StaticOptions { time_unit: Some(TimeUnit::S), accel_unit: Some(AccelUnit::G), ..Default::default() };
    read_static_from(text.as_bytes(), &opts).unwrap()
}
