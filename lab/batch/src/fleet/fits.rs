//! Whether a unit's log fits the batch: it holds the axes the batch's units hold, and
//! readings of its own (no other unit's table is its table, byte for byte). A unit that does
//! not FAILs with [`super::FleetUnit::input_fault`].

use crate::unit::{UnitOutcome, UnitResult};

/// Per unit, the axes it lacks that more than half of the batch's calibrated static units
/// hold, and those axes, in words (`None` for a unit that lacks none, a QFA unit, or one not
/// calibrated). A unit whose log lost a column got a table of fewer axes, which met its
/// limits on the axes it has and passed.
pub(super) fn missing_axes(results: &[UnitResult]) -> Vec<Option<(String, String)>> {
    let axes: Vec<Option<Vec<&str>>> = results
        .iter()
        .map(|r| match &r.outcome {
            UnitOutcome::Calibrated(c) if c.qfa.is_none() => {
                Some(c.structures.iter().map(|(a, _)| a.as_str()).collect())
            }
            _ => None,
        })
        .collect();
    let held: Vec<&Vec<&str>> = axes.iter().flatten().collect();
    let mut fleet: Vec<&str> = held.iter().flat_map(|a| a.iter().copied()).collect();
    fleet.sort_unstable();
    fleet.dedup();
    fleet.retain(|axis| 2 * held.iter().filter(|a| a.contains(axis)).count() > held.len());
    axes.iter()
        .map(|a| {
            let a = a.as_ref()?;
            let lacks: Vec<&str> = fleet.iter().copied().filter(|x| !a.contains(x)).collect();
            (!lacks.is_empty()).then(|| (lacks.join(", "), fleet.join(", ")))
        })
        .collect()
}

/// Per unit, the other calibrated units whose `table.bin` is its own, byte for byte (the
/// same CRC-32 and length). Two units' rows never give the same table unless they are the
/// same rows: a manifest naming one log for two serials, a log copied to another serial's
/// name, or a chamber log's column written under two serials. Each table then passed as
/// its unit's, and one unit would be flashed with the other's.
pub(super) fn same_tables(results: &[UnitResult]) -> Vec<Vec<String>> {
    let key = |r: &UnitResult| match &r.outcome {
        UnitOutcome::Calibrated(c) => Some((c.table_crc32.clone(), c.table_bytes)),
        UnitOutcome::Failed { .. } => None,
    };
    results
        .iter()
        .map(|r| {
            let Some(k) = key(r) else { return Vec::new() };
            results
                .iter()
                .filter(|o| o.serial != r.serial && key(o).as_ref() == Some(&k))
                .map(|o| o.serial.clone())
                .collect()
        })
        .collect()
}

/// What of each unit's input does not fit the batch: an axis the batch's units hold that its
/// log lacks ([`missing_axes`]), and the other units whose readings are its own
/// ([`same_tables`]).
pub(super) struct InputFaults {
    /// Per unit: the axes it lacks and the fleet's, or `None`.
    pub(super) missing: Vec<Option<(String, String)>>,
    /// Per unit: the serials whose `table.bin` is its own, byte for byte.
    pub(super) same: Vec<Vec<String>>,
}

impl InputFaults {
    /// The faults of `results`' inputs.
    pub(super) fn of(results: &[UnitResult]) -> Self {
        Self { missing: missing_axes(results), same: same_tables(results) }
    }

    /// Whether unit `i`'s log does not fit the batch.
    pub(super) fn any(&self, i: usize) -> bool {
        self.missing[i].is_some() || !self.same[i].is_empty()
    }
}
