//! The MEMS recipe of the firmware guide, end to end: a static chamber log → `qfa-lab
//! calibrate --lsb-per-g 4096` → `table.bin` → `Table::decode` → a compensator that states
//! the part's 4 096 LSB/g → the part's raw LSB → `cycle_samples` removes the bias's change
//! with temperature (0.98 mg between 10 and 50 °C here, 0.07 mg left). And the mistakes it
//! guards against: the part read at ±16 g (2 048 LSB/g) against a table calibrated at ±8 g
//! is refused, and so is a samples configuration that does not state the sensitivity.
//! Before, the firmware multiplied the raw LSB by 2²⁰/4 096 by hand: left out, 1 g read
//! 0.0039 g; with ±8 g's 256 for a ±16 g part, 0.5 g; both with the status OK.

use std::process::Command;

use qfa_thermal::table::{self, Input, Table};
use qfa_thermal::{Compensator, Config, ConfigError, G0};

/// The truth of the synthetic part: bias in g at `temp_c` (the same on every axis).
fn bias_g(temp_c: f64) -> f64 {
    let d = temp_c - 25.0;
    1e-3 + 2e-5 * d + 2e-7 * d * d
}

/// A ±8 g part read at 4 096 LSB/g.
const LSB_PER_G: f64 = 4_096.0;

#[test]
fn a_mems_table_reaches_the_firmware_from_the_docs() {
    let dir = std::env::temp_dir().join(format!("qfa-mems-recipe-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let log = dir.join("board.csv");
    // Two ramps of ±35 °C about 25 °C at 2 °C/min, 1-s rows, z up, readings in g.
    let mut csv = String::from("time_s,temp_c,ax_g,ay_g,az_g\n");
    for k in 0..6_000u32 {
        let phase = f64::from(k % 4_200) / 4_200.0;
        let tri = if phase < 0.5 { 4.0 * phase - 1.0 } else { 3.0 - 4.0 * phase };
        let temp = ((25.0 + 35.0 * tri) * 16.0).round() / 16.0;
        let b = bias_g(temp);
        csv.push_str(&format!("{k},{temp},{b},{b},{}\n", 1.0 + b));
    }
    std::fs::write(&log, csv).unwrap();
    let out = dir.join("cal");
    let run = Command::new(env!("CARGO_BIN_EXE_qfa-lab"))
        .args(["calibrate", "--log", log.to_str().unwrap(), "--out", out.to_str().unwrap(), "--lsb-per-g", "4096"])
        .output()
        .expect("run qfa-lab");
    assert!(run.status.success(), "{}", String::from_utf8_lossy(&run.stderr));
    let table = Table::decode(&std::fs::read(out.join("table.bin")).unwrap()).unwrap();
    assert_eq!(table.input, Input::Samples);
    assert_eq!(table.part_lsb_per_g, Some(4_096.0));

    // The mistakes: no sensitivity stated; the part read at ±16 g.
    let unstated = Config { input: Input::Samples, ..Config::default() };
    assert_eq!(Compensator::<3, 32>::new(unstated).err(), Some(ConfigError::SampleScaleNotStated));
    let sixteen = Config { input: Input::Samples, sample_lsb_per_g: 2_048.0, ..Config::default() };
    let mut wrong = Compensator::<3, 32>::new(sixteen).unwrap();
    assert_eq!(
        wrong.set_table(table.clone()),
        Err(table::Error::PartScale { table_lsb_per_g: 4_096, config_lsb_per_g: 2_048 })
    );

    // The recipe: the compensator states the part's sensitivity; raw LSB go in as they come.
    let part = Config { input: Input::Samples, sample_lsb_per_g: LSB_PER_G as f32, ..Config::default() };
    let mut c = Compensator::<3, 32>::new(part).unwrap();
    c.set_table(table).unwrap();
    // Hold at 10 °C, warm at 1 °C/min to 50 °C, hold again; each hold is long enough for
    // whatever history states the table has to settle (`MODEL_SETTLING` clears). The part's
    // bias moves by 0.88 mg between the holds; the table removes that change (a static log
    // cannot tell the offset from gravity's projection, so the table keeps the log's mean
    // bias: the outputs are compared with each other, not with 0 and 1 g).
    let mut t_ms = 0u32;
    let mut at = |c: &mut Compensator<3, 32>, raw_t: i16, secs: u32| {
        for _ in 0..secs {
            c.on_raw(0, t_ms, raw_t).unwrap();
            t_ms += 1_000;
        }
    };
    let mut held = Vec::new();
    for (k, temp_c) in [10.0f64, 50.0].into_iter().enumerate() {
        // Warming to each hold (0.94 °C/min: 1/16 °C every 4 s), so the bias branch is known.
        let from = if k == 0 { 8 * 16 } else { 10 * 16 };
        for raw_t in from..(temp_c * 16.0) as i16 {
            at(&mut c, raw_t, 4);
        }
        at(&mut c, (temp_c * 16.0) as i16, 3_600);
        let b = bias_g(temp_c);
        let raw: [i32; 3] = [b, b, 1.0 + b].map(|g| (g * LSB_PER_G).round() as i32);
        let o = c.cycle_samples(raw, 5_000);
        assert!(o.status.is_ok(), "at {temp_c} °C: {:?}", o.status);
        held.push((raw, o.accel_mps2.map(|a| f64::from(a) / f64::from(G0))));
    }
    let ((raw_cold, cold), (raw_hot, hot)) = (held[0], held[1]);
    for axis in 0..3 {
        let raw_moved = f64::from(raw_hot[axis] - raw_cold[axis]) / LSB_PER_G;
        let moved = hot[axis] - cold[axis];
        println!("axis {axis}: raw moved {:.3} mg, compensated {:.3} mg", raw_moved * 1e3, moved * 1e3);
        assert!(raw_moved.abs() > 0.7e-3, "the bias moves: {raw_moved}");
        // Within the part's quantization (one LSB between the two readings, 0.24 mg) and the fit.
        assert!(moved.abs() < 0.3e-3, "axis {axis}: the compensated output moved {moved} g");
    }
    let _ = std::fs::remove_dir_all(&dir);
}

/// A sensitivity no part has is refused as a usage error before any work, naming the range
/// and an example: 0, NaN and a word (the table's own check came only after the whole fit).
#[test]
fn a_sensitivity_no_part_has_is_refused_before_the_fit() {
    let dir = std::env::temp_dir().join(format!("qfa-mems-lsb-{}", std::process::id()));
    for v in ["0", "nan", "4096g"] {
        let out = Command::new(env!("CARGO_BIN_EXE_qfa-lab"))
            .args(["calibrate", "--log", "no-such.csv", "--out", dir.to_str().unwrap(), "--lsb-per-g", v])
            .output()
            .expect("run qfa-lab");
        let err = String::from_utf8_lossy(&out.stderr);
        assert_eq!(out.status.code(), Some(2), "{v}: {err}");
        assert!(err.contains("LSB per g") && err.contains("4096"), "{v}: {err}");
        assert!(!dir.exists(), "nothing written");
    }
}
