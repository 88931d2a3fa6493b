//! What a run leaves in its `--out` folder: this run's files only, whatever ran there
//! before. A user calibrates one log, then another of another kind into the same folder
//! (as a script with a fixed `--out` does); what the folder then holds must be what the new
//! report lists, or a table of the first log reads as the second's.

mod common;

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use common::lab_ok;

fn tmp(name: &str) -> PathBuf {
    common::fresh_dir("out-folder", name)
}

/// The files in `dir` (not its folders).
fn files_in(dir: &Path) -> BTreeSet<String> {
    std::fs::read_dir(dir)
        .unwrap()
        .filter_map(Result::ok)
        .filter(|e| e.path().is_file())
        .map(|e| e.file_name().to_string_lossy().into_owned())
        .collect()
}

/// The files `report.json`'s verdict lists as written (a pattern such as
/// `nav_table_{x,y,z}_….toml` is not expected here).
fn listed(dir: &Path) -> BTreeSet<String> {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    v["verdict"]["files"]
        .as_array()
        .expect("the verdict's files")
        .iter()
        .map(|f| f["file"].as_str().unwrap().to_string())
        .collect()
}

/// The verdict's answer in `dir/report.json`.
fn answer(dir: &Path) -> String {
    let v: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("report.json")).unwrap()).unwrap();
    v["verdict"]["answer"].as_str().unwrap().to_string()
}

/// A cycling log calibrated into a folder, then a static log into the same folder: the
/// folder holds exactly the files the static run's report lists. Before, the cycling run's
/// `table_simple.bin`, `table_simple.toml`, `sf_vs_temp.png` and `residual_vs_time.png`
/// stayed beside the static `table.bin` (`qfa_calibrate::clear_outputs`). And the reverse.
/// Each verdict's answer offers the parameter files only when the run wrote them.
#[test]
fn a_calibration_into_a_used_folder_leaves_only_its_own_files() {
    let d = tmp("calibrate");
    let s = |p: &Path| p.to_str().unwrap().to_string();
    let cycling = d.join("log.csv");
    lab_ok(&["simulate", "--out", &s(&cycling), "--row-s", "10", "--seed", "5"]);
    let batch = d.join("S");
    lab_ok(&["simulate-batch", "--units", "1", "--no-bad", "--seed", "7", "--out", &s(&batch)]);
    let static_log = batch.join("units").join("SN0001.tsv");
    let cal = d.join("cal");
    let calibrate_cycling = ["calibrate", "--log", &s(&cycling), "--out", &s(&cal)];
    let columns = "time=time,temp=temp,ax=ax,ay=ay,az=az";
    let calibrate_static = [
        "calibrate",
        "--log",
        &s(&static_log),
        "--columns",
        columns,
        "--time-unit",
        "s",
        "--accel-unit",
        "g",
        "--temp-unit",
        "C",
        "--no-plots",
        "--out",
        &s(&cal),
    ];
    lab_ok(&calibrate_cycling);
    // No parameter file is written for a cycling log here, so the answer names none (it
    // said "or load the exported parameters" whatever was written).
    assert!(!files_in(&cal).iter().any(|f| f.ends_with(".parm") || f.ends_with(".params")));
    assert_eq!(answer(&cal), "table.bin meets every limit held out; flash it");
    let first = files_in(&cal);
    assert!(first.contains("table_simple.bin") && first.contains("sf_vs_temp.png"), "{first:?}");
    assert_eq!(first, listed(&cal), "the cycling run's folder against its report");
    lab_ok(&calibrate_static);
    assert_eq!(files_in(&cal), listed(&cal), "after a static run into the cycling run's folder");
    assert!(files_in(&cal).contains("ardupilot_tcal_2_values.parm"));
    assert_eq!(answer(&cal), "table.bin meets every limit held out; flash it, or load the exported parameters");
    lab_ok(&calibrate_cycling);
    assert_eq!(files_in(&cal), listed(&cal), "after a cycling run into the static run's folder");
    let _ = std::fs::remove_dir_all(&d);
}
