//! Production batches: a simulated chamber run of many units through `qfa-lab batch`,
//! judged against the truth the simulator wrote (which units are bad and why, each unit's
//! curve), and the outputs' independence of threads and shards.

mod common;

use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

use qfa_batch::fleet::Decision;
use qfa_batch::input::{from_chamber_log, UnitInput};
use qfa_batch::unit::{ResidualStep, UnitOptions, UnitOutcome, UnitResult};
use qfa_batch::{BatchOptions, Shard};
use qfa_log::open::ReadFlags;
use qfa_log::static_log::columns::{AccelUnit, TimeUnit};
use qfa_log::units::TempUnit;
use qfa_sim::population::{draw, write_chamber, Defect, PopulationSpec, PopulationTruth, UnitTruth, SPREAD};

fn scratch(name: &str) -> PathBuf {
    let d = PathBuf::from(env!("CARGO_TARGET_TMPDIR")).join(name);
    let _ = std::fs::remove_dir_all(&d);
    std::fs::create_dir_all(&d).unwrap();
    d
}

fn flags() -> ReadFlags {
    ReadFlags {
        time_unit: Some(TimeUnit::S),
        accel_unit: Some(AccelUnit::G),
        temp_unit: Some(TempUnit::C),
        ..ReadFlags::default()
    }
}

/// A chamber log of `spec`'s units in `dir`, split into units.
fn chamber(dir: &Path, spec: &PopulationSpec) -> (PopulationTruth, Vec<UnitInput>) {
    let truth = draw(spec);
    write_chamber(dir, &truth).unwrap();
    let path = dir.join("chamber.tsv");
    let units = from_chamber_log(&path, &std::fs::read(&path).unwrap(), &flags()).unwrap();
    (truth, units)
}

/// Every file under `dir`, relative path → bytes.
fn tree(dir: &Path) -> BTreeMap<PathBuf, Vec<u8>> {
    let mut out = BTreeMap::new();
    let mut stack = vec![dir.to_path_buf()];
    while let Some(d) = stack.pop() {
        for e in std::fs::read_dir(&d).unwrap() {
            let p = e.unwrap().path();
            if p.is_dir() {
                stack.push(p);
            } else {
                out.insert(p.strip_prefix(dir).unwrap().to_path_buf(), std::fs::read(&p).unwrap());
            }
        }
    }
    out
}

/// The figure a defect moves (what the flag must name).
fn moved_by(d: Defect) -> &'static [&'static str] {
    match d {
        Defect::DriftingSensor => &["sensor.drift_c_per_h"],
        Defect::Hysteresis3x => {
            &["ax.split_mg", "ay.split_mg", "az.split_mg", "ax.ramp_split_mg", "ay.ramp_split_mg", "az.ramp_split_mg"]
        }
        // A 6-mg shift part-way through bends every curve fitted across it: any of the
        // axes' figures (the test also asks for the shift named, with its time and size).
        Defect::Damaged => &[
            "ax.level_mg",
            "ax.slope_ug_per_c",
            "ax.curvature_ug_per_c2",
            "ax.split_mg",
            "ax.ramp_split_mg",
            "ax.held_out_mg",
            "ay.level_mg",
            "ay.slope_ug_per_c",
            "ay.curvature_ug_per_c2",
            "ay.split_mg",
            "ay.ramp_split_mg",
            "ay.held_out_mg",
            "az.level_mg",
            "az.slope_ug_per_c",
            "az.curvature_ug_per_c2",
            "az.split_mg",
            "az.ramp_split_mg",
            "az.held_out_mg",
        ],
    }
}

/// The steps a unit's own residuals hold ([`ResidualStep`]).
fn unit_steps(results: &[(usize, UnitResult)], serial: &str) -> Vec<ResidualStep> {
    match &results.iter().find(|r| r.1.serial == serial).expect("the unit has a result").1.outcome {
        UnitOutcome::Calibrated(c) => c.steps.clone(),
        UnitOutcome::Failed { reason } => panic!("{serial} not calibrated: {reason}"),
    }
}

