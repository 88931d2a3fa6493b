//! Soak benchmark: `cargo run --release -p host-tests --bin soak -- --hours H [--imu-hz F]
//! [--sensors 1|3] [--faults]`. Drives the simulated bus, the DS18B20 driver and the split
//! compensator through H hours of simulated time, starting both clocks near their wraps,
//! healthy or with the field fault schedule (`host_tests::soak::Faults::field`, laid out
//! for 1 320 h, the default H with `--faults`), and prints one `key=value` line per figure
//! (`host_tests::soak`).

use std::process::ExitCode;

use host_tests::soak::{run, Faults, Settings};

fn main() -> ExitCode {
    let mut set = Settings::default();
    let mut hours = None;
    let args: Vec<String> = std::env::args().skip(1).collect();
    let mut it = args.iter();
    while let Some(a) = it.next() {
        let ok = match a.as_str() {
            "--faults" => {
                set.faults = Some(Faults::field());
                true
            }
            "--hours" => it.next().and_then(|v| v.parse().ok()).map(|h| hours = Some(h)).is_some(),
            "--imu-hz" => it.next().and_then(|v| v.parse().ok()).map(|h| set.imu_hz = h).is_some(),
            "--sensors" => it.next().and_then(|v| v.parse().ok()).map(|s| set.sensors = s).is_some(),
            _ => false,
        };
        if !ok {
            eprintln!("usage: soak --hours H [--imu-hz F] [--sensors 1|3] [--faults]   (bad argument `{a}`)");
            return ExitCode::from(2);
        }
    }
    set.hours = hours.unwrap_or(if set.faults.is_some() { Faults::FIELD_HOURS } else { set.hours });
    let bar = indicatif::ProgressBar::new(set.hours.ceil() as u64);
    bar.set_style(
        indicatif::ProgressStyle::with_template("soak {bar:40} {pos}/{len} simulated h, {eta} left")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    let fig = run(&set, |h| bar.set_position(h as u64));
    bar.finish_and_clear();
    for l in fig.lines() {
        println!("{l}");
    }
    ExitCode::SUCCESS
}
