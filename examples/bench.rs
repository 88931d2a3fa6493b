//! Instruction counts of the fast and slow paths on the Cortex-M4F, under QEMU with
//! `-icount shift=0` (one instruction = 1 ns of virtual time; SysTick counts that clock
//! deterministically, the DWT cycle counter reads 0). Run: `cargo xtask bench-target`, which
//! builds it with `fixtures` and `bench-internals` and, as an application crate, at opt-level
//! 3 (the core package's own `"s"` would reach it otherwise).
//!
//! Method: SysTick runs from the core clock, reload 2²⁴−1. A loop of exactly two
//! instructions per iteration (`subs`/`bne`, inline asm), timed at two lengths, gives
//! instructions per tick without its fixed overhead. Each figure is `CALLS` calls in
//! batches short enough never to wrap SysTick, minus the same loop with an empty body that
//! passes the same values through `black_box`, times instructions per tick, over `CALLS`.
#![cfg_attr(target_os = "none", no_std, no_main)]

mod common;

#[cfg(target_os = "none")]
mod target {
    use core::fmt::Write;
    use core::hint::black_box;

    use cortex_m::peripheral::{syst::SystClkSource, SYST};
    use cortex_m_rt::entry;
    use qfa_thermal::{
        Config, PulseOutput, Status, Table, ThreeAxisSensorPerAxis, ThreeAxisSensorPerAxisWithMatrix,
        ThreeAxisSharedSensor, ThreeAxisSharedSensorWithMatrix,
    };

    use crate::common::inputs::{self, sample};
    use crate::common::rt;
    use crate::common::tables;

    const CALLS: u32 = 10_000;
    const BATCH: u32 = 500;
    const RELOAD: u32 = 0x00FF_FFFF;

    fn now() -> u32 {
        SYST::get_current()
    }

    /// Ticks from `start` to `end` of the down-counter (less than one wrap).
    fn ticks(start: u32, end: u32) -> u32 {
        start.wrapping_sub(end) & RELOAD
    }

    /// `n` iterations of exactly two instructions.
    #[inline(always)]
    #[allow(unsafe_code)]
    fn spin(n: u32) {
        // SAFETY: register-only countdown loop; no memory, no stack.
        unsafe {
            core::arch::asm!("2:", "subs {0}, {0}, #1", "bne 2b", inout(reg) n => _, options(nomem, nostack));
        }
    }

    fn time_spin(n: u32) -> u32 {
        let s = now();
        spin(black_box(n));
        ticks(s, now())
    }

    /// Ticks for `CALLS` calls of `f(k)`, k = 0.., in batches of `BATCH`.
    // Never inlined: whether `main` absorbs it decides which registers the loop keeps free
    // (a zero held outside the loop or loaded in it), which moved the fast-path figure by
    // one instruction with the library's code unchanged.
    #[inline(never)]
    fn time_calls(mut f: impl FnMut(u32)) -> u64 {
        let mut total = 0u64;
        let mut k = 0u32;
        for _ in 0..CALLS / BATCH {
            let s = now();
            for _ in 0..BATCH {
                f(k);
                k = k.wrapping_add(1);
            }
            total += u64::from(ticks(s, now()));
        }
        total
    }

    /// A compensator with one shared sensor, holding `table` in flash, warmed up.
    fn shared_sensor(config: Config, table: &'static Table) -> ThreeAxisSharedSensor {
        inputs::shared_sensor(config, table)
    }

    /// [`shared_sensor`] with a misalignment stage, for a table with a matrix.
    fn shared_sensor_with_matrix(table: &'static Table) -> ThreeAxisSharedSensorWithMatrix {
        inputs::shared_sensor(Config::default(), table)
    }

    /// The samples path measured on a compensator configured for samples at the table's own
    /// part sensitivity (on a pulse one it would time the `WRONG_INPUT` return).
    fn samples_compensator() -> ThreeAxisSharedSensor {
        let config = Config {
            input: qfa_thermal::Input::Samples,
            sample_lsb_per_g: tables::SAMPLE_LSB_PER_G,
            ..Config::default()
        };
        shared_sensor(config, &tables::SAMPLES)
    }

