//! Field scenarios: states a navigation computer reaches in weeks of service (dead, frozen
//! and browned-out sensors, clones, reloads, mis-wired tables), each pinned by a test that
//! failed on the code before its fix. The test names say which scenario they pin.

use host_tests::scenarios;
use qfa_thermal::ds18b20::{self, Resolution, POWER_ON_RAW};
use qfa_thermal::model::BiasGrid;
use qfa_thermal::table::{self, Input, Table};
use qfa_thermal::{Compensator, Config, ConfigError, Extensions, SampleError, Status};

type Comp = Compensator<3, 32, 3>;

fn comp(input: Input) -> Comp {
    let t = scenarios::table(0, [Extensions::default(); 3], None);
    let (config, t) = match input {
        Input::Samples => (scenarios::samples_config(Config::default()), scenarios::as_samples(&t)),
        Input::PulseCounts => (Config::default(), t),
    };
    let mut c = Comp::new(config).unwrap();
    c.set_table(t).unwrap();
    c
}

/// 22 °C, with a slow wobble so the rate windows stay busy.
fn raw_at(t_ms: u64) -> i16 {
    352 + ((t_ms / 60_000) % 4) as i16
}

const WRAP_MS: u64 = 1 << 32;

/// Scenario 1. Sensor 1 dies after 60 s while sensors 0 and 2 keep reporting. Its stream
/// must read stale on every cycle from 3 s after its last reading on, for more than a whole
/// ms wrap (the stale flag used to clear for 3 s at 2³² ms + 60 s, when the wrapped
/// difference looked fresh).
#[test]
fn dead_sensor_stays_stale_across_the_ms_wrap() {
    let mut c = comp(Input::Samples);
    let stale_ms = 3_000u64;
    let mut checked_near_wrap = 0;
    let mut t: u64 = 0;
    let end = WRAP_MS + 120_000;
    while t < end {
        // 1 Hz around the start and the wrap; 20 s steps in between (within the rate
        // window's 30-s gap) to keep the test fast.
        let near = t < 120_000 || (WRAP_MS - 60_000..end).contains(&t);
        for s in [0usize, 2] {
            c.on_raw(s, (t + 10 * s as u64) as u32, raw_at(t)).unwrap();
        }
        if t <= 60_000 {
            c.on_raw(1, (t + 10) as u32, raw_at(t)).unwrap();
        }
        let out = c.cycle_samples([1 << 20, 0, 0], 2_500);
        if t > 60_000 + stale_ms + 20 {
            assert!(out.status.contains(Status::TEMP_STALE), "t = {t} ms: sensor 1 dead since 60 s, {out:?}");
            if near && t > WRAP_MS {
                checked_near_wrap += 1;
            }
        }
        t += if near { 1_000 } else { 20_000 };
    }
    assert!(checked_near_wrap > 100, "{checked_near_wrap}");
}

/// Scenario 1, the returning sensor. A sensor that returns one whole ms wrap after its last
/// reading (the wrapped difference says 2 s) starts a new rate window instead of reusing its
/// old one as if seconds had passed, and a step beyond `max_step_raw` is confirmed first.
#[test]
fn returning_sensor_after_a_whole_wrap_restarts_its_window() {
    let mut c = comp(Input::Samples);
    for k in 0..40u64 {
        for s in 0..3 {
            c.on_raw(s, (1_000 * k + 10 * s as u64) as u32, 352).unwrap();
        }
    }
    assert!(c.estimate_of(1).unwrap().ready);
    // Sensor 1 is away for a whole wrap; sensors 0 and 2 report every 20 s meanwhile.
    let mut t = 40_000u64;
    while t < WRAP_MS + 41_000 {
        for s in [0usize, 2] {
            c.on_raw(s, (t + 10 * s as u64) as u32, 352).unwrap();
        }
        t += 20_000;
    }
    // Back at 2³² ms + 41 s, 2 s after its last reading modulo the wrap, at the same
    // temperature: taken, in a new window (the old one would give a rate over "2 s").
    let back = (WRAP_MS + 41_010) as u32;
    c.on_raw(1, back, 353).unwrap();
    let e = c.estimate_of(1).unwrap();
    assert!(!e.ready, "the window restarted: {e:?}");
    assert_eq!(e.temp_c, 22.0625);
    // A 5 °C step after the same gap is confirmed first.
    let mut d = c.clone();
    let _ = d.on_raw(1, back + 1, 353 + 80);
    assert!(d.on_raw(1, back + 1_000, 353 + 80).is_err(), "within 1 s: the slew bound is 1.5 °C");
}

