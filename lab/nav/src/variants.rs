//! The compensation variants flown in lock-step: their names in report order, the tables
//! each is built from, and the oracle that carries the tables' misalignment.

use std::path::Path;

use anyhow::Context;
use qfa_thermal::table::Table;

use super::accel::{AccelCompensation, OracleCompensation, TableCompensation};
use super::run::Variant;
use super::*;

/// Variant names in report order.
pub const VARIANTS: [&str; 5] = ["none", "simple", "hysteresis", "discovered", "oracle"];

/// Read a table for the discovered variant: root-crate postcard (`.bin`) or TOML.
///
/// # Errors
/// I/O, decode or validation errors.
pub fn read_table(path: &Path) -> anyhow::Result<Table> {
    let bytes = std::fs::read(path).with_context(|| format!("reading {}", path.display()))?;
    if path.extension().is_some_and(|e| e == "toml") {
        let text = String::from_utf8(bytes)?;
        let t: Table = toml::from_str(&text).with_context(|| format!("parsing {}", path.display()))?;
        t.validate().map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))?;
        Ok(t)
    } else {
        Table::decode(&bytes).map_err(|e| anyhow::anyhow!("{}: {e}", path.display()))
    }
}

/// Build the five variants in [`VARIANTS`] order. `discovered` holds one 1-axis table per
/// axis; `None` uses the hysteresis tables.
///
/// # Errors
/// A table the compensator refuses.
pub fn variants(t: &Tables, discovered: Option<[Table; 3]>) -> anyhow::Result<Vec<Variant>> {
    let u = &t.units;
    let m = t.misalignment;
    let tc = |f: &dyn Fn(&calib::UnitTables) -> &Table| -> anyhow::Result<Box<dyn AccelCompensation>> {
        Ok(Box::new(TableCompensation::with_misalignment([f(&u[0]), f(&u[1]), f(&u[2])], m)?))
    };
    let disc: Box<dyn AccelCompensation> = match &discovered {
        Some(d) => Box::new(TableCompensation::with_misalignment([&d[0], &d[1], &d[2]], m)?),
        None => tc(&|x| &x.hysteresis)?,
    };
    Ok(vec![
        Variant { name: "none".into(), comp: tc(&|x| &x.none)? },
        Variant { name: "simple".into(), comp: tc(&|x| &x.simple)? },
        Variant { name: "hysteresis".into(), comp: tc(&|x| &x.hysteresis)? },
        Variant { name: "discovered".into(), comp: disc },
        Variant { name: "oracle".into(), comp: Box::new(oracle_of(t)) },
    ])
}

/// The oracle carrying the same misalignment as the tables (in f64).
fn oracle_of(t: &Tables) -> OracleCompensation {
    let m = t.misalignment.map(|m| nalgebra::Matrix3::from_fn(|r, c| f64::from(m[r * 3 + c])));
    OracleCompensation::carrying(m)
}

/// The variants flown in the Monte Carlo runs: `none`, `simple`, `hysteresis`,
/// `discovered` (each unit's own discovery run on its calibration log, when the tables
/// were calibrated with discovery; otherwise it is the hysteresis table and is left out)
/// and `oracle`.
///
/// # Errors
/// A table the compensator refuses.
pub fn mc_variants(t: &Tables) -> anyhow::Result<Vec<Variant>> {
    let u = &t.units;
    let m = t.misalignment;
    let tc = |f: &dyn Fn(&calib::UnitTables) -> &Table| -> anyhow::Result<Box<dyn AccelCompensation>> {
        Ok(Box::new(TableCompensation::with_misalignment([f(&u[0]), f(&u[1]), f(&u[2])], m)?))
    };
    let mut v = vec![
        Variant { name: "none".into(), comp: tc(&|x| &x.none)? },
        Variant { name: "simple".into(), comp: tc(&|x| &x.simple)? },
        Variant { name: "hysteresis".into(), comp: tc(&|x| &x.hysteresis)? },
    ];
    if u.iter().all(|x| x.discovered_effects.iter().all(|e| e != "not run")) {
        v.push(Variant { name: "discovered".into(), comp: tc(&|x| &x.discovered)? });
    }
    v.push(Variant { name: "oracle".into(), comp: Box::new(oracle_of(t)) });
    Ok(v)
}
