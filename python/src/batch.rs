//! Production batches from Python: one shard of a batch (`qfa-lab batch --shard K/N`) and
//! the merge that forms the fleet (`qfa-lab batch merge`), the same library calls the
//! command makes. The Python layer (`qfa_thermal.batch`) maps the shards over any
//! `concurrent.futures.Executor` (a process pool, Dask, Ray) and merges.

use std::path::PathBuf;

use pyo3::prelude::*;

use qfa_batch::unit::UnitOptions;
use qfa_batch::{input, BatchError as LabBatchError, BatchOptions, Shard};
use qfa_calibrate::output_error::OutputError;
use qfa_calibrate::static_cal::{Holdout, StaticCalOptions};
use qfa_report::verdict::LimitsChoice;

use crate::errors::{with_kind, BatchError, Kind};
use crate::logs::read_flags;

impl Kind for LabBatchError {
    fn kind(&self) -> &'static str {
        match self {
            Self::Manifest { .. } | Self::NoInput => "Manifest",
            Self::Chamber { .. } => "Chamber",
            Self::Serial(_) => "Serial",
            Self::Unit(_) => "Unit",
            Self::Shard { .. } => "Shard",
            Self::NothingToMerge { .. } | Self::MergeClash { .. } => "Merge",
            Self::Io { .. } | Self::Json { .. } | Self::Output(_) => "Io",
            Self::Limits(_) => "Limits",
            _ => "Other",
        }
    }
}

fn err(py: Python<'_>, e: &LabBatchError) -> PyErr {
    with_kind::<BatchError>(py, e.to_string(), e.kind())
}

fn options(py: Python<'_>, holdout: &str, limits: Option<PathBuf>) -> PyResult<UnitOptions> {
    let holdout: Holdout = holdout.parse().map_err(|e: qfa_calibrate::static_cal::StaticCalError| {
        with_kind::<BatchError>(py, e.to_string(), "UnknownHoldout")
    })?;
    let limits = LimitsChoice::from_arg(limits.as_deref())
        .and_then(|l| qfa_batch::check_limits(&l).map(|()| l))
        .map_err(|e| with_kind::<BatchError>(py, e.to_string(), "Limits"))?;
    Ok(UnitOptions {
        cal: StaticCalOptions { holdout, ..StaticCalOptions::default() },
        limits,
        plots: false,
        spelling: qfa_log::spelling::Spelling::Python,
    })
}

/// Calibrate shard `k` of `n` of a batch (a chamber `log` or a `manifest`) into `out`, on
/// `threads` threads (0: one per core); returns the number of units it calibrated. The
/// units and the files are exactly `qfa-lab batch … --shard k/n`'s.
#[pyfunction]
#[pyo3(signature = (*, out, k, n, log = None, manifest = None, holdout = "auto", limits = None, threads = 1, columns = None, time_unit = None, accel_unit = None, temp_unit = None, decimal_comma = false))]
#[allow(clippy::too_many_arguments)]
pub fn batch_shard(
    py: Python<'_>,
    out: PathBuf,
    k: usize,
    n: usize,
    log: Option<PathBuf>,
    manifest: Option<PathBuf>,
    holdout: &str,
    limits: Option<PathBuf>,
    threads: usize,
    columns: Option<&str>,
    time_unit: Option<&str>,
    accel_unit: Option<&str>,
    temp_unit: Option<&str>,
    decimal_comma: bool,
) -> PyResult<usize> {
    let flags = read_flags(py, columns, time_unit, accel_unit, temp_unit, decimal_comma)?;
    let unit = options(py, holdout, limits)?;
    if n == 0 || k >= n {
        return Err(err(py, &LabBatchError::Shard { given: format!("{k}/{n}") }));
    }
    // A chamber log is streamed, its units' rows waiting in a folder in `out` until
    // `_chamber` goes.
    let (units, _chamber) = match (log, manifest) {
        (Some(l), None) => input::from_chamber_file(&l, &flags, &out).map(|c| (c.units.clone(), Some(c))),
        (None, Some(m)) => input::from_manifest(&m, &flags).map(|u| (u, None)),
        _ => Err(LabBatchError::NoInput),
    }
    .map_err(|e| err(py, &e))?;
    let opts = BatchOptions { unit, threads, shard: Some(Shard { k, n }), progress: false };
    let run = py.detach(|| qfa_batch::run(&units, &out, &opts)).map_err(|e| err(py, &e))?;
    Ok(run.results.len())
}

/// Form the fleet and the certificates from every `SERIAL/unit.json` under `out`
/// (`qfa-lab batch merge`); returns `fleet.json`'s text.
#[pyfunction]
#[pyo3(signature = (out, *, limits = None))]
pub fn batch_merge(py: Python<'_>, out: PathBuf, limits: Option<PathBuf>) -> PyResult<String> {
    let unit = options(py, "auto", limits)?;
    let (_, fleet) = py.detach(|| qfa_batch::merge(&out, &unit)).map_err(|e| err(py, &e))?;
    serde_json::to_string_pretty(&fleet)
        .map_err(|e| err(py, &LabBatchError::Output(OutputError::json(&out.join("fleet.json"))(e))))
}
