//! The named streams of a flight. Every random draw of a navigation study comes from one
//! of these families under a base seed (the scenario's for the nominal flight, the Monte
//! Carlo run's for run `i`, a fault set's for its injectors), through the lab's one
//! derivation, [`qfa_rng::stream_seed`]. Offsets and XORs of the base seed, as these were,
//! gave a Monte Carlo run's IMU errors the very numbers its temperature variation and unit
//! spread were drawn from (both generators were seeded with the run's seed).

use qfa_rng::{stream_seed, Stream};

const MONTE_CARLO_RUNS: Stream = Stream::named("monte carlo: runs");
const VARIATION: Stream = Stream::named("flight: temperature variation and unit spread");
const IMU_ERRORS: Stream = Stream::named("flight: IMU errors and noise");
const ACCELEROMETER: Stream = Stream::named("flight: accelerometer noise");
const CALIBRATION_LOG: Stream = Stream::named("flight: calibration log");
const FAULTS: Stream = Stream::named("flight: injected faults");

/// The seed of run `i` of a Monte Carlo study of base seed `seed`: every draw of the run
/// follows from it.
#[must_use]
pub fn monte_carlo_run(seed: u64, i: u64) -> u64 {
    stream_seed(seed, MONTE_CARLO_RUNS, i)
}

/// The seed of a Monte Carlo run's temperature variation and unit spread.
#[must_use]
pub fn variation(seed: u64) -> u64 {
    stream_seed(seed, VARIATION, 0)
}

/// The seed of a flight's non-thermal IMU errors and its gyro and sensor noise.
#[must_use]
pub fn imu_errors(seed: u64) -> u64 {
    stream_seed(seed, IMU_ERRORS, 0)
}

/// The noise seed of axis `axis`'s accelerometer in flight.
#[must_use]
pub fn accelerometer(seed: u64, axis: usize) -> u64 {
    stream_seed(seed, ACCELEROMETER, axis as u64)
}

/// The base seed of axis `axis`'s simulated calibration log (its runs' seeds follow from
/// it, [`qfa_sim::run_seed`]).
#[must_use]
pub fn calibration_log(seed: u64, axis: usize) -> u64 {
    stream_seed(seed, CALIBRATION_LOG, axis as u64)
}

/// The seed of injector `index` of a fault set (0–2 the axes' readings, 3 the IMU cycle's
/// jitter).
#[must_use]
pub fn faults(seed: u64, index: u64) -> u64 {
    stream_seed(seed, FAULTS, index)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Over the base seeds of a nominal flight and 400 Monte Carlo runs of two study
    /// seeds, no two purposes share a seed, nor does any purpose take a run's own seed or
    /// one of its calibration logs' run seeds (the Monte Carlo run seeded its variation
    /// and its IMU errors both with the run's seed before).
    #[test]
    fn no_two_draws_of_a_flight_share_a_stream() {
        let mut seen = std::collections::HashSet::new();
        let runs = |s: u64| (0..400).map(move |i| monte_carlo_run(s, i));
        for base in [2019, 40].into_iter().chain(runs(2019)).chain(runs(7)) {
            let mut mine = vec![base, variation(base), imu_errors(base)];
            for axis in 0..3 {
                mine.push(accelerometer(base, axis));
                let log = calibration_log(base, axis);
                mine.push(log);
                mine.extend((0..6).flat_map(|p| (0..8).map(move |r| qfa_sim::run_seed(log, p, r))));
            }
            mine.extend((0..4).map(|k| faults(base, k)));
            for s in mine {
                assert!(seen.insert(s), "base seed {base}: seed {s} drawn twice");
            }
        }
    }
}
