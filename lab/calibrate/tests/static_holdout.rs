//! Static calibration's held-out schemes, their refusals, and the coverage a log needs
//! before any fit.

use qfa_calibrate::static_cal::{check_coverage, resolve_holdout, Holdout, Scheme, StaticCalError, CV_FOLDS};
use qfa_log::spelling::Spelling;
use qfa_log::static_log::StaticLog;
use qfa_log::static_log::{read_static_from, AccelUnit, StaticOptions, TimeUnit};

/// A static log of `temps` at 1-s rows, one axis `az` = −1 g + 0.1 mg/°C.
fn log_of(temps: &[f64]) -> StaticLog {
    let mut text = String::from("time,temp,az\n");
    for (i, t) in temps.iter().enumerate() {
        text.push_str(&format!("{i},{t},{}\n", -1.0 + 1e-4 * t));
    }
    let opts = StaticOptions { time_unit: Some(TimeUnit::S), accel_unit: Some(AccelUnit::G), ..Default::default() };
    read_static_from(text.as_bytes(), &opts).unwrap()
}

#[test]
fn a_log_that_ends_at_its_hottest_is_held_out_by_blocks() {
    // Heating only: the maximum is the last row. `after-max` asked for is refused with
    // that reason; `auto` resolves to blocks and names it.
    let log = log_of(&(0..400).map(|i| 20.0 + 0.05 * f64::from(i)).collect::<Vec<_>>());
    let e = resolve_holdout(&log, Holdout::AfterMax, 10).unwrap_err();
    assert_eq!(
        e.to_string(),
        "held-out split: the highest temperature (39.95 °C) is at row 400 of 400: fewer than a tenth of the \
         rows lie after it, no later leg to evaluate on"
    );
    let (scheme, rule) = resolve_holdout(&log, Holdout::Auto, 10).unwrap();
    assert_eq!(scheme, Scheme::Blocks { k: CV_FOLDS });
    assert!(rule.starts_with("auto: the highest temperature (39.95 °C) is at row 400 of 400"), "{rule}");
    assert_eq!(scheme.folds(400), vec![0..80, 80..160, 160..240, 240..320, 320..400]);
}

#[test]
fn a_log_with_a_later_leg_is_held_out_after_its_maximum() {
    let mut t: Vec<f64> = (0..300).map(|i| 20.0 + 0.1 * f64::from(i)).collect();
    t.extend((0..100).map(|i| 49.9 - 0.1 * f64::from(i)));
    let log = log_of(&t);
    // Heating then cooling: `auto` takes blocks here (the rows before the later leg hold one
    // branch; `several_cycles_hold_out_everything_after_the_first_maximum`), `after-max`
    // by name splits at the maximum.
    assert_eq!(resolve_holdout(&log, Holdout::AfterMax, 10).unwrap().0, Scheme::AfterMax { last: 299 });
    assert_eq!(Scheme::AfterMax { last: 299 }.folds(400), vec![300..400]);
    // Blocks too large for the log are refused with the reason.
    let e = resolve_holdout(&log, Holdout::Blocks(50), 10).unwrap_err();
    assert_eq!(
        e.to_string(),
        "--holdout blocks:50: 400 rows make blocks of 8 rows; a held-out block needs at least 10 (one averaged \
         equation)"
    );
    assert!(e.message(Spelling::Python).starts_with("holdout=\"blocks:50\": 400 rows"), "{e:?}");
}

