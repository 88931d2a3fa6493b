use super::*;

#[test]
fn limits_refuse_a_unit_mistake_on_either_side_and_unknown_keys() {
    assert_eq!(Limits::from_toml("").unwrap(), Limits::default());
    assert_eq!(Limits::from_toml("held_out_bias_mg = 2.5").unwrap().held_out_bias_mg, 2.5);
    // µg typed into the mg key: too large to be mg.
    assert!(matches!(
        Limits::from_toml("held_out_bias_mg = 500"),
        Err(LimitsError::OutOfRange { key: "held_out_bias_mg", .. })
    ));
    // mg typed into the µg key: too small to be µg? 0.005 µg is below what any test resolves.
    assert!(matches!(
        Limits::from_toml("held_out_bias_ug = 0.005"),
        Err(LimitsError::OutOfRange { key: "held_out_bias_ug", .. })
    ));
    for bad in ["held_out_bias_mg = -1", "held_out_bias_mg = nan", "min_span_c = 400", "min_span_c = -5"] {
        assert!(matches!(Limits::from_toml(bad), Err(LimitsError::OutOfRange { .. })), "{bad}");
    }
    assert!(matches!(Limits::from_toml("held_out_bias = 5"), Err(LimitsError::Parse { .. })), "typo refused");
    assert!(matches!(Limits::from_toml("held_out_bias_mg = \"5\""), Err(LimitsError::Parse { .. })));
}

fn verdict(values: &[f64]) -> Verdict {
    let l = Limits::default();
    let axes: Vec<(String, f64)> = values.iter().enumerate().map(|(i, v)| (format!("a{i}"), *v)).collect();
    Verdict::new("a unit", "held out on the later leg", l.static_checks(&axes, 40.0))
}

#[test]
fn the_outcome_fails_on_any_failed_limit_and_on_a_figure_that_was_not_measured() {
    assert_eq!(verdict(&[1.0, 4.99]).outcome, Outcome::Pass);
    assert_eq!(verdict(&[1.0, 5.01]).outcome, Outcome::Fail);
    assert_eq!(verdict(&[1.0, f64::NAN]).outcome, Outcome::Fail, "NaN never passes");
    assert_eq!(Verdict::new("a study", "held out", vec![]).outcome, Outcome::Study);
    let v = verdict(&[1.0, 6.0]);
    assert_eq!(v.failed().len(), 1);
    assert!(v.failed()[0].contains("a1") && v.failed()[0].ends_with("(FAIL)"), "{:?}", v.failed());
    let nan = verdict(&[f64::NAN]);
    assert!(nan.console().contains("not computed") && !nan.console().contains("NaN"), "{}", nan.console());
    let json = json_with_verdict(&nan, &serde_json::json!({})).unwrap();
    assert!(!json.contains("NaN") && !json.contains("null"), "{json}");
}

#[test]
fn every_rendering_carries_the_same_lines() {
    let mut v = verdict(&[1.0, 6.0]);
    v.warnings.push("a step".into());
    v.files.push(FileUse::of("table.bin"));
    v.limits_from = "default limits".into();
    let lines: Vec<String> = v.lines().into_iter().map(|(k, t)| format!("{k}: {t}")).collect();
    let console: Vec<String> = v.console().lines().map(String::from).collect();
    assert_eq!(console, lines);
    let md: Vec<String> =
        v.markdown().lines().filter_map(|l| l.strip_prefix("- **")).map(|l| l.replacen(":** ", ": ", 1)).collect();
    assert_eq!(md, lines);
    let json: serde_json::Value =
        serde_json::from_str(&json_with_verdict(&v, &serde_json::json!({"x": 1})).unwrap()).unwrap();
    let jl: Vec<String> =
        json["verdict"]["lines"].as_array().unwrap().iter().map(|l| l.as_str().unwrap().to_string()).collect();
    assert_eq!(jl, lines);
    assert_eq!(json["x"], 1, "the report's own keys beside the verdict");
    assert!(lines[0].starts_with("verdict: FAIL against the default limits"), "{lines:?}");
}

#[test]
fn a_limits_file_for_the_other_kind_of_log_is_refused_and_partial_files_name_their_defaults() {
    let dir = std::env::temp_dir().join(format!("qfa-limits-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    let cyc = dir.join("cyc.toml");
    std::fs::write(&cyc, "held_out_bias_ug = 20\n").unwrap();
    let c = LimitsChoice::from_arg(Some(&cyc)).unwrap();
    assert!(matches!(c.check_applies("static", &STATIC_KEYS), Err(LimitsError::NoneApply { .. })));
    assert!(c.check_applies("cycling", &CYCLING_KEYS).is_ok());
    let checks = c.limits.cycling_checks("ax", 0.3, 9.0, 100.0);
    let from = c.source_for(&checks);
    assert!(from.ends_with("(defaults for held_out_sensitivity_ppm_per_c, min_span_c)"), "{from}");
    let empty = dir.join("empty.toml");
    std::fs::write(&empty, "").unwrap();
    let e = LimitsChoice::from_arg(Some(&empty)).unwrap().check_applies("static", &STATIC_KEYS).unwrap_err();
    assert!(e.to_string().contains("sets no key"), "{e}");
    assert!(LimitsChoice::default().check_applies("static", &STATIC_KEYS).is_ok(), "defaults need no file");
    let neg = Limits::from_toml("held_out_bias_mg = -1").unwrap_err().to_string();
    assert!(neg.ends_with("a limit is a positive number") && !neg.contains("µg"), "{neg}");
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn defaults_never_change_the_exit_status_a_limits_file_does() {
    let v = verdict(&[9.0]);
    assert!(!LimitsChoice::default().enforced_failure(&v));
    let c = LimitsChoice { limits: Limits::default(), file: Some("l.toml".into()), keys_set: vec![] };
    assert!(c.enforced_failure(&v));
    assert!(!c.enforced_failure(&verdict(&[1.0])));
}

/// A limits file that is not there is refused naming it, in the system's words (as
/// `std::io::Error` says it), and typed: the file and the error's kind.
#[test]
fn a_missing_limits_file_is_named_with_what_the_system_said() {
    let path = std::env::temp_dir().join("qfa-no-such-limits-file.toml");
    let system = std::fs::read_to_string(&path).expect_err("the file is not there");
    let e = Limits::from_file(&path).expect_err("refused");
    assert!(matches!(&e, LimitsError::Read { file, kind: std::io::ErrorKind::NotFound, .. } if *file == path), "{e:?}");
    assert_eq!(e.to_string(), format!("{}: {system}", path.display()));
}