/// The damaged unit's reasons name, on every axis, the shock the generator drew: its size
/// and sign (within a tenth), its time (60 % of the rows, within 2 % of the run) and that it
/// is not thermal.
fn assert_names_the_shock(u: &UnitTruth, results: &[(usize, UnitResult)], reasons: &[String]) {
    let steps = unit_steps(results, &u.serial);
    for (k, axis) in ["ax", "ay", "az"].iter().enumerate() {
        let s = steps
            .iter()
            .find(|s| s.axis == *axis)
            .unwrap_or_else(|| panic!("{}: no step on {axis}: {steps:?}", u.serial));
        let want_mg = u.shock_g[k] * 1e3;
        assert!((s.size_mg - want_mg).abs() < 0.1 * want_mg.abs(), "{} {axis}: {s:?} against {want_mg} mg", u.serial);
        assert!((s.at_s / s.run_s - 0.6).abs() < 0.02, "{} {axis}: {s:?}", u.serial);
        assert!(s.thermal_share < 0.1, "{} {axis}: {s:?}", u.serial);
        let said = reasons.iter().any(|r| {
            r.starts_with(&format!("{axis} stepped by {:+.2} mg at t = {:.0} s", s.size_mg, s.at_s))
                && r.ends_with("not thermal")
        });
        assert!(said, "{} {axis}: {reasons:?}", u.serial);
    }
}