/// A run cut short while it warmed up again: its highest reading falls in the first hold
/// (by a 1/16-°C flicker at row 791), so the rows before it are a hold at one temperature.
/// `auto` once took `after-max` there and every fold's fit failed on a 0.1-°C span; now it
/// takes blocks and says why. `after-max` asked for by name is still run as asked.
#[test]
fn auto_does_not_hold_out_a_later_leg_its_training_rows_cannot_fit() {
    let mut t: Vec<f64> = vec![25.0; 900];
    t[790] = 25.0625;
    t.extend((1..=1350).map(|i| 25.0 - f64::from(i) / 30.0));
    t.extend(std::iter::repeat_n(-20.0, 900));
    t.extend((1..=1125).map(|i| -20.0 + f64::from(i) / 30.0));
    let log = log_of(&t);
    let (scheme, rule) = resolve_holdout(&log, Holdout::Auto, 10).unwrap();
    assert_eq!(scheme, Scheme::Blocks { k: CV_FOLDS }, "{rule}");
    assert!(rule.contains("cannot hold the bias grid"), "{rule}");
    assert_eq!(resolve_holdout(&log, Holdout::AfterMax, 10).unwrap().0, Scheme::AfterMax { last: 790 });
    // A later leg that leaves the training range (25 → 70 → −20) is not scored as one.
    let mut t: Vec<f64> = (0..450).map(|i| 25.0 + 0.1 * f64::from(i)).collect();
    t.extend((0..900).map(|i| 70.0 - 0.1 * f64::from(i)));
    let (scheme, rule) = resolve_holdout(&log_of(&t), Holdout::Auto, 10).unwrap();
    assert_eq!(scheme, Scheme::Blocks { k: CV_FOLDS }, "{rule}");
    assert!(rule.contains("extrapolation"), "{rule}");
}

#[test]
fn several_cycles_hold_out_everything_after_the_first_maximum() {
    // A cooling leg 35 → 20 °C, then two cycles 20 → 50 → 20 °C, the second peaking 0.5 °C
    // lower: the later leg is everything after the first peak (the second cycle included).
    let mut t: Vec<f64> = (0..150).map(|i| 35.0 - 15.0 * f64::from(i) / 150.0).collect();
    for peak in [50.0, 49.5] {
        t.extend((0..300).map(|i| 20.0 + (peak - 20.0) * f64::from(i) / 300.0));
        t.extend((0..300).map(|i| peak - (peak - 20.0) * f64::from(i) / 300.0));
    }
    let log = log_of(&t);
    let (scheme, rule) = resolve_holdout(&log, Holdout::Auto, 10).unwrap();
    assert_eq!(scheme, Scheme::AfterMax { last: 450 }, "{rule}");
    assert!(rule.contains("evaluate on rows 452..=1350"), "{rule}");
    // Without the first cooling leg the rows up to the peak heat only, while the log also
    // cools: they could not fit the heating/cooling terms a table of the whole log may
    // hold, so `auto` takes blocks and says why; `after-max` by name still runs.
    let log = log_of(&t[150..]);
    let (scheme, rule) = resolve_holdout(&log, Holdout::Auto, 10).unwrap();
    assert_eq!(scheme, Scheme::Blocks { k: CV_FOLDS }, "{rule}");
    assert!(rule.contains("hold one branch (") && rule.contains("while the log holds both"), "{rule}");
    assert_eq!(resolve_holdout(&log, Holdout::AfterMax, 10).unwrap().0, Scheme::AfterMax { last: 300 });
    assert_eq!(scheme.selection_folds(), CV_FOLDS);
    assert_eq!(Scheme::Blocks { k: 7 }.selection_folds(), 7);
}

#[test]
fn coverage_refuses_a_small_span_and_a_sparse_part_of_the_span() {
    let e = check_coverage(&(0..300).map(|i| 25.0 + 0.001 * f64::from(i)).collect::<Vec<_>>(), 16, 10);
    assert_eq!(
        e.unwrap_err().to_string(),
        "the temperature span is too small: 0.30 °C (25.00..25.30 °C); the model needs at least 1.50 °C (16 \
         bias-grid nodes at least 0.1 °C apart, the root crate's smallest grid step)"
    );
    // 20 → 50 °C with a jump over 30..40 °C: the intervals there hold no row.
    let mut t: Vec<f64> = (0..1000).map(|i| 20.0 + 0.01 * f64::from(i)).collect();
    t.extend((0..1000).map(|i| 40.0 + 0.01 * f64::from(i)));
    let e = check_coverage(&t, 16, 10).unwrap_err();
    assert!(matches!(e, StaticCalError::TooFewRowsPerDegree { rows: 0, needed: 10, intervals: 15, .. }), "{e}");
    assert!(check_coverage(&(0..2000).map(|i| 20.0 + 0.015 * f64::from(i)).collect::<Vec<_>>(), 16, 10).is_ok());
}
