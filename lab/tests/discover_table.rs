//! One table for one cycling log: `discover` writes the table `calibrate` writes, with the
//! catalog's extension slots only when they carry to held-out programs
//! (`qfa_discover::cycling_table`).

mod common;

use qfa_calibrate::{calibrate_log, CalibrateOptions};
use qfa_discover::cycling_table::{adopt_slots, SlotGaps, Slots};
use qfa_discover::{analyze_source, Source, Start};
use qfa_sim::synth::{cycling_csv, kt8_1_scale, truth, SynthConfig};
use qfa_thermal::model::{Extensions, SensorLag};

fn quick(seed: u64) -> SynthConfig {
    SynthConfig { seed, t_lo: 5.0, t_hi: 40.0, hold_start_min: 30.0, hold_end_min: 45.0, ..SynthConfig::default() }
}

fn log_of(src: &Source) -> &qfa_log::cycling::Log {
    match src {
        Source::Cycling { log, .. } => log,
        Source::Single(_) => panic!("a cycling log"),
    }
}

/// The user's view: `calibrate` then `discover` on one log write the same `table.bin`, and
/// `discover` names that table's structure. Before, `discover` flashed the catalog's own
/// model (a smooth single-valued bias) and the two files differed.
#[test]
fn discover_writes_the_table_calibrate_writes() {
    let dir = common::fresh_dir("discover-table", "same");
    let csv = cycling_csv(&quick(31), &truth(kt8_1_scale(), [1.2e-4, 2.5e-6, 1.5e-8], Extensions::NONE), 20.0);
    let log = dir.join("log.csv");
    std::fs::write(&log, csv).unwrap();
    let (log_s, cal, disc) = (log.to_str().unwrap(), dir.join("cal"), dir.join("disc"));
    common::lab_ok(&["calibrate", "--log", log_s, "--out", cal.to_str().unwrap(), "--no-plots"]);
    let text = common::lab_ok(&["discover", "--log", log_s, "--start", "paper", "--out", disc.to_str().unwrap()]);
    let (a, b) = (std::fs::read(cal.join("table.bin")).unwrap(), std::fs::read(disc.join("table.bin")).unwrap());
    assert!(a == b, "discover's table.bin differs from calibrate's ({} and {} bytes)", b.len(), a.len());
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(disc.join("report.json")).unwrap()).unwrap();
    let structure = json["table"]["structure"].as_str().expect("report.json names the table's structure");
    assert!(structure.starts_with("Eq. 11 + "), "{structure}");
    assert!(text.contains(&format!("named {structure} = table.bin")), "{text}");
    assert_eq!(json["flashed"]["model"], structure);
    // calibrate's own held-out figures of that table, as calibrate prints them.
    let cal_json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(cal.join("report.json")).unwrap()).unwrap();
    let sens = cal_json["report"]["sensitivity_ppm_per_c"]["hysteresis"]
        .as_f64()
        .or_else(|| cal_json["sensitivity_ppm_per_c"]["hysteresis"].as_f64())
        .expect("calibrate's held-out sensitivity");
    assert_eq!(json["table"]["calibrate_heldout"]["sensitivity_ppm_per_c"].as_f64(), Some(sens));
    // What to expect in use is calibrate's figure, once; the covers line is calibrate's.
    let expect = text.lines().find(|l| l.starts_with("expect in use:")).expect("an expect line");
    assert!(
        expect.contains("calibrate's held-out figures of table.bin") && !expect.contains("held-out RMS"),
        "{expect}"
    );
    let covers = |t: &str| t.lines().find(|l| l.starts_with("covers:")).map(str::to_string);
    let cal_text = common::lab_ok(&["calibrate", "--log", log_s, "--out", cal.to_str().unwrap(), "--no-plots"]);
    assert_eq!(covers(&text), covers(&cal_text));

    // A log of one program: calibrate holds its table back, and discover writes the same
    // bytes, held back too (before, it flashed the catalog's own model).
    let text_all = std::fs::read_to_string(&log).unwrap();
    let first = text_all.lines().nth(1).unwrap().split(',').next().unwrap().to_string();
    let one: String = text_all
        .lines()
        .enumerate()
        .filter(|(i, l)| *i == 0 || l.starts_with(&format!("{first},")))
        .map(|(_, l)| format!("{l}\n"))
        .collect();
    let one_log = dir.join("one.csv");
    std::fs::write(&one_log, one).unwrap();
    let (one_s, cal1, disc1) = (one_log.to_str().unwrap(), dir.join("cal1"), dir.join("disc1"));
    let _ = common::lab(&["calibrate", "--log", one_s, "--out", cal1.to_str().unwrap(), "--no-plots"]);
    let text = common::lab_ok(&["discover", "--log", one_s, "--start", "paper", "--out", disc1.to_str().unwrap()]);
    assert!(std::fs::read(cal1.join("table.bin")).unwrap() == std::fs::read(disc1.join("table.bin")).unwrap());
    assert!(text.contains("= table.bin, the table `calibrate` writes for this log, held back: one program"), "{text}");
    assert!(text.contains("file: table.bin: held back"), "{text}");
    // A misspelt fit program is named as missing from the log, not as a program without a pair.
    let (ok, err) =
        common::lab(&["calibrate", "--log", log_s, "--fit-programs", "nope", "--out", cal.to_str().unwrap()]);
    assert!(!ok && err.contains("program `nope` is not in the log (its programs: "), "{err}");
    let _ = std::fs::remove_dir_all(&dir);
}

