//! The paths `cargo xtask trace-target` traces instruction by instruction (QEMU
//! `-singlestep -d exec`): the same compensators and inputs as the benchmark
//! (`examples/bench.rs`), each measured stretch between two calls of [`marker`], so the
//! trace can be cut into segments and each attributed to the functions it ran.
//!
//! Segments: 1, 30 readings with a sensor per axis, every slot on; 3, 30 readings of one
//! shared sensor, every slot on; 5, the same with every slot off; 7, 100 fast-path cycles.
#![cfg_attr(target_os = "none", no_std, no_main)]

mod common;

#[cfg(target_os = "none")]
mod target {
    use core::hint::black_box;

    use cortex_m_rt::entry;
    use qfa_thermal::{Config, Table, ThreeAxisSensorPerAxis, ThreeAxisSharedSensor};

    use crate::common::inputs::{self, sample};
    use crate::common::{rt, tables};

    /// Readings per slow-path segment.
    pub const READINGS: u32 = 30;
    /// Cycles in the fast-path segment.
    pub const CYCLES: u32 = 100;

    /// A segment boundary: the trace counts this function's entries.
    #[inline(never)]
    fn marker(n: u32) {
        black_box(n);
    }

    fn shared_sensor(table: &'static Table) -> ThreeAxisSharedSensor {
        inputs::shared_sensor(Config::default(), table)
    }

    #[entry]
    fn main() -> ! {
        let mut c = ThreeAxisSensorPerAxis::new(Config::default()).expect("a valid config");
        c.set_table(&tables::SLOTS_ON).expect("fixture table validates");
        let per_axis = |k: u32| {
            let (t, raw) = sample(k / 3);
            (t.wrapping_add(k % 3), (k % 3) as usize, raw)
        };
        for k in 0..3 * 64 {
            let (t, sensor, raw) = per_axis(k);
            c.on_raw(sensor, t, raw).expect("warm-up readings are plausible");
        }
        marker(1);
        for k in 0..READINGS {
            let (t, sensor, raw) = per_axis(k + 3 * 64);
            let _ = black_box(black_box(&mut c).on_raw(black_box(sensor), black_box(t), black_box(raw)));
        }
        marker(2);
        for (segment, table) in [(3, &tables::SLOTS_ON), (5, &tables::SLOTS_OFF)] {
            let mut c = shared_sensor(table);
            marker(segment);
            for k in 0..READINGS {
                let (t, raw) = sample(k + 64);
                let _ = black_box(black_box(&mut c).on_raw(0, black_box(t), black_box(raw)));
            }
            marker(segment + 1);
        }
        let mut c = shared_sensor(&tables::SLOTS_OFF);
        let (_, mut ap) = c.split();
        ap.cycle([0; 3], 5_000);
        marker(7);
        for _ in 0..CYCLES {
            black_box(black_box(&mut ap).cycle(black_box([1_602, -3_203, 320_320]), black_box(5_000)));
        }
        marker(8);
        rt::exit(0)
    }

    crate::common::printing_handlers!();
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("trace_paths runs under QEMU: run `cargo xtask trace-target`");
    std::process::exit(2);
}
