//! The firmware demo on the QEMU reference target (Cortex-M4F, `mps2-an386`, whose memory
//! map is the repository's `memory.x`): JB-KT8 #1 on three axes, five minutes of a
//! 0.8 °C/min ramp read by a DS18B20 once a second, and 200 Hz pulse counts; prints
//! compensated output and status.
//!
//! ```sh
//! cargo xtask demo-qemu                                   # build for the target and run under QEMU
//! cargo run --example qemu_demo --features fixtures      # the same program on the host
//! ```
//!
//! The simulated instrument follows the same table (heating branch, slots off), with the
//! true temperature and rate, so the residual shows what the 12-bit readings and the rate
//! estimator's lag cost. Uncompensated output uses the nominal γ and no bias.
#![cfg_attr(target_os = "none", no_std, no_main)]

#[cfg(target_os = "none")]
mod target {
    use cortex_m_rt::entry;
    use cortex_m_semihosting::{debug, hio};

    #[entry]
    fn main() -> ! {
        let ok = hio::hstdout().is_ok_and(|mut out| super::run(&mut out).is_ok());
        let code = if ok { debug::EXIT_SUCCESS } else { debug::EXIT_FAILURE };
        debug::exit(code);
        // Without a semihosting host, exit returns: trap rather than run on.
        cortex_m::asm::udf()
    }

    /// A panic fails the run (QEMU exits non-zero) instead of hanging it.
    #[panic_handler]
    fn panic(info: &core::panic::PanicInfo<'_>) -> ! {
        if let Ok(mut e) = hio::hstderr() {
            use core::fmt::Write;
            let _ = writeln!(e, "panic: {info}");
        }
        debug::exit(debug::EXIT_FAILURE);
        cortex_m::asm::udf()
    }
}

/// On the host: the same demo on stdout.
#[cfg(not(target_os = "none"))]
fn main() {
    let mut out = String::new();
    let ok = run(&mut out).is_ok();
    print!("{out}");
    std::process::exit(if ok { 0 } else { 1 });
}

use core::fmt::{self, Write};

use qfa_thermal::ds18b20::{encode_scratchpad, Resolution};
use qfa_thermal::fixtures::JB_KT8_1;
use qfa_thermal::model::AxisState;
use qfa_thermal::table::MAX_TABLE_BYTES;
use qfa_thermal::{AxisModel, BiasGrid, Config, Extensions, Input, Status, Table, ThreeAxisSharedSensor, G0};

/// Seconds simulated.
const DURATION_S: u32 = 300;
/// IMU cycles per second.
const IMU_HZ: u32 = 200;
/// Ramp, °C/min.
const RAMP_C_PER_MIN: f64 = 0.8;
/// Temperature at t = 0, °C.
const START_C: f64 = 20.0;
/// True specific force per axis, g (a slight tilt, z up).
const TRUE_G: [f64; 3] = [0.02, -0.01, 1.0];
/// Seconds between printed lines.
const REPORT_EVERY_S: u32 = 30;

fn flags(out: &mut dyn Write, s: Status) -> fmt::Result {
    const NAMES: [(Status, &str); 7] = [
        (Status::TEMP_STALE, "stale"),
        (Status::TEMP_INVALID, "invalid"),
        (Status::RATE_NOT_READY, "rate-not-ready"),
        (Status::TEMP_OUT_OF_RANGE, "temp-out-of-range"),
        (Status::RATE_OUT_OF_RANGE, "rate-out-of-range"),
        (Status::NO_TABLE, "no-table"),
        (Status::NO_COUNTER_BASE, "no-counter-base"),
    ];
    write!(out, "{:#06x}", s.bits())?;
    if s.is_ok() {
        return out.write_str(" ok");
    }
    for (bit, name) in NAMES {
        if s.contains(bit) {
            write!(out, " {name}")?;
        }
    }
    Ok(())
}

/// JB-KT8 #1 (paper Eq. 15) on three axes, a plausible bias grid per axis (about 100 µg at
/// 22 °C, 1.5 µg/°C, slight curvature, heating 8 µg above cooling) on −40…80 °C.
fn table() -> Table {
    let mut axes = heapless::Vec::new();
    for axis in 0..3 {
        let offset = 1.0e-4 + 2.0e-5 * axis as f32;
        let k0 = |i: usize| {
            let d = -40.0 + 10.0 * i as f32 - 22.0;
            offset + 1.5e-6 * d + 8.0e-9 * d * d
        };
        let mut bias = BiasGrid::single_valued(-40.0, 10.0, &[0.0; 13]).expect("2 to 16 grid values");
        for (i, (h, c)) in bias.heating_g.iter_mut().zip(bias.cooling_g.iter_mut()).enumerate() {
            *h = k0(i) + 4e-6;
            *c = k0(i) - 4e-6;
        }
        let model = AxisModel { scale: JB_KT8_1, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() };
        // Capacity is 3 and the loop pushes 3.
        let _ = axes.push(model);
    }
    Table { input: Input::PulseCounts, rate_window: 32, axes, misalignment: None, part_lsb_per_g: None }
}