/// 20 units, one of each defect per started 50 (3 bad): every bad unit is held back
/// (REVIEW or FAIL) with its strongest flag on a figure its defect moves; every good unit
/// passes; and every good unit's fleet figures agree with the truth it was drawn from, to
/// a small share of the population's spread (the descriptor measures what it says).
#[test]
fn a_chamber_run_flags_each_bad_unit_for_its_defect_and_passes_the_rest() {
    let dir = scratch("batch-flags");
    // 20 units in CI (about 2 s of CPU each); `flag_study` below runs hundreds.
    let spec = PopulationSpec { units: 20, seed: 3, bad: true, truncated: 0, die_lags: false };
    let (truth, units) = chamber(&dir, &spec);
    let out = dir.join("out");
    let run = qfa_batch::run(&units, &out, &BatchOptions { threads: 2, ..BatchOptions::default() }).unwrap();
    let fleet = run.fleet.unwrap();
    let (mut bad, mut good) = (0, 0);
    for (u, f) in truth.unit.iter().zip(&fleet.unit) {
        assert_eq!(u.serial, f.serial);
        match u.defect {
            Some(d) => {
                bad += 1;
                assert_ne!(f.decision, Decision::Pass, "{} ({d:?}) passed", u.serial);
                let top = f.flags.first().unwrap_or_else(|| panic!("{} ({d:?}): no flag; {:?}", u.serial, f.reasons));
                assert!(
                    moved_by(d).contains(&top.feature.as_str()),
                    "{} ({d:?}): strongest flag {}",
                    u.serial,
                    top.text
                );
                if d == Defect::Damaged {
                    // The shift itself, named where and how large, not thermal. (Its held-out
                    // figure is not asked for: when the search's cross-validation scored only
                    // the rows each fold's grid covers, SN0013's model took the shift, which
                    // falls on a heating/cooling turn, as its branch split, flagged at −48
                    // robust SDs, and carried it into the held-out leg.)
                    assert_names_the_shock(u, &run.results, &f.reasons);
                }
            }
            None => {
                good += 1;
                assert_eq!(f.decision, Decision::Pass, "{}: {:?}", u.serial, f.reasons);
                // No shock was drawn: no step that is not thermal stands out of its residual
                // (the fleet's rule for a shock). A step most of which the temperature's own
                // change across it explains is a ramp's, not a shock: SN0014 showed one
                // (z 11.6, −0.10 mg, 77 % thermal; now under its row noise, so not a step at
                // all) since the branch waits for a partial
                // window's own flicker floor at the log's start, which moves its fit a little.
                // A step at a turn of the branch is the unit's split, said as such.
                let steps = unit_steps(&run.results, &u.serial);
                let shocks: Vec<_> = steps
                    .iter()
                    .filter(|s| s.thermal_share < qfa_batch::unit::NOT_THERMAL_SHARE && s.at_turn.is_none())
                    .collect();
                assert!(shocks.is_empty(), "{}: {shocks:?}", u.serial);
            }
        }
    }
    assert_eq!((bad, good), (3, 17));
    // The descriptor against the truth, on the good units: slope, level and split.
    let stats: BTreeMap<&str, BTreeMap<&str, f64>> = fleet
        .stats
        .iter()
        .map(|s| (s.feature.name.as_str(), s.values.iter().map(|(k, v)| (k.as_str(), *v)).collect()))
        .collect();
    let mut split_errors = Vec::new();
    for u in truth.unit.iter().filter(|u| u.defect.is_none()) {
        for (k, axis) in ["ax", "ay", "az"].iter().enumerate() {
            let c = &u.axes[k];
            let got = |f: &str| stats[format!("{axis}.{f}").as_str()][u.serial.as_str()];
            // The fleet reads each unit at its own sensor's 25 °C, where the die is at
            // 25 °C less the sensor's offset (0.5 °C SD): the truth is taken there. (Read at
            // the die's 25 °C instead, SN0009 of a later draw, offset +1.56 °C, missed by
            // 2.3 µg/°C; at its sensor's, 1.5.) A tenth of the population's spread for the
            // slope, a sixth for the level.
            let die_c = 25.0 - u.sensor_offset_c;
            let mid = |t: f64| 0.5 * (c.at(t, true) + c.at(t, false));
            let truth_slope_ug_per_c = (mid(die_c + 0.5) - mid(die_c - 0.5)) * 1e6;
            let slope = (got("slope_ug_per_c") - truth_slope_ug_per_c).abs();
            assert!(slope < 0.1 * SPREAD.c1 * 1e6, "{} {axis}: slope off by {slope} µg/°C", u.serial);
            let level = (got("level_mg") - mid(die_c) * 1e3).abs();
            assert!(level < SPREAD.level_g * 1e3 / 6.0, "{} {axis}: level off by {level} mg", u.serial);
            split_errors.push(got("split_mg") - c.split_g * 1e3);
        }
    }
    // The split is the unit's own model's, which one chamber cycle does not always tell
    // from a lag or a creep (both give a heating/cooling difference that grows with the
    // ramp's rate): where the search gave the hysteresis to one of them the figure reads
    // low. Most axes are within a third of the hysteresis defect's own size (it adds twice
    // the split, ≥ 0.12 mg on ay), and the fleet's median is not moved. Measured on this
    // seed when the split was first read from the units' models: 43 of 51 within, median
    // error −0.01 mg; the bounds below were set then.
    let within = split_errors.iter().filter(|e| e.abs() < 0.08).count();
    let mut sorted = split_errors.clone();
    sorted.sort_by(f64::total_cmp);
    let median_error = sorted[sorted.len() / 2];
    println!(
        "split: {within} of {} good axes within 0.08 mg of the truth, median error {median_error:+.3} mg",
        sorted.len()
    );
    assert!(within * 4 >= sorted.len() * 3, "{within} of {} within 0.08 mg: {split_errors:?}", sorted.len());
    assert!(median_error.abs() < 0.03, "median split error {median_error} mg");
    // The sensor's figures against the truth on the good units: no drift was drawn, and each
    // offset is the drawn one less the fleet's median (its units' cases lag the air by
    // 60–170 s each, so a minute where one unit's reading still moves is left out).
    let good: Vec<(&qfa_sim::population::UnitTruth, &qfa_batch::fleet::FleetUnit)> =
        truth.unit.iter().zip(&fleet.unit).filter(|(u, _)| u.defect.is_none()).collect();
    let mut offsets: Vec<f64> = good.iter().map(|(u, _)| u.sensor_offset_c).collect();
    offsets.sort_by(f64::total_cmp);
    let value = |m: &qfa_report::verdict::Measured| match m {
        qfa_report::verdict::Measured::Value(v) => *v,
        qfa_report::verdict::Measured::NotComputed { not_computed } => panic!("not computed: {not_computed}"),
    };
    let drift = good.iter().map(|(_, f)| value(&f.sensor_drift_c_per_h).abs()).fold(0.0, f64::max);
    let offset = good
        .iter()
        .map(|(u, f)| (value(&f.sensor_offset_c) - (u.sensor_offset_c - offsets[offsets.len() / 2])).abs())
        .fold(0.0, f64::max);
    println!("sensor: good units' largest drift {drift:.4} °C/h, largest offset error {offset:.4} °C");
    assert!(drift < 0.02 && offset < 0.03, "drift {drift} °C/h, offset error {offset} °C");
    // Every unit has its certificate, naming the CRC in its table's header.
    for r in &run.results {
        let cert: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(out.join(&r.1.serial).join("certificate.json")).unwrap())
                .unwrap();
        let bin = std::fs::read(out.join(&r.1.serial).join("table.bin")).unwrap();
        let crc = u32::from_le_bytes(bin[12..16].try_into().unwrap());
        assert_eq!(qfa_thermal::table::crc32(&bin[16..]), crc, "{}: header CRC", r.1.serial);
        assert_eq!(cert["unit"]["calibrated"]["table_crc32"], format!("{crc:08x}"), "{}", r.1.serial);
    }
    common::browser::assert_page(&out.join("fleet.html"), 2);
    let bad_unit = truth.unit.iter().find(|u| u.defect.is_some()).unwrap();
    common::browser::assert_page(&out.join(&bad_unit.serial).join("certificate.html"), 0);
}

