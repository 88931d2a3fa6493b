use super::*;

fn opts() -> StaticOptions {
    StaticOptions { time_unit: Some(TimeUnit::Ms), accel_unit: Some(AccelUnit::Mg), ..Default::default() }
}

#[test]
fn glitch_row_is_skipped_and_counted() {
    let mut text = String::from("time\ttemp\taz\n0\t20\t1050\n");
    for i in 1..40 {
        text.push_str(&format!("{}\t{}\t1000\n", i * 500, 20.0 + 0.01 * f64::from(i)));
    }
    let log = read_static_from(text.as_bytes(), &opts()).unwrap();
    // Line 2 is 50 mg off its neighbours (σ ≈ 0): a glitch.
    assert_eq!(log.skipped.glitch, SkipCount { count: 1, lines: vec![2] });
    assert_eq!(log.rows(), 39);
    assert_eq!(log.time_s[0], 0.0);
    assert!((log.axes[0].accel_g[0] - 1.0).abs() < 1e-12);
}

#[test]
fn slew_is_the_largest_range_in_a_minute_and_ignores_two_bad_rows() {
    // 1-s rows: hold 20 °C, ramp at 6 °C/min (0.1 °C per row) to 40 °C, hold. The
    // fastest minute holds 61 rows, 6.0 °C.
    let temp: Vec<f64> = (0..600).map(|i| 20.0 + 0.1 * f64::from((i - 100).clamp(0, 200))).collect();
    let time: Vec<f64> = (0..600).map(f64::from).collect();
    let s = max_slew(&time, &temp);
    assert!((s.c_per_min - 6.0).abs() < 1e-9 && (s.range_c - 6.0).abs() < 1e-9, "{s:?}");
    assert_eq!((s.window_s, s.to - s.from), (60.0, 60));
    // Two 85 °C readings in a row (a DS18B20's power-on value) do not count.
    let mut spiked = temp.clone();
    spiked[50] = 85.0;
    spiked[51] = 85.0;
    assert!((max_slew(&time, &spiked).c_per_min - 6.0).abs() < 1e-9);
    // Shorter than a minute: the whole log is the window. 20 K in 0.6 s.
    let fast: Vec<f64> = time.iter().map(|t| t * 1e-3).collect();
    let s = max_slew(&fast, &temp);
    assert!((s.c_per_min - 20.0 / 0.599 * 60.0).abs() < 1e-6, "{s:?}");
}

#[test]
fn decimal_commas_are_named_or_read() {
    let text = "time;temp;az\n".to_string() + &(0..40).map(|i| format!("{i};20,{i:02};-1,0\n")).collect::<String>();
    let o = StaticOptions { time_unit: Some(TimeUnit::S), accel_unit: Some(AccelUnit::G), ..Default::default() };
    let e = read_static_from(text.as_bytes(), &o).unwrap_err();
    assert_eq!(
        e.to_string(),
        "column `temp` holds `20,00` at line 2: a decimal comma? 40 row(s) have numbers like it; pass \
         --decimal-comma to read them"
    );
    let log = read_static_from(text.as_bytes(), &StaticOptions { decimal_comma: true, ..o.clone() }).unwrap();
    assert_eq!(log.temp_c[..2], [20.0, 20.01]);
    assert_eq!(log.axes[0].accel_g[0], -1.0);
    // A comma-separated file cannot carry decimal commas.
    let e = read_static_from("time,temp,az\n".as_bytes(), &StaticOptions { decimal_comma: true, ..o }).unwrap_err();
    assert_eq!(e, StaticError::DecimalCommaDelimiter);
}

#[test]
fn duplicates_skipped_gaps_reported_units_from_names() {
    // Units from the names (ms, g); line 4 repeats line 3's time; a 40-s gap after line 20.
    let mut text = String::from("time_ms,temp_c,ax_g\n");
    let mut t = 0u64;
    for i in 0..40u64 {
        text.push_str(&format!("{t},{},0.001\n", 20.0 + 0.001 * i as f64));
        if i != 1 {
            t += if i == 18 { 40_000 } else { 1000 };
        }
    }
    let log = read_static_from(text.as_bytes(), &StaticOptions::default()).unwrap();
    assert_eq!(log.skipped.duplicate, SkipCount { count: 1, lines: vec![4] });
    assert_eq!(log.rows(), 39);
    assert_eq!(log.sampling.median_interval_s, 1.0);
    assert_eq!((log.sampling.gaps_over_30s, log.sampling.irregular_intervals), (1, 1));
    assert_eq!(log.sampling.max_interval_s, 40.0);
    assert_eq!(log.columns[0], ("time".into(), "time_ms".into(), "ms".into()));
    // Without a unit in the name or a flag: an error naming the flag.
    let e = read_static_from("timestamp,temp_c,ax_g\n0,20,0\n".as_bytes(), &StaticOptions::default()).unwrap_err();
    assert_eq!(e.to_string(), "the unit of column `timestamp` is not known: pass --time-unit s|ms|us|ns");
}

/// A `--columns` map that names an axis names the axes: `ax` and `ay` named on a log with an
/// `az` column read two axes; a map naming none (the time alone) finds all three by their
/// common names. Before, the first read `az` as well.
#[test]
fn a_columns_map_naming_axes_reads_those_axes_only() {
    let text = String::from("time\ttemp\tax\tay\taz\n")
        + &(0..40).map(|i| format!("{}\t{}\t1\t2\t-1000\n", i * 500, 20.0 + 0.01 * f64::from(i))).collect::<String>();
    let with = |map: &str| StaticOptions { columns: map.parse().unwrap(), ..opts() };
    let names = |o: &StaticOptions| {
        read_static_from(text.as_bytes(), o).unwrap().axes.iter().map(|a| a.name.clone()).collect::<Vec<_>>()
    };
    assert_eq!(names(&with("time=time,temp=temp,ax=ax,ay=ay")), ["ax", "ay"]);
    assert_eq!(names(&with("az=az")), ["az"]);
    assert_eq!(names(&with("time=time")), ["ax", "ay", "az"]);
    assert_eq!(names(&opts()), ["ax", "ay", "az"]);
}
