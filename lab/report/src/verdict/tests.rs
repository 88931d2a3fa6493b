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
    let axes: Vec<(String, Measured)> =
        values.iter().enumerate().map(|(i, v)| (format!("a{i}"), Measured::Value(*v))).collect();
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
    // A study checks no limit and names no source of limits: no key, never "".
    let study = Verdict::new("a study", "held out", vec![]);
    let json: serde_json::Value =
        serde_json::from_str(&json_with_verdict(&study, &serde_json::json!({})).unwrap()).unwrap();
    assert!(json["verdict"].get("limits_from").is_none(), "{json}");
    let mut checked = verdict(&[1.0]);
    checked.limits_from = "default limits".into();
    let json: serde_json::Value =
        serde_json::from_str(&json_with_verdict(&checked, &serde_json::json!({})).unwrap()).unwrap();
    assert_eq!(json["verdict"]["limits_from"], "default limits");
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
    let checks = c.limits.cycling_checks("ax", Measured::Value(0.3), Measured::Value(9.0), 100.0);
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

/// Over random figures (values, figures not computed, not finite) and merges of random
/// parts: a verdict fails exactly when it has a failed line to give, and each such line
/// says why (its figure, or why none). A FAIL with nothing to say is what a batch once
/// printed as "fail: SN0002: " for a unit logged through one program.
#[test]
fn a_verdict_fails_exactly_when_it_can_say_which_limit_and_why() {
    let l = Limits::default();
    let mut seed = 0x9e37_79b9_7f4a_7c15_u64;
    let mut next = move || {
        seed = seed.wrapping_mul(6_364_136_223_846_793_005).wrapping_add(1_442_695_040_888_963_407);
        (seed >> 11) as f64 / (1u64 << 53) as f64
    };
    let mut figure = || match next() {
        x if x < 0.15 => Measured::NotComputed { not_computed: "one program only".into() },
        x if x < 0.2 => Measured::Value(f64::NAN),
        x => Measured::Value(10.0 * x),
    };
    for _ in 0..500 {
        let parts: Vec<(String, Verdict)> = (0..3)
            .map(|p| {
                let axes: Vec<(String, Measured)> = (0..3).map(|a| (format!("a{a}"), figure())).collect();
                let cyc = l.cycling_checks("u", figure(), figure(), 40.0);
                let checks = if p % 2 == 0 { l.static_checks(&axes, 40.0) } else { cyc };
                (format!("p{p}"), Verdict::new("a unit", "held out", checks))
            })
            .collect();
        let merged = Verdict::merge(&parts, "default limits", vec![]);
        for v in parts.iter().map(|(_, v)| v).chain([&merged]) {
            let failed = v.failed();
            assert_eq!(v.outcome == Outcome::Fail, !failed.is_empty(), "{failed:?}");
            for line in &failed {
                assert!(line.ends_with("(FAIL)") && !line.contains("NaN"), "{line}");
            }
        }
    }
}