/// One 20-unit chamber run whose units' dies lag their temperature sensors, each by its own
/// 0–240 s: per bad unit, its defect and the robust distance of its strongest flag on a
/// figure that defect moves (`None`: not flagged for it); and the good units held back.
fn die_lag_run(seed: u64) -> (Vec<(Defect, Option<f64>)>, Vec<String>) {
    let dir = scratch(&format!("batch-die-lags-{seed}"));
    let (truth, units) = chamber(&dir, &PopulationSpec { units: 20, seed, bad: true, truncated: 0, die_lags: true });
    let run =
        qfa_batch::run(&units, &dir.join("out"), &BatchOptions { threads: 2, ..BatchOptions::default() }).unwrap();
    let fleet = run.fleet.unwrap();
    let (mut bad, mut held_back) = (Vec::new(), Vec::new());
    for (u, f) in truth.unit.iter().zip(&fleet.unit) {
        assert_eq!(u.serial, f.serial);
        match u.defect {
            Some(d) => {
                let z = f
                    .flags
                    .iter()
                    .filter(|g| moved_by(d).contains(&g.feature.as_str()))
                    .map(|g| g.z.abs())
                    .reduce(f64::max);
                bad.push((d, z.filter(|_| f.decision != Decision::Pass)));
            }
            None if f.decision != Decision::Pass => held_back.push(format!("{}: {:?}", u.serial, f.reasons)),
            None => {}
        }
    }
    (bad, held_back)
}

/// A unit with three times the fleet's heating/cooling split stands out of a fleet whose
/// dies lag their sensors by different times, and no good unit is held back. A split read
/// from a cubic and a constant step fitted beside each unit's model took each die's lag for
/// a split (a lag's apparent split is the slope × τ × the ramp's rate), and the lags'
/// spread hid the 3× unit at 2.2 robust SDs on this seed; the split read from the unit's
/// own model at a vanishing rate leaves the lag to the model's lag slot. Seed 1 is the
/// first seed; `die_lag_study` below gives the rate over more.
#[test]
fn a_unit_with_three_times_the_split_stands_out_when_the_dies_lag_differently() {
    let (bad, held_back) = die_lag_run(1);
    assert!(held_back.is_empty(), "{held_back:?}");
    for (d, z) in &bad {
        assert!(z.is_some(), "{d:?} not flagged for its figure: {bad:?}");
    }
}