/// Scenario 2. A clone made after the applier has seen a publication and a table load has
/// happened since must apply the table exactly as the original does.
#[test]
fn clone_after_a_table_load_applies_the_table() {
    let mut a = Comp::new(scenarios::samples_config(Config::default())).unwrap();
    let _ = a.cycle_samples([1 << 20, 0, 0], 2_500);
    a.set_table(scenarios::as_samples(&scenarios::table(0, [Extensions::default(); 3], None))).unwrap();
    for k in 0..12u32 {
        for s in 0..3 {
            a.on_raw(s, 1_000 * k + s as u32, 352).unwrap();
        }
    }
    let mut b = a.clone();
    for _ in 0..3 {
        let (x, y) = (a.cycle_samples([1 << 20, 5, -9], 2_500), b.cycle_samples([1 << 20, 5, -9], 2_500));
        assert!(!y.status.contains(Status::NO_TABLE), "{y:?}");
        assert_eq!(x, y);
    }
}

/// Scenario 3. A table records the input it was fitted for; one fitted on samples is
/// refused by a pulse-count compensator with a typed error, and a path that does not match
/// the compensator's input raises `WRONG_INPUT` (it used to return Δv with status OK).
#[test]
fn samples_table_on_a_pulse_compensator_is_refused() {
    let mut c = Comp::new(Config::default()).unwrap();
    assert_eq!(c.config().input, Input::PulseCounts);
    let mut t = scenarios::table(0, [Extensions::default(); 3], None);
    t.input = Input::Samples;
    assert_eq!(
        c.set_table(t.clone()),
        Err(table::Error::Input { table: Input::Samples, compensator: Input::PulseCounts })
    );
    assert!(c.table().is_none());
    // The same refusal from the wire bytes.
    let mut buf = [0u8; table::MAX_TABLE_BYTES];
    let bytes = t.encode(&mut buf).unwrap();
    assert!(matches!(c.load_table(bytes), Err(table::Error::Input { .. })));

    let mut s = comp(Input::Samples);
    for k in 0..12u32 {
        for j in 0..3 {
            s.on_raw(j, 1_000 * k + j as u32, 352).unwrap();
        }
    }
    // At rest since power-up: no decisive rate, so the bias branch is unknown (this table's
    // branches differ by 30 µg) and only that is flagged.
    assert_eq!(s.cycle_samples([1 << 20, 0, 0], 2_500).status, Status::MODEL_SETTLING);
    let wrong = s.cycle([800, 0, 0], 2_500);
    assert!(wrong.status.contains(Status::WRONG_INPUT), "{wrong:?}");
    let wrong = s.cycle_counters([800, 0, 0], 2_500);
    assert!(wrong.status.contains(Status::WRONG_INPUT), "{wrong:?}");
    let mut p = comp(Input::PulseCounts);
    assert!(p.cycle_samples([1 << 20, 0, 0], 2_500).status.contains(Status::WRONG_INPUT));
}

/// Scenario 3, old tables. Format 1 did not record the input; such a table is refused with
/// an error that says so, never guessed.
#[test]
fn format_1_table_is_refused_for_its_missing_input() {
    let t = scenarios::table(0, [Extensions::default(); 3], None);
    let mut buf = [0u8; table::MAX_TABLE_BYTES];
    let mut bytes = t.encode(&mut buf).unwrap().to_vec();
    bytes[4..6].copy_from_slice(&1u16.to_le_bytes());
    assert_eq!(Table::decode(&bytes), Err(table::Error::NoInputRecorded));
    assert!(table::Error::NoInputRecorded.to_string().contains("pulse counts or samples"));
}

/// Scenario 4. After a dropout, the power-on value 0550h (+85 °C) following 22 °C is a
/// brown-out, not a reading: it is refused however long the gap was (the plausibility
/// bound used to grow without limit, admitting it after 6.3 min), and a real large step
/// after a long gap is confirmed before it is used.
#[test]
fn power_on_value_after_a_dropout_is_refused() {
    for gap_min in [1u32, 7, 60, 24 * 60] {
        let mut c = comp(Input::Samples);
        for k in 0..20u32 {
            c.on_raw(0, 1_000 * k, 352).unwrap();
        }
        let back = 19_000 + gap_min * 60_000;
        assert_eq!(c.on_raw(0, back, POWER_ON_RAW), Err(SampleError::PowerOnJump), "gap {gap_min} min");
        // Through the scratchpad, from a clone part whose byte 6 does not give it away.
        let sp = ds18b20::encode_scratchpad(POWER_ON_RAW, Resolution::Bits12, 0x10);
        assert!(c.on_scratchpad(0, back + 1_000, &sp).is_err(), "gap {gap_min} min");
        assert_eq!(c.estimate_of(0).unwrap().temp_c, 22.0);
    }
    let mut c = comp(Input::Samples);
    for k in 0..20u32 {
        c.on_raw(0, 1_000 * k, 352).unwrap();
    }
    // 10 min later the case is 20 °C warmer: a real step, used once three readings agree.
    let back = 19_000 + 600_000;
    assert!(matches!(c.on_raw(0, back, 672), Err(SampleError::Implausible { raw: 672 })));
    assert!(c.on_raw(0, back + 1_000, 672).is_err());
    c.on_raw(0, back + 2_000, 672).unwrap();
    assert_eq!(c.estimate_of(0).unwrap().temp_c, 42.0);
}

