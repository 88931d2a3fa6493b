//! Soak benchmark: `cargo run --release -p host-tests --bin soak -- --hours H [--imu-hz F]
//! [--sensors 1|3]`. Drives the simulated bus, the DS18B20 driver and the split compensator
//! through H hours of simulated time, starting both clocks near their wraps, and prints one
//! `key=value` line per figure (`host_tests::soak`).

use std::process::ExitCode;

use host_tests::soak::{run, Settings};

fn main() -> ExitCode {
    let mut set = Settings::default();
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let v = it.next().map(String::as_str);
        let ok = match (a.as_str(), v) {
            ("--hours", Some(v)) => v.parse().map(|h| set.hours = h).is_ok(),
            ("--imu-hz", Some(v)) => v.parse().map(|h| set.imu_hz = h).is_ok(),
            ("--sensors", Some(v)) => v.parse().map(|s| set.sensors = s).is_ok(),
            _ => false,
        };
        if !ok {
            eprintln!("usage: soak --hours H [--imu-hz F] [--sensors 1|3]   (bad argument `{a}`)");
            return ExitCode::from(2);
        }
    }
    let bar = indicatif::ProgressBar::new(set.hours.ceil() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("soak {bar:40} {pos}/{len} simulated h, {eta} left")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let fig = run(set, |h| bar.set_position(h as u64));
    bar.finish_and_clear();
    for l in fig.lines() {
        println!("{l}");
    }
    ExitCode::SUCCESS
}