/// The rate behind the test above: seeds 1–6, each 3× unit's strongest split distance and
/// the good units held back
/// (`cargo test --release -p qfa-lab --test batch -- --ignored die_lag_study --nocapture`).
#[test]
#[ignore = "a study: about a minute in release"]
fn die_lag_study() {
    for seed in 1..=6 {
        let (bad, held_back) = die_lag_run(seed);
        let split = bad.iter().find(|(d, _)| *d == Defect::Hysteresis3x).and_then(|(_, z)| *z);
        let others = bad.iter().filter(|(d, z)| *d != Defect::Hysteresis3x && z.is_some()).count();
        println!(
            "seed={seed} hysteresis3x_z={} other_defects_flagged={others} of 2 good_held_back={}",
            split.map_or("not flagged".to_string(), |z| format!("{z:.1}")),
            held_back.len()
        );
    }
}

/// The same batch at 1 and 2 threads writes the same bytes in every file; run as two
/// shards into one folder and merged, it writes the same fleet and certificates.
#[test]
fn threads_and_shards_do_not_change_a_byte() {
    let dir = scratch("batch-threads");
    // Two units: each thread and each shard gets one.
    let spec = PopulationSpec { units: 2, seed: 9, bad: true, truncated: 0, die_lags: false };
    let (_, units) = chamber(&dir, &spec);
    let opts = |threads, shard| BatchOptions { unit: UnitOptions::default(), threads, shard, progress: false };
    qfa_batch::run(&units, &dir.join("one"), &opts(1, None)).unwrap();
    qfa_batch::run(&units, &dir.join("two"), &opts(2, None)).unwrap();
    let (one, two) = (tree(&dir.join("one")), tree(&dir.join("two")));
    assert_eq!(one.len(), two.len());
    for (path, bytes) in &one {
        assert!(two.get(path) == Some(bytes), "{} differs between 1 and 2 threads", path.display());
    }
    let sharded = dir.join("sharded");
    for k in [1, 0] {
        let run = qfa_batch::run(&units, &sharded, &opts(2, Some(Shard { k, n: 2 }))).unwrap();
        assert!(run.fleet.is_none());
        assert_eq!(run.results.len(), 1);
    }
    qfa_batch::merge(&sharded, &UnitOptions::default()).unwrap();
    let merged = tree(&sharded);
    assert_eq!(merged.len(), one.len());
    for (path, bytes) in &one {
        assert!(merged.get(path) == Some(bytes), "{} differs between one run and merged shards", path.display());
    }
}

/// A unit whose log the reader refuses fails alone, with the reader's reason on its
/// certificate; the rest of the batch is calibrated.
#[test]
fn a_refused_unit_fails_alone_with_its_reason() {
    let dir = scratch("batch-refused");
    let spec = PopulationSpec { units: 3, seed: 2, bad: false, truncated: 0, die_lags: false };
    let (_, mut units) = chamber(&dir, &spec);
    units[1].rows = qfa_batch::input::UnitRows::Bytes(b"time\ttemp\tax\n0\t20\t0.1\n".to_vec());
    let run = qfa_batch::run(&units, &dir.join("out"), &BatchOptions::default()).unwrap();
    let fleet = run.fleet.unwrap();
    assert_eq!(fleet.unit[1].decision, Decision::Fail);
    assert!(fleet.unit[1].reasons[0].starts_with("not calibrated: "), "{:?}", fleet.unit[1].reasons);
    assert_eq!(fleet.unit.iter().map(|u| u.calibrated).collect::<Vec<_>>(), [true, false, true]);
    assert!(matches!(run.results[1].1.outcome, UnitOutcome::Failed { .. }));
    for i in [0, 2] {
        assert!(matches!(run.results[i].1.outcome, UnitOutcome::Calibrated(_)), "unit {i}");
    }
}