    /// Timestamp (ms), sensor and raw reading of slow-path call `k` with a sensor per axis:
    /// the three sensors read in turn, each at 1 Hz on [`sample`]'s triangle.
    fn sample_per_axis(k: u32) -> (u32, usize, i16) {
        let (t, raw) = sample(k / 3);
        (t.wrapping_add(k % 3), (k % 3) as usize, raw)
    }

    /// The recommended configuration: a sensor per axis, the table in flash, warmed up.
    fn sensor_per_axis(table: &'static Table) -> ThreeAxisSensorPerAxis {
        let mut c = ThreeAxisSensorPerAxis::new(Config::default()).expect("a valid config");
        c.set_table(table).expect("fixture table validates");
        for k in 0..3 * 64 {
            let (t, sensor, raw) = sample_per_axis(k);
            c.on_raw(sensor, t, raw).expect("warm-up readings are plausible");
        }
        c
    }

    fn per_call(ticks: u64, empty: u64, insns_per_tick: f64) -> f64 {
        (ticks as f64 - empty as f64) * insns_per_tick / f64::from(CALLS)
    }

    #[entry]
    fn main() -> ! {
        let Some(mut out) = rt::console() else { rt::exit(2) };
        let mut cp = cortex_m::Peripherals::take().expect("first take");
        cp.SYST.set_clock_source(SystClkSource::Core);
        cp.SYST.set_reload(RELOAD);
        cp.SYST.clear_current();
        cp.SYST.enable_counter();

        let (n1, n2) = (100_000u32, 1_100_000u32);
        let (t1, t2) = (time_spin(n1), time_spin(n2));
        let ipt = 2.0 * f64::from(n2 - n1) / f64::from(t2 - t1);

        const PULSES: [i32; 3] = [1_602, -3_203, 320_320];
        const DT: u32 = 5_000;
        let fast_empty = time_calls(|_| {
            black_box(black_box(PULSES));
            black_box(black_box(DT));
            black_box(PulseOutput { dv_mps: black_box([0.0f32; 3]), status: Status::from_bits_retain(black_box(0)) });
        });
        // The fast path is measured through the split applier, as the IMU interrupt runs it.
        let mut c = shared_sensor(Config::default(), &tables::SLOTS_OFF);
        let (_, mut ap) = c.split();
        let fast = time_calls(|_| {
            black_box(black_box(&mut ap).cycle(black_box(PULSES), black_box(DT)));
        });
        let mut cs = samples_compensator();
        let (_, mut aps) = cs.split();
        let fast_s = time_calls(|_| {
            black_box(black_box(&mut aps).cycle_samples(black_box(PULSES), black_box(DT)));
        });
        let mut c = shared_sensor_with_matrix(&tables::MISALIGNED);
        let (_, mut ap) = c.split();
        let fast_m = time_calls(|_| {
            black_box(black_box(&mut ap).cycle(black_box(PULSES), black_box(DT)));
        });

        // The creep slot's exp: libm against micromath, over its argument range −dt/τ for
        // dt = 1 s and τ ≥ 1 s, i.e. [−1, 0).
        let arg = |k: u32| -((k & 1023) as f32 + 0.5) / 1024.0;
        let exp_empty = time_calls(|k| {
            black_box(black_box(arg(k)));
        });
        let exp_libm = time_calls(|k| {
            black_box(libm::expf(black_box(arg(k))));
        });
        let exp_mm = time_calls(|k| {
            black_box(micromath::F32(black_box(arg(k))).exp().0);
        });
        let mut exp_err = 0.0f64;
        for k in 0..1024 {
            let x = arg(k);
            let want = libm::exp(f64::from(x));
            exp_err = exp_err.max(((f64::from(micromath::F32(x).exp().0) - want) / want).abs());
        }
        let mut libm_err = 0.0f64;
        for k in 0..1024 {
            let x = arg(k);
            let want = libm::exp(f64::from(x));
            libm_err = libm_err.max(((f64::from(libm::expf(x)) - want) / want).abs());
        }

        let slow_empty = time_calls(|k| {
            let (t, raw) = sample(k + 64);
            black_box(black_box(t));
            black_box(black_box(raw));
            let _ = black_box(Ok::<Status, qfa_thermal::SampleError>(Status::from_bits_retain(black_box(0))));
        });
        let mut c = shared_sensor(Config::default(), &tables::SLOTS_OFF);
        let slow_off = time_calls(|k| {
            let (t, raw) = sample(k + 64);
            let _ = black_box(black_box(&mut c).on_raw(0, black_box(t), black_box(raw)));
        });
        let off_status = c.status();
        let mut c = shared_sensor(Config::default(), &tables::SLOTS_ON);
        let slow_on = time_calls(|k| {
            let (t, raw) = sample(k + 64);
            let _ = black_box(black_box(&mut c).on_raw(0, black_box(t), black_box(raw)));
        });
        let on_status = c.status();
        let per_axis_empty = time_calls(|k| {
            let (t, sensor, raw) = sample_per_axis(k + 3 * 64);
            black_box(black_box(t));
            black_box(black_box(sensor));
            black_box(black_box(raw));
            let _ = black_box(Ok::<Status, qfa_thermal::SampleError>(Status::from_bits_retain(black_box(0))));
        });
        let mut c = sensor_per_axis(&tables::SLOTS_ON);
        let per_axis_on = time_calls(|k| {
            let (t, sensor, raw) = sample_per_axis(k + 3 * 64);
            let _ = black_box(black_box(&mut c).on_raw(black_box(sensor), black_box(t), black_box(raw)));
        });
        let per_axis_status = c.status();

        let _ = writeln!(out, "calls_per_figure={CALLS}");
        let _ = writeln!(out, "insns_per_systick_tick={ipt:.4}");
        let _ = writeln!(out, "fast_path_insns_3axis={:.1}", per_call(fast, fast_empty, ipt));
        let _ = writeln!(out, "fast_path_insns_3axis_misalign={:.1}", per_call(fast_m, fast_empty, ipt));
        let _ = writeln!(out, "fast_path_samples_insns_3axis={:.1}", per_call(fast_s, fast_empty, ipt));
        let _ = writeln!(out, "expf_libm_insns={:.1}", per_call(exp_libm, exp_empty, ipt));
        let _ = writeln!(out, "expf_micromath_insns={:.1}", per_call(exp_mm, exp_empty, ipt));
        let _ = writeln!(out, "expf_libm_max_rel_err={libm_err:.2e}");
        let _ = writeln!(out, "expf_micromath_max_rel_err={exp_err:.2e}");
        let _ = writeln!(out, "slow_path_insns_3axis_all_off={:.1}", per_call(slow_off, slow_empty, ipt));
        let _ = writeln!(out, "slow_path_insns_3axis_all_on={:.1}", per_call(slow_on, slow_empty, ipt));
        let _ = writeln!(out, "slow_path_insns_sensor_per_axis={:.1}", per_call(per_axis_on, per_axis_empty, ipt));
        let _ = writeln!(out, "slow_path_status_all_off={:#06x}", off_status.bits());
        let _ = writeln!(out, "slow_path_status_all_on={:#06x}", on_status.bits());
        let _ = writeln!(out, "slow_path_status_sensor_per_axis={:#06x}", per_axis_status.bits());
        // The core has no statics: its RAM is the compensator it is given. The recommended
        // configuration: one sensor per axis, the table in flash (`&'static Table`).
        let _ = writeln!(out, "core_ram_bytes={}", core::mem::size_of::<ThreeAxisSensorPerAxis>());
        let _ = writeln!(out, "core_ram_bytes_one_sensor={}", core::mem::size_of::<ThreeAxisSharedSensor>());
        // The misalignment stage's cost: the recommended configuration with one.
        let _ =
            writeln!(out, "core_ram_bytes_with_matrix={}", core::mem::size_of::<ThreeAxisSensorPerAxisWithMatrix>());
        let _ = writeln!(out, "core_ram_bytes_table_in_ram={}", core::mem::size_of::<ThreeAxisSensorPerAxis<Table>>());
        let _ = writeln!(out, "core_ram_published_bytes={}", core::mem::size_of::<qfa_thermal::Published<3>>());
        // Of which: the active table's copy and the rate estimator's window.
        let _ = writeln!(out, "core_ram_table_bytes={}", core::mem::size_of::<Option<Table>>());
        let _ = writeln!(out, "core_ram_rate_bytes={}", core::mem::size_of::<qfa_thermal::rate::RateEstimator<32>>());
        rt::exit(0)
    }

    crate::common::printing_handlers!();
}

#[cfg(not(target_os = "none"))]
fn main() {
    eprintln!("bench counts instructions under QEMU: run `cargo xtask bench-target`");
    std::process::exit(2);
}