/// A lag the catalog names carries to the held-out programs: the table holds it, as
/// calibrate's fit with that slot, and the held-out gaps with it are below those without.
/// A 3000-s lag on a log without one does not carry, and is left out with its figures.
#[test]
fn a_slot_is_in_the_table_only_when_it_carries_forward() {
    let ext = Extensions { sensor_lag: Some(SensorLag { tau_s: 450.0 }), ..Extensions::NONE };
    let src = Source::parse(&cycling_csv(&quick(21), &truth(kt8_1_scale(), [1.2e-4, 2.5e-6, 1.5e-8], ext), 20.0), 60.0)
        .unwrap();
    let (r, table) = analyze_source(&src, Start::Paper).unwrap();
    let t = r.table.as_ref().expect("a cycling log's table");
    let Slots::Added(SlotGaps { without, with }) = &t.slots else { panic!("the named lag must carry: {:?}", t.slots) };
    eprintln!("lag: without {without:?}, with {with:?}; {}", t.structure);
    let lag = table.as_ref().unwrap().axes[0].ext.sensor_lag.expect("the table holds the lag");
    assert!((lag.tau_s - 450.0).abs() < 0.25 * 450.0, "{lag:?}");
    assert!(t.structure.contains("+lag"), "{}", t.structure);
    let named_ext = r.effects.iter().find(|e| e.name == "sensor_lag").map(|_| table.as_ref().unwrap().axes[0].ext);
    let cal = calibrate_log(log_of(&src), &CalibrateOptions { ext: named_ext.unwrap(), ..CalibrateOptions::default() })
        .unwrap();
    assert_eq!(cal.table.hysteresis.to_bytes().unwrap(), table.unwrap().to_bytes().unwrap());

    let clean = Source::parse(
        &cycling_csv(&quick(31), &truth(kt8_1_scale(), [1.2e-4, 2.5e-6, 1.5e-8], Extensions::NONE), 20.0),
        60.0,
    )
    .unwrap();
    let (mut r, _) = analyze_source(&clean, Start::Paper).unwrap();
    let Source::Cycling { log, channels } = &clean else { unreachable!() };
    let bogus = Extensions { sensor_lag: Some(SensorLag { tau_s: 3000.0 }), ..Extensions::NONE };
    let table = adopt_slots(log, channels, &mut r, vec!["sensor_lag".into()], bogus).unwrap();
    let t = r.table.as_ref().unwrap();
    assert!(matches!(t.slots, Slots::NotAdded(_)), "a 3000-s lag on a log without one: {:?}", t.slots);
    assert!(table.axes[0].ext.sensor_lag.is_none());
    let plain = calibrate_log(log, &CalibrateOptions::default()).unwrap();
    assert_eq!(plain.table.hysteresis.to_bytes().unwrap(), table.to_bytes().unwrap());
}

/// What `covers` and the table's limits describe is the table written, fitted on every
/// program with a pair, not the fit programs the held-out figures come from. Before, a
/// two-program log's report said the table clamps |Ṫ| to 1.25 × its fit program's fastest
/// rate while `table.bin` held 1.25 × the faster held-out program's.
#[test]
fn the_coverage_is_of_the_table_written() {
    let src = Source::parse(
        &cycling_csv(&quick(41), &truth(kt8_1_scale(), [1.2e-4, 2.5e-6, 1.5e-8], Extensions::NONE), 20.0),
        60.0,
    )
    .unwrap();
    let log = log_of(&src);
    let cal = calibrate_log(log, &CalibrateOptions::default()).unwrap();
    let r = &cal.report;
    assert!(r.fit_programs.len() < r.table_programs.len(), "a log whose table has more programs than its fit");
    assert_eq!(r.coverage.programs, r.table_programs);
    let table = &cal.table.hysteresis;
    let written = qfa_thermal::Table::decode(&table.to_bytes().unwrap()).unwrap();
    assert_eq!(r.coverage.table.rate_limit_c_per_min, f64::from(written.axes[0].rate_limit_c_per_min));
    // Every program's rows are in the coverage: as many rows as the table's programs' runs
    // have temperatures, counted here from the log itself.
    let rows: usize = log
        .runs
        .iter()
        .filter(|run| r.table_programs.contains(&run.program))
        .map(|run| run.samples.iter().filter(|s| s.temp_c.is_some_and(f64::is_finite)).count())
        .sum();
    assert!(r.coverage.covered.rows >= rows * 9 / 10, "{} rows covered of {rows}", r.coverage.covered.rows);
}