/// Scenario 6. A bias grid whose step is too fine to resolve in f32 (start 64 °C, step
/// 2.6e-7 °C) is refused, and no grid that validates extrapolates past its own values.
#[test]
fn degenerate_bias_grid_is_refused() {
    let mut t = scenarios::table(0, [Extensions::default(); 3], None);
    let vals: Vec<f32> = (0..16).map(|i| 1e-3 * i as f32).collect();
    t.axes[0].bias = BiasGrid::single_valued(64.0, 2.6e-7, &vals).expect("2 to 16 grid values");
    assert_eq!(t.validate(), Err(table::Error::OutOfRange("bias.t_step_c")));
    // At the smallest accepted step, K0 stays within the grid's values everywhere.
    let mut g = BiasGrid::single_valued(64.0, table::limits::MIN_GRID_STEP_C, &vals).expect("2 to 16 grid values");
    g.deadband_c_per_min = 0.0;
    t.axes[0].bias = g.clone();
    t.validate().unwrap();
    let lo = vals[0];
    let hi = vals[15];
    for i in 0..2_000 {
        let temp = 63.0 + 0.002 * i as f32;
        let k0 = g.k0(temp.clamp(g.t_start_c, g.t_end_c()), qfa_thermal::model::Branch::Heating);
        assert!((lo..=hi).contains(&k0), "{temp} °C: K0 {k0}");
    }
}

/// Scenario 7. `confirm_samples = 1` would switch off both the plausibility check and the
/// restart check; it is refused.
#[test]
fn confirm_samples_of_one_is_refused() {
    let c = Config { confirm_samples: 1, ..Config::default() };
    assert_eq!(c.validate(), Err(ConfigError::OutOfRange("confirm_samples")));
    assert_eq!(Comp::new(c).err(), Some(ConfigError::OutOfRange("confirm_samples")));
}

/// Scenario 7. A CRC-valid scratchpad with a value the DS18B20 cannot produce (outside
/// −55…125 °C) is refused, also as the first reading and through `on_raw`.
#[test]
fn reading_outside_the_sensor_range_is_refused() {
    for raw in [-881i16, 2_001, i16::MIN, i16::MAX & !0xF] {
        let sp = ds18b20::encode_scratchpad(raw, Resolution::Bits12, 0x10);
        assert_eq!(ds18b20::decode_scratchpad(&sp), Err(ds18b20::Error::OutOfRange { raw }), "{raw}");
        let mut c = comp(Input::Samples);
        assert!(c.on_scratchpad(0, 0, &sp).is_err());
        assert_eq!(c.on_raw(0, 1_000, raw), Err(SampleError::Decode(ds18b20::Error::OutOfRange { raw })));
        assert!(c.estimate_of(0).is_none());
    }
    for raw in [-880i16, 2_000] {
        let sp = ds18b20::encode_scratchpad(raw, Resolution::Bits12, 0x10);
        assert_eq!(ds18b20::decode_scratchpad(&sp).map(|r| r.raw), Ok(raw));
    }
}

/// Scenario 7, the board part: a read that never arrived raises `TEMP_INVALID` and keeps
/// the last good compensation.
#[test]
fn missed_reading_raises_temp_invalid() {
    let mut c = comp(Input::Samples);
    for k in 0..12u32 {
        for s in 0..3 {
            c.on_raw(s, 1_000 * k + s as u32, 352).unwrap();
        }
    }
    let good = c.cycle_samples([1 << 20, 0, 0], 2_500);
    // At rest since power-up: only the unknown bias branch is flagged.
    assert_eq!(good.status, Status::MODEL_SETTLING, "{good:?}");
    assert_eq!(c.on_missed_reading(1, 12_001), Err(SampleError::Missed));
    let out = c.cycle_samples([1 << 20, 0, 0], 2_500);
    assert!(out.status.contains(Status::TEMP_INVALID), "{out:?}");
    assert_eq!(out.accel_mps2, good.accel_mps2);
}

/// Scenario 9. The compensator's module doc, the first page a firmware engineer reads,
/// described two buffers and the rule "the updater never preempts the applier", while the
/// code is one seqlock that is safe whichever context preempts which. The page must state
/// the contract the code has; the loom model (`cargo xtask loom`) checks the code side.
#[test]
fn compensator_doc_states_the_seqlock_contract() {
    let doc: String = include_str!("../../src/compensator/mod.rs")
        .lines()
        .take_while(|l| l.starts_with("//!"))
        .map(|l| l.trim_start_matches("//!").trim())
        .collect::<Vec<_>>()
        .join(" ");
    for gone in ["two buffers", "never preempts the applier", "inactive buffer"] {
        assert!(!doc.contains(gone), "the module doc still says {gone:?}");
    }
    for stated in ["seqlock", "whichever context preempts which", "the torn copy is dropped", "odd sequence"] {
        assert!(doc.contains(stated), "the module doc does not say {stated:?}");
    }
}