/// Run the demo, writing to `out`.
///
/// # Errors
/// A failed write, or [`fmt::Error`] if the table does not load (it always does).
fn run(out: &mut dyn Write) -> fmt::Result {
    let table = table();
    let mut buf = [0u8; MAX_TABLE_BYTES];
    let bytes = table.encode(&mut buf).map_err(|_| fmt::Error)?;
    // One sensor for the three axes; the table, loaded from bytes, is owned.
    // The IMU's 200-Hz cycle, stated so that a dt in another unit is flagged.
    let config = Config { imu_period_s: 5e-3, ..Config::default() };
    let mut comp = ThreeAxisSharedSensor::<Table>::new(config).map_err(|_| fmt::Error)?;
    comp.load_table(bytes).map_err(|_| fmt::Error)?;
    writeln!(
        out,
        "qfa-thermal demo: JB-KT8 #1 (γ=320320, μ=−32.76, β=0.1008, ε=88.14, η=−0.02409, α=273, T0=22 °C) on 3 axes"
    )?;
    writeln!(
        out,
        "table {} bytes; ramp {RAMP_C_PER_MIN} °C/min from {START_C} °C; DS18B20 12-bit at 1 Hz; IMU {IMU_HZ} Hz; true a = {TRUE_G:?} g",
        bytes.len()
    )?;
    writeln!(out, "   t      T      Ṫ est   compensated a, g (mean over {REPORT_EVERY_S} s)   residual, µg   uncompensated err, µg   status")?;

    let dt_s = 1.0 / f64::from(IMU_HZ);
    let dt_ticks = (dt_s / f64::from(comp.config().tick_s)) as u32;
    let truth = &table.axes;
    let mut truth_state = [AxisState::default(); 3];
    let mut k1k0 = [(0.0f64, 0.0f64); 3];
    let mut carry = [0.0f64; 3];
    let mut dv_sum = [0.0f64; 3];
    let mut pulse_sum = [0i64; 3];
    let mut status = Status::empty();
    let rate_true = RAMP_C_PER_MIN as f32;

    for cycle in 0..DURATION_S * IMU_HZ {
        let t_s = f64::from(cycle) * dt_s;
        if cycle % IMU_HZ == 0 {
            let temp = START_C + RAMP_C_PER_MIN * t_s / 60.0;
            for (i, axis) in truth.iter().enumerate() {
                let e = axis.evaluate(&mut truth_state[i], temp as f32, rate_true, 1.0);
                k1k0[i] = (f64::from(e.k1), f64::from(e.k0));
            }
            // The reading of a conversion that ends now, 12-bit: nearest 1/16 °C.
            let raw = libm::round(temp * 16.0) as i16;
            let sp = encode_scratchpad(raw, Resolution::Bits12, 0x10);
            // A rejected reading raises TEMP_INVALID, which the status column shows.
            let _ = comp.on_scratchpad(0, cycle / IMU_HZ * 1000, &sp);
        }
        let mut pulses = [0i32; 3];
        for i in 0..3 {
            let (k1, k0) = k1k0[i];
            let exact = k1 * (k0 + TRUE_G[i]) * dt_s + carry[i];
            let n = libm::floor(exact);
            carry[i] = exact - n;
            pulses[i] = n as i32;
        }
        let o = comp.cycle(pulses, dt_ticks);
        for i in 0..3 {
            dv_sum[i] += f64::from(o.dv_mps[i]);
            pulse_sum[i] += i64::from(pulses[i]);
        }
        status = o.status;
        let next = cycle + 1;
        if next % (REPORT_EVERY_S * IMU_HZ) == 0 {
            let span = f64::from(REPORT_EVERY_S);
            let est = comp.estimate().ok_or(fmt::Error)?;
            write!(out, "{:>4} s {:>6.2} °C {:>+6.3} °C/min [", next / IMU_HZ, est.temp_c, est.rate_c_per_min)?;
            let a: [f64; 3] = core::array::from_fn(|i| dv_sum[i] / span / f64::from(G0));
            for x in a {
                write!(out, "{x:>+10.6}")?;
            }
            out.write_str("]  [")?;
            for i in 0..3 {
                write!(out, "{:>+7.1}", (a[i] - TRUE_G[i]) * 1e6)?;
            }
            out.write_str("]  [")?;
            for i in 0..3 {
                let raw_g = pulse_sum[i] as f64 / (f64::from(JB_KT8_1.gamma) * span);
                write!(out, "{:>+7.0}", (raw_g - TRUE_G[i]) * 1e6)?;
            }
            out.write_str("]  ")?;
            flags(out, status)?;
            out.write_char('\n')?;
            dv_sum = [0.0; 3];
            pulse_sum = [0; 3];
        }
    }
    write!(out, "demo done: final status ")?;
    flags(out, status)?;
    out.write_char('\n')
}