/// A unit whose column for one axis is missing from the chamber log (dropped or misnamed by
/// the logger) gets a table of two axes: it FAILs, naming the axis, where it passed (its
/// table met the limits on the axes it has). The column is cut from the log's text here.
#[test]
fn a_unit_missing_an_axis_column_fails_naming_it() {
    let dir = scratch("batch-missing-axis");
    let spec = PopulationSpec { units: 3, seed: 2, bad: false, truncated: 0, die_lags: false };
    let truth = draw(&spec);
    write_chamber(&dir, &truth).unwrap();
    let text = std::fs::read_to_string(dir.join("chamber.tsv")).unwrap();
    let gone = format!("{}.ay", truth.unit[1].serial);
    let col = text.lines().next().unwrap().split('\t').position(|h| h == gone).expect("the column");
    let cut: String = text
        .lines()
        .map(|l| {
            l.split('\t').enumerate().filter(|(k, _)| *k != col).map(|(_, f)| f).collect::<Vec<_>>().join("\t") + "\n"
        })
        .collect();
    let path = dir.join("cut.tsv");
    std::fs::write(&path, &cut).unwrap();
    let units = from_chamber_log(&path, cut.as_bytes(), &flags()).unwrap();
    let fleet = qfa_batch::run(&units, &dir.join("out"), &BatchOptions::default()).unwrap().fleet.unwrap();
    let decisions: Vec<Decision> = fleet.unit.iter().map(|u| u.decision).collect();
    assert_eq!(decisions, [Decision::Pass, Decision::Fail, Decision::Pass], "{:?}", fleet.unit[1].reasons);
    assert!(
        fleet.unit[1].reasons.iter().any(|r| r.starts_with("its log holds no ay where")),
        "{:?}",
        fleet.unit[1].reasons
    );
    assert!(!fleet.unit[1].flashable());
    // A fault of the input: the command's exit status fails whatever the limits.
    assert_eq!(fleet.unit.iter().map(|u| u.input_fault).collect::<Vec<_>>(), [false, true, false]);
    // Its figures measure no yardstick: two units of full coverage compare, and each
    // capability row counts the two whose log fits the batch.
    assert_eq!(fleet.reference_units, 2);
    assert!(fleet.capability.iter().all(|c| c.n == 2), "{:?}", fleet.capability);
}

/// The error of `table`'s axis `k` against unit `u`'s truth over `span` (the truth is in
/// case temperature, the table in the sensor's).
fn table_error_mg(table: &qfa_thermal::Table, k: usize, u: &qfa_sim::population::UnitTruth, span: [f64; 2]) -> f64 {
    common::table_error_mg(table, k, u.sensor_offset_c, span, |t, heating| u.axes[k].at(t, heating))
}

/// One unit axis's error against its truth: serial, truncated, own table (mg), the prior's (mg).
type PriorRow = (String, bool, f64, f64);

/// Each unit's error against its truth, own table and the prior's, per axis. The prior's table for a full unit is formed in memory
/// from the same population (which that unit is part of).
fn prior_study(units: usize, truncated: usize, seed: u64, name: &str) -> Vec<PriorRow> {
    use qfa_batch::input::from_manifest;
    use qfa_batch::prior::prior_table;
    use qfa_sim::population::write_manifest_run;
    let dir = scratch(name);
    let truth = draw(&PopulationSpec { units, seed, bad: false, truncated, die_lags: false });
    write_manifest_run(&dir, &truth).unwrap();
    let inputs = from_manifest(&dir.join("batch.toml"), &ReadFlags::default()).unwrap();
    let out = dir.join("out");
    let run = qfa_batch::run(&inputs, &out, &BatchOptions { threads: 2, ..BatchOptions::default() }).unwrap();
    let fleet = run.fleet.unwrap();
    let span = (fleet.span_c[0], fleet.span_c[1]);
    let mut rows = Vec::new();
    for ((_, r), u) in run.results.iter().zip(&truth.unit) {
        let UnitOutcome::Calibrated(c) = &r.outcome else { panic!("{}: not calibrated", r.serial) };
        let own = qfa_thermal::Table::decode(&std::fs::read(out.join(&r.serial).join("table.bin")).unwrap()).unwrap();
        let deadband = qfa_calibrate::static_cal::StaticCalOptions::default().deadband_c_per_min;
        let prior =
            prior_table(c.normal.as_ref().expect("a static unit's statistics"), &fleet.population, span, deadband)
                .unwrap();
        for k in 0..3 {
            rows.push((
                r.serial.clone(),
                u.truncation.is_some(),
                table_error_mg(&own, k, u, fleet.span_c),
                table_error_mg(&prior, k, u, fleet.span_c),
            ));
        }
    }
    rows
}

