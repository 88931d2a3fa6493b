//! The cycling-log reader: every malformed row reported with its line number; round trip;
//! one-row bursts skipped, recorded and said, and on the second independent generator's
//! logs with bursts, discovery then names nothing and leaves nothing unexplained.

mod common;
mod truth2;

use qfa_discover::{analyze, Channels, Report, Start};
use rayon::prelude::*;
use truth2::Draw;

use qfa_log::cycling::{read_log_from, write_log_to, Log, RowFault, Run, Sample};
use qfa_log::static_log::SkipCount;

const HEADER: &str = "program,run,time_s,input_g,temp_c,pulses,interval_s\n";

#[test]
fn every_malformed_row_is_reported_with_its_line() {
    let text = format!(
        "{HEADER}\
         p,0,1,1,,320000,1\n\
         p,0,2,1,22.0625,320001\n\
         p,0,3,1,abc,320002,1\n\
         p,0,4,1,22.0625,32x,1\n\
         p,0,1,1,22.0625,320003,1\n\
         p,0,5,0,22.0625,320003,1\n\
         p,0,6,1,22.0625,320004,0\n\
         p,0,7,1,22.0625,320005,1\n\
         p,,8,1,22.0625,320005,1\n\
         p,0,9,1,400,320005,1\n"
    );
    let err = read_log_from(text.as_bytes()).unwrap_err();
    let got: Vec<(u64, String)> = err.errors.iter().map(|e| (e.line, format!("{}", e.fault))).collect();
    println!("{err}");
    let lines: Vec<u64> = err.errors.iter().map(|e| e.line).collect();
    assert_eq!(lines, vec![3, 4, 5, 6, 7, 8, 10, 11], "{got:?}");
    assert_eq!(err.total, 8);
    assert_eq!(err.errors[0].fault, RowFault::FieldCount(6));
    assert!(matches!(&err.errors[1].fault, RowFault::Field { column: "temp_c", text } if text == "abc"));
    assert!(matches!(&err.errors[2].fault, RowFault::Field { column: "pulses", .. }));
    assert_eq!(err.errors[3].fault, RowFault::TimeNotIncreasing);
    assert_eq!(err.errors[4].fault, RowFault::InputChanged);
    assert!(matches!(&err.errors[5].fault, RowFault::Field { column: "interval_s", .. }));
    assert!(matches!(&err.errors[6].fault, RowFault::Field { column: "run", .. }));
    assert!(matches!(&err.errors[7].fault, RowFault::Field { column: "temp_c", text } if text == "400"));
    assert!(err.to_string().contains("line 4: bad temp_c `abc`"), "{err}");
}

#[test]
fn bad_header_is_line_one_and_empty_file_is_an_error() {
    let err =
        read_log_from("program,run,time,input_g,temp_c,pulses,interval_s\np,0,1,1,,1,1\n".as_bytes()).unwrap_err();
    assert_eq!(err.errors[0].line, 1);
    assert!(matches!(err.errors[0].fault, RowFault::Header(_)));
    assert!(read_log_from("".as_bytes()).is_err());
}

#[test]
fn write_then_read_round_trips_and_groups_runs() {
    let mk = |program: &str, run: &str, g: f64, t0: f64| Run {
        program: program.to_string(),
        run: run.to_string(),
        input_g: g,
        samples: (0..5)
            .map(|i| Sample {
                time_s: t0 + 10.0 * f64::from(i),
                temp_c: if i == 0 { None } else { Some(-12.5625 + f64::from(i) / 16.0) },
                pulses: -3_200_000 + i64::from(i),
                interval_s: 10.0,
            })
            .collect(),
    };
    let log = Log {
        runs: vec![
            mk("paper-0.3", "0", 1.0, 10.0),
            mk("paper-0.3", "rate0.3_pos2", -1.0, 10.0),
            mk("b", "1", 0.0, 10.0),
        ],
        ..Log::default()
    };
    let mut buf = Vec::new();
    write_log_to(&mut buf, &log).unwrap();
    let back = read_log_from(buf.as_slice()).unwrap();
    assert_eq!(back, log);
    // Interleaved rows of two runs are grouped back into their runs.
    let text = format!("{HEADER}a,0,1,1,,5,1\na,1,1,-1,,-5,1\na,0,2,1,,6,1\na,1,2,-1,,-6,1\n");
    let l = read_log_from(text.as_bytes()).unwrap();
    assert_eq!(l.runs.len(), 2);
    assert_eq!(l.runs[1].samples.iter().map(|s| s.pulses).collect::<Vec<_>>(), vec![-5, -6]);
}

