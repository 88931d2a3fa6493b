//! The cycling-log reader: every malformed row reported with its line number; round trip.

use qfa_log::cycling::{read_log_from, write_log_to, Log, RowFault, Run, Sample};

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