/// RMS of the own and the prior's errors over the truncated (or full) units' axes, and the
/// worst prior/own ratio.
fn summary(rows: &[PriorRow], truncated: bool) -> (f64, f64, f64) {
    let pick: Vec<&PriorRow> = rows.iter().filter(|r| r.1 == truncated).collect();
    let n = pick.len() as f64;
    let rms = |f: &dyn Fn(&PriorRow) -> f64| (pick.iter().map(|r| f(r).powi(2)).sum::<f64>() / n).sqrt();
    let worst_ratio = pick.iter().map(|r| r.3 / r.2).fold(0.0, f64::max);
    (rms(&|r| r.2), rms(&|r| r.3), worst_ratio)
}

/// The population prior on a simulated batch of 12 good units, 4 with truncated logs
/// (heating only, or the first half of the run): it brings the truncated units' error
/// against their truth down, and leaves the full-log units within noise of their own
/// tables (their tables' error against the truth is itself the noise floor; the prior's
/// cubic may not exceed it by more than 50 µg on any axis of any unit).
#[test]
fn the_prior_helps_truncated_units_and_costs_full_ones_nothing_beyond_noise() {
    let rows = prior_study(12, 4, 21, "batch-prior");
    let (own_t, prior_t, _) = summary(&rows, true);
    println!("truncated units: own {own_t:.3} mg, prior {prior_t:.3} mg (RMS over axes and units)");
    assert!(prior_t < 0.5 * own_t, "truncated: own {own_t:.3} mg, prior {prior_t:.3} mg");
    for r in rows.iter().filter(|r| !r.1) {
        assert!(r.3 < r.2 + 0.05, "{} full log: own {:.3} mg, prior {:.3} mg", r.0, r.2, r.3);
    }
}

/// The study behind the figures in docs/measurements.md: 100 units, 20 truncated, three
/// seeds (`cargo test --release -p qfa-lab --test batch -- --ignored prior_study_100 --nocapture`).
#[test]
#[ignore = "a study: about 4 minutes in release"]
fn prior_study_100() {
    for seed in [1, 2, 3] {
        let rows = prior_study(100, 20, seed, &format!("batch-prior-study-{seed}"));
        let (own_t, prior_t, worst_t) = summary(&rows, true);
        let (own_f, prior_f, worst_f) = summary(&rows, false);
        println!(
            "seed={seed} truncated_own_mg={own_t:.3} truncated_prior_mg={prior_t:.3} truncated_worst_ratio={worst_t:.2} \
             full_own_mg={own_f:.3} full_prior_mg={prior_f:.3} full_worst_ratio={worst_f:.2}"
        );
    }
}