/// A row written twice (the logger repeating itself) is skipped and counted with its line,
/// as the static reader skips a repeated timestamp: it holds no reading of its own, and the
/// rest of the log is calibrated (before, the whole log was refused). A row whose time goes
/// back with other values is two counts for one interval, and still refused.
#[test]
fn a_row_written_twice_is_skipped_and_counted() {
    let twice = "p,0,10,1,22.0625,320000,10\np,0,10,1,22.0625,320000,10\np,0,20,1,22.125,320010,10\n";
    let log = read_log_from(format!("{HEADER}{twice}").as_bytes()).unwrap();
    assert_eq!(log.repeated, SkipCount { count: 1, lines: vec![3] });
    assert_eq!(log.runs[0].samples.iter().map(|s| s.pulses).collect::<Vec<_>>(), [320_000, 320_010]);
    let findings = qfa_lint::lint_cycling(&log);
    let rows = findings.iter().find(|f| f.check == "rows").expect("a rows finding");
    assert!(rows.evidence.contains("1 row(s) written twice") && rows.evidence.contains("(line 3)"), "{rows}");
    let err = read_log_from(format!("{HEADER}{twice}p,0,20,1,22.125,320011,10\n").as_bytes()).unwrap_err();
    let faults: Vec<(u64, &RowFault)> = err.errors.iter().map(|e| (e.line, &e.fault)).collect();
    assert_eq!(faults, [(5, &RowFault::TimeNotIncreasing)], "{err}");
}

/// A burst of pulses in one row of a run (here 50 000 extra pulses in a 10-s row of a
/// +1 g ramp with ±3 pulses of noise) is skipped by the reader and recorded with its run,
/// time and count; a turn of the ramp, a step of the level and the noise are not. The same
/// row through `qfa-lab calibrate` is said in the verdict and listed in `report.json`, and
/// `qfa-lab compensate` says it too (its output holds the rows kept).
#[test]
fn a_burst_in_one_row_is_skipped_recorded_and_said() {
    let mut rng = qfa_rng::seeded(qfa_rng::stream_seed(53, qfa_rng::Stream::named("log reader test"), 1));
    let mut text = String::from(HEADER);
    for (run, g) in [("pos0", 1.0f64), ("pos2", -1.0)] {
        for i in 0..400u32 {
            let t = 10.0 * f64::from(i + 1);
            // Up 0.5 °C per row for 200 rows, then down; the level steps by 400 pulses at row 300.
            let leg = if i < 200 { f64::from(i) } else { f64::from(400 - i) };
            let temp = -10.0 + 0.5 * leg / 6.0;
            let step = if i >= 300 { 400.0 } else { 0.0 };
            let noise = (3.0 * qfa_rng::normal(&mut rng)).round();
            let mut pulses = g * 3_200_000.0 - 300.0 * temp + step + noise;
            if run == "pos0" && i == 123 {
                pulses += 50_000.0;
            }
            text.push_str(&format!("p,{run},{t},{g},{:.4},{pulses:.0},10\n", (temp * 16.0).round() / 16.0));
        }
    }
    let log = read_log_from(text.as_bytes()).unwrap();
    assert_eq!(log.glitches.len(), 1, "{:?}", log.glitches);
    let g = &log.glitches[0];
    assert_eq!((g.program.as_str(), g.run.as_str(), g.time_s), ("p", "pos0", 1240.0));
    assert_eq!(log.rows(), 799);
    assert!(log.runs[0].samples.iter().all(|s| s.time_s != 1240.0));
    let dir = std::env::temp_dir().join(format!("qfa-burst-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join("burst.csv");
    std::fs::write(&path, &text).unwrap();
    let out = dir.join("cal");
    let (ok, console) =
        common::lab(&["calibrate", "--log", path.to_str().unwrap(), "--no-plots", "--out", out.to_str().unwrap()]);
    println!("{console}");
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("report.json")).unwrap_or_default()).unwrap_or_default();
    // `compensate` writes the rows it kept and says which it skipped.
    let comp = dir.join("comp.csv");
    let table = out.join("table.bin");
    let (comp_ok, comp_console) = common::lab(&[
        "compensate",
        "--log",
        path.to_str().unwrap(),
        "--table",
        table.to_str().unwrap(),
        "--out",
        comp.to_str().unwrap(),
    ]);
    let comp_rows = std::fs::read_to_string(&comp).unwrap_or_default().lines().count();
    let _ = std::fs::remove_dir_all(&dir);
    assert!(comp_ok, "{comp_console}");
    assert!(comp_console.contains("799 rows (1 skipped as glitches, 0 as written twice)"), "{comp_console}");
    assert!(comp_console.contains("p pos0 at t = 1240 s"), "{comp_console}");
    assert_eq!(comp_rows, 1 + 799, "the header and the rows kept");
    assert!(console.contains("the reader skipped 1 row(s) as one-row glitches"), "ok {ok}: {console}");
    assert!(console.contains("p pos0 at t = 1240 s"), "{console}");
    assert_eq!(report["skipped_glitches"][0]["time_s"], 1240.0, "{report}");
}

/// Bursts of pulses in single seconds (20 000 pulses/s: 6 mg over a 10-s row at this
/// unit's 320 000 pulses/(g·s)), about one second in 5 000, on heavy-tailed clean logs
/// (nothing missing from the `simple` start): the reader skips the rows that hold a burst
/// and records them (`Log::glitches`); of the same logs without bursts it skips at most one
/// row in 5 000 (measured: none; a heavy-tailed draw past 10 robust σ and 2 mg would be a
/// one-row glitch too); discovery
/// then names nothing and leaves nothing unexplained. Before the reader skipped them, 11 of
/// the 16 seeds 1–16 got "unexplained" (run levels with χ² up to 135 against a critical
/// 11.1, change points in the level): the bursts' rows entered every least-squares fit, and
/// each held-out program inherited a fit moved by the other fold's bursts (seed 9: the
/// programs' median scale-factor residuals −6.1, +2.5, −5.5 and +1.2 ppm, against
/// −0.4…+0.4 without bursts), a level per run that the run-level test's clipping of single
/// bins cannot remove.
#[test]
fn bursts_in_single_rows_are_skipped_by_the_reader_and_not_read_as_structure() {
    let draws: Vec<Draw> = (1..=6u64)
        .map(|seed| Draw { glitches: true, heavy_tails: true, glitch_pulses_per_s: 20_000.0, ..Draw::clean(seed) })
        .collect();
    let out: Vec<(usize, usize, usize, usize, Vec<String>, Report)> = draws
        .par_iter()
        .map(|d| {
            let (text, trace) = truth2::cycling_traced(d);
            let log = qfa_log::cycling::read_log_from(text.as_bytes()).expect("reads");
            let twin = Draw { glitches: false, ..d.clone() };
            let twin_log = qfa_log::cycling::read_log_from(truth2::cycling(&twin).as_bytes()).expect("reads");
            let ch = Channels::parse(&text, 60.0).expect("the generated log parses");
            let r = analyze(&ch, Start::Simple);
            // Each skipped row, against the same row without bursts: a burst moves its count
            // by thousands of pulses.
            let twin_pulses = |g: &qfa_log::cycling::Glitch| {
                twin_log
                    .runs
                    .iter()
                    .filter(|run| run.program == g.program && run.run == g.run)
                    .flat_map(|run| &run.samples)
                    .find(|s| s.time_s == g.time_s)
                    .map(|s| s.pulses)
            };
            let not_bursts: Vec<String> = log
                .glitches
                .iter()
                .filter(|g| twin_pulses(g).is_none_or(|p| (g.pulses - p).abs() < 10_000))
                .map(|g| {
                    format!(
                        "{} {} t {} s: {} pulses, {:?} without bursts",
                        g.program,
                        g.run,
                        g.time_s,
                        g.pulses,
                        twin_pulses(g)
                    )
                })
                .collect();
            (log.glitches.len(), trace.glitch_seconds, twin_log.glitches.len(), twin_log.rows(), not_bursts, r)
        })
        .collect();
    for (d, (skipped, bursts, twin, rows, not_bursts, r)) in draws.iter().zip(&out) {
        println!(
            "seed {}: {bursts} burst seconds, {skipped} rows skipped ({twin} of {rows} without bursts); named {:?}, \
             unexplained {:?}",
            d.seed,
            r.effect_labels(),
            r.unexplained.iter().map(|u| &u.channel).collect::<Vec<_>>()
        );
        // At most one burst in ten missed (a 10-s row holds two now and then); rows without
        // a burst are skipped at most once in 5 000, as on the log without bursts.
        assert!(*skipped * 10 >= *bursts * 9, "{skipped} rows for {bursts} bursts");
        assert!(not_bursts.len() * 5_000 <= *rows, "{not_bursts:?}");
        assert!(*twin * 5_000 <= *rows, "{twin} of {rows} rows skipped without bursts");
        assert!(r.effects.is_empty() && r.unexplained.is_empty(), "{:?} {:?}", r.effect_labels(), r.unexplained);
    }
}