/// The study behind the flag threshold (`fleet::Z_FLAG`): three 100-unit chamber runs
/// (6 bad units each), the largest robust distance any good unit reaches on any figure,
/// and the smallest strongest-flag distance of a bad unit, with the decisions
/// (`cargo test --release -p qfa-lab --test batch -- --ignored flag_study --nocapture`).
#[test]
#[ignore = "a study: about 4 minutes in release"]
fn flag_study() {
    for seed in [1, 2, 3] {
        let dir = scratch(&format!("batch-flag-study-{seed}"));
        let (truth, units) =
            chamber(&dir, &PopulationSpec { units: 100, seed, bad: true, truncated: 0, die_lags: false });
        let run =
            qfa_batch::run(&units, &dir.join("out"), &BatchOptions { threads: 2, ..BatchOptions::default() }).unwrap();
        let fleet = run.fleet.unwrap();
        let good_max = common::largest_good_distance(&fleet, |serial| {
            truth.unit.iter().any(|u| u.serial == serial && u.defect.is_none())
        });
        let bad_min = fleet
            .unit
            .iter()
            .zip(&truth.unit)
            .filter(|(_, u)| u.defect.is_some())
            .map(|(f, _)| f.flags.first().map_or(0.0, |g| g.z.abs()))
            .fold(f64::INFINITY, f64::min);
        let [pass, review, fail] = fleet.counts;
        println!(
            "seed={seed} good_max_z={good_max:.2} bad_min_top_z={bad_min:.1} pass={pass} review={review} fail={fail}"
        );
    }
}

/// In a fleet of 15 (the fewest it compares units in), a unit whose output spikes (one row
/// in 60 of one axis 10 mg off, far above its noise) is
/// held back by its own fleet figure, `log.glitches_per_h`, and by no other: the reader
/// skipped those rows, so its held-out figure is within 2 % of the same unit's without the
/// spikes, and every other unit (all are good) passes.
#[test]
fn a_unit_that_spikes_is_flagged_by_its_glitch_rate_not_by_its_held_out_figure() {
    let dir = scratch("batch-spikes");
    let spec = PopulationSpec { units: 15, seed: 5, bad: false, truncated: 0, die_lags: false };
    let truth = draw(&spec);
    write_chamber(&dir, &truth).unwrap();
    let clean = std::fs::read_to_string(dir.join("chamber.tsv")).unwrap();
    let header: Vec<&str> = clean.lines().next().unwrap().split('\t').collect();
    let col = header.iter().position(|h| *h == "SN0002.ax").expect("SN0002.ax");
    let spiked: String = clean
        .lines()
        .enumerate()
        .map(|(i, line)| {
            if i == 0 || i % 60 != 30 {
                return format!("{line}\n");
            }
            let mut f: Vec<String> = line.split('\t').map(String::from).collect();
            f[col] = format!("{:.7}", f[col].parse::<f64>().unwrap() + 0.010);
            format!("{}\n", f.join("\t"))
        })
        .collect();
    // The spiked fleet whole; of the clean log only SN0002, for its held-out figure (every
    // unit is good, so every other unit must pass).
    let fleet_of = |name: &str, text: &str, only: Option<&str>| {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let mut units = from_chamber_log(&path, text.as_bytes(), &flags()).unwrap();
        units.retain(|u| only.is_none_or(|s| u.serial == s));
        let out = dir.join(format!("{name}.out"));
        qfa_batch::run(&units, &out, &BatchOptions { threads: 2, ..BatchOptions::default() }).unwrap().fleet.unwrap()
    };
    let (before, after) = (fleet_of("clean.tsv", &clean, Some("SN0002")), fleet_of("spiked.tsv", &spiked, None));
    assert!(after.compared, "a fleet of {} compares its units", after.reference_units);
    for a in &after.unit {
        println!("{}: {:?} {:?}", a.serial, a.decision, a.reasons);
        if a.serial == "SN0002" {
            assert_ne!(a.decision, Decision::Pass, "{:?}", a.reasons);
            assert!(a.flags.iter().all(|g| g.feature == "log.glitches_per_h"), "{:?}", a.reasons);
            assert!(!a.flags.is_empty(), "{:?}", a.reasons);
        } else {
            assert_eq!(a.decision, Decision::Pass, "{}: {:?}", a.serial, a.reasons);
        }
    }
    let held = |f: &qfa_batch::fleet::Fleet| {
        let s = f.stats.iter().find(|s| s.feature.name == "ax.held_out_mg").unwrap();
        s.values.iter().find(|(k, _)| k == "SN0002").unwrap().1
    };
    let (hb, ha) = (held(&before), held(&after));
    assert!((ha / hb - 1.0).abs() < 0.02, "SN0002 ax held out {hb} mg without spikes, {ha} with");
}