/// One row of a generated log: (run index, pulses, interval in tenths of a second, an
/// empty temperature, written twice).
type GenRow = (usize, i64, u32, bool, bool);

proptest::proptest! {
    #![proptest_config(proptest::prelude::ProptestConfig { cases: 256, ..Default::default() })]
    /// The reader takes any well-formed log and loses no row silently: the rows it keeps, the glitch rows
    /// it records and the rows it counts as written twice are the rows written, each glitch
    /// is a written row of its run (program, run, time, pulses, interval), each repeat is
    /// counted once, and a kept run is in time order. Logs of up to three runs, each row's
    /// pulses anything from quiet to a burst, its interval 0.1…60 s, one row in ten written
    /// twice.
    #[test]
    fn every_row_is_kept_or_recorded_as_a_glitch(
        rows in proptest::collection::vec(
            (0usize..3, proptest::prop_oneof![-5i64..5, 3_199_990i64..3_200_010, -10_000_000i64..10_000_000], 1u32..600, proptest::bool::ANY, proptest::bool::weighted(0.1)),
            0..120,
        )
    ) {
        let rows: Vec<GenRow> = rows;
        let mut text = String::from(HEADER);
        let mut written: Vec<(String, f64, i64, f64)> = Vec::new();
        let mut t = [0.0f64; 3];
        let mut twice_written = 0usize;
        for &(run, pulses, tenths, no_temp, twice) in &rows {
            let interval = f64::from(tenths) / 10.0;
            t[run] += interval;
            let temp = if no_temp { String::new() } else { "21.5".to_string() };
            let g = [1.0, -1.0, 0.0][run];
            let line = format!("p,r{run},{},{g},{temp},{pulses},{interval}\n", t[run]);
            text.push_str(&line);
            if twice {
                text.push_str(&line);
                twice_written += 1;
            }
            written.push((format!("r{run}"), t[run], pulses, interval));
        }
        // Every row written is well formed (a run's times increase, its input is constant), so
        // the reader takes the log: a row written twice is no reason to refuse it.
        let log = read_log_from(text.as_bytes()).map_err(|e| proptest::test_runner::TestCaseError::fail(e.to_string()))?;
        proptest::prop_assert_eq!(log.rows() + log.glitches.len(), written.len());
        proptest::prop_assert_eq!(log.repeated.count, twice_written);
        for g in &log.glitches {
            proptest::prop_assert!(
                written.iter().any(|w| (w.0.as_str(), w.1, w.2, w.3) == (g.run.as_str(), g.time_s, g.pulses, g.interval_s)),
                "{:?} was not written", g
            );
        }
        for r in &log.runs {
            proptest::prop_assert!(r.samples.windows(2).all(|w| w[0].time_s < w[1].time_s));
        }
    }
}
