//! Production batches (`qfa-lab batch`): many units from one chamber run, each calibrated
//! as `qfa-lab calibrate` would, a certificate per serial, and the fleet page.
//!
//! Layout of the output folder:
//! * `SERIAL/`: the unit's `table.bin` (flash it under that serial), `table.toml`, its
//!   ArduPilot files, `report.*`, `unit.json` (what the fleet reads), and
//!   `certificate.json` / `certificate.html` (decision, figures, the table's CRC-32);
//! * `fleet.json`, `fleet.html`, `fleet_figures.png`, `fleet_held_out.png`.
//!
//! The units run in parallel on a rayon pool of `--threads` threads; each unit's files
//! depend only on its own rows, and the fleet is formed afterwards in batch order, so the
//! outputs are byte-identical whatever the thread count (a test holds this). With
//! `--shard K/N` (0 ≤ K < N, as `navigate --shard`) a run calibrates the units whose place
//! `i` in the batch has `i mod N = K` and writes only their folders; `qfa-lab batch merge OUT` then forms the fleet and certificates from every
//! `unit.json` under OUT, as one run would have.

pub mod ageing;
mod error;
pub mod fleet;
pub mod input;
pub mod lots;
pub(crate) mod pages;
pub mod prior;
pub mod qfa;
pub mod unit;

use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicUsize, Ordering};

use rayon::prelude::*;

pub use self::error::{BatchError, ChamberFault, ManifestFault, SerialFault, UnitFault};
use self::fleet::{Decision, Fleet};
use self::input::UnitInput;
use self::unit::{calibrate_unit, UnitOptions, UnitOutcome, UnitResult};
use qfa_calibrate::output_error::OutputError;
use qfa_report::verdict::Outcome;

/// A table's bytes as `table.bin` holds them, and the CRC-32 its header carries (taken
/// from the encoded value, not read back from a file). `dir` names the unit in an error.
pub(crate) fn encoded(
    table: &qfa_thermal::Table,
    dir: &Path,
) -> Result<(heapless::Vec<u8, { qfa_thermal::table::MAX_TABLE_BYTES }>, u32), BatchError> {
    let bin = table.to_bytes().map_err(OutputError::table(dir))?;
    let mut crc = [0u8; 4];
    crc.copy_from_slice(&bin[12..qfa_thermal::table::HEADER_LEN]);
    Ok((bin, u32::from_le_bytes(crc)))
}

/// The limits a batch may be given, before its units are known: a batch holds static or
/// cycling (QFA) units, so a file must set a key of either kind. [`run`] then checks them
/// against the kinds its units are ([`check_limits_for`]).
///
/// # Errors
/// [`qfa_report::verdict::LimitsError::NoneApply`]: the file sets no key a batch checks.
pub fn check_limits(limits: &qfa_report::verdict::LimitsChoice) -> Result<(), qfa_report::verdict::LimitsError> {
    use qfa_report::verdict::{CYCLING_KEYS, STATIC_KEYS};
    let either: Vec<&'static str> = STATIC_KEYS.iter().chain(&CYCLING_KEYS).copied().collect();
    limits.check_applies("batch", &either)
}

/// The limits against the kinds of log `units` hold: a file must set a key that each kind
/// present checks, or the batch is refused before any unit is calibrated. (Checked per unit
/// only, a QFA batch given a file of static keys calibrated every unit and failed each one
/// for the same reason.)
///
/// # Errors
/// [`BatchError::Limits`]: the file sets no key one of the kinds checks.
pub fn check_limits_for(limits: &qfa_report::verdict::LimitsChoice, units: &[UnitInput]) -> Result<(), BatchError> {
    use qfa_log::open::LogFormat;
    use qfa_report::verdict::{CYCLING_KEYS, STATIC_KEYS};
    let formats: Vec<LogFormat> = units.iter().filter_map(UnitInput::format).collect();
    if formats.contains(&LogFormat::Static) {
        limits.check_applies("static", &STATIC_KEYS).map_err(BatchError::Limits)?;
    }
    if formats.contains(&LogFormat::Cycling) {
        limits.check_applies("cycling", &CYCLING_KEYS).map_err(BatchError::Limits)?;
    }
    Ok(())
}

/// Name of each unit's result file in its folder.
pub(crate) const UNIT_JSON: &str = "unit.json";

/// Every file a batch may write into a unit's folder (a static or a QFA unit, with
/// `--plots`, with a prior table, and the exports). Each is removed before the unit is
/// calibrated, so its folder holds this batch's files only: a unit not calibrated now keeps
/// no `table.bin` an earlier batch wrote there (its certificate says FAIL; the folder said
/// otherwise). The batch's tests check that a unit's folder holds nothing else.
pub const UNIT_FILES: [&str; 19] = [
    "table.bin",
    "table.toml",
    "table_simple.bin",
    "table_simple.toml",
    "table_prior.bin",
    "table_prior.toml",
    "report.json",
    "report.md",
    "report.html",
    "unit.json",
    "certificate.json",
    "certificate.html",
    "bias_vs_temp.png",
    "sf_vs_temp.png",
    "residual_vs_time.png",
    qfa_calibrate::export::EXPORT_FILES[0],
    qfa_calibrate::export::EXPORT_FILES[1],
    qfa_calibrate::export::EXPORT_FILES[2],
    qfa_calibrate::export::EXPORT_FILES[3],
];

/// Remove from a unit's folder `dir` every file an earlier batch may have written there
/// ([`UNIT_FILES`]).
fn clear_unit_folder(dir: &Path) -> Result<(), BatchError> {
    for name in UNIT_FILES {
        let path = dir.join(name);
        qfa_log::io_fault::remove_if_present(&path).map_err(OutputError::io(&path))?;
    }
    Ok(())
}

/// One shard of a job array: the units whose place `i` has `i mod n = k`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Shard {
    /// This run, 0..n.
    pub k: usize,
    /// Runs.
    pub n: usize,
}

impl std::str::FromStr for Shard {
    type Err = BatchError;
    fn from_str(s: &str) -> Result<Self, BatchError> {
        let bad = || BatchError::Shard { given: s.to_string() };
        let (k, n) = s.split_once('/').ok_or_else(bad)?;
        let (k, n): (usize, usize) = (k.trim().parse().map_err(|_| bad())?, n.trim().parse().map_err(|_| bad())?);
        if n == 0 || k >= n {
            return Err(bad());
        }
        Ok(Self { k, n })
    }
}

/// A batch's settings.
#[derive(Clone, Debug, Default)]
pub struct BatchOptions {
    /// Per unit.
    pub unit: UnitOptions,
    /// Worker threads (0: rayon's default, one per core).
    pub threads: usize,
    /// Only this shard's units; the fleet is left to `batch merge`.
    pub shard: Option<Shard>,
    /// Show progress on the console.
    pub progress: bool,
}

/// What a run produced: every unit's result and, unless sharded, the fleet.
#[derive(Clone, Debug)]
pub struct BatchRun {
    /// Results of the units run, in batch order, with their index in the batch.
    pub results: Vec<(usize, UnitResult)>,
    /// The fleet (`None` for a shard).
    pub fleet: Option<Fleet>,
}

#[derive(serde::Serialize, serde::Deserialize)]
struct IndexedResult {
    /// The unit's place in the batch (what `merge` orders by).
    index: usize,
    #[serde(flatten)]
    result: UnitResult,
}

fn progress_bar(len: usize, show: bool) -> indicatif::ProgressBar {
    if !show {
        return indicatif::ProgressBar::hidden();
    }
    let pb = indicatif::ProgressBar::new(len as u64);
    pb.set_style(
        indicatif::ProgressStyle::with_template("{bar:30} {pos}/{len} units, {msg}, {eta} left")
            .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb
}

/// Calibrate `units` into `out` (see the module docs).
///
/// # Errors
/// The thread pool cannot be built, or a file cannot be written. A unit that fails is a
/// result, not an error.
pub fn run(units: &[UnitInput], out: &Path, opts: &BatchOptions) -> Result<BatchRun, BatchError> {
    check_limits_for(&opts.unit.limits, units)?;
    std::fs::create_dir_all(out).map_err(OutputError::io(out))?;
    let mine: Vec<(usize, &UnitInput)> =
        units.iter().enumerate().filter(|(i, _)| opts.shard.is_none_or(|s| i % s.n == s.k)).collect();
    let pool = rayon::ThreadPoolBuilder::new().num_threads(opts.threads).build().map_err(BatchError::ThreadPool)?;
    let pb = progress_bar(mine.len(), opts.progress);
    let (failed, limit_failed) = (AtomicUsize::new(0), AtomicUsize::new(0));
    let results: Vec<Result<(usize, UnitResult), BatchError>> = pool.install(|| {
        mine.par_iter()
            .map(|&(i, u)| {
                let dir = out.join(&u.serial);
                std::fs::create_dir_all(&dir).map_err(OutputError::io(&dir))?;
                clear_unit_folder(&dir)?;
                let r = calibrate_unit(u, &dir, &opts.unit);
                match &r.outcome {
                    UnitOutcome::Failed { .. } => failed.fetch_add(1, Ordering::Relaxed),
                    UnitOutcome::Calibrated(c) if c.outcome == Outcome::Fail => {
                        limit_failed.fetch_add(1, Ordering::Relaxed)
                    }
                    UnitOutcome::Calibrated(_) => 0,
                };
                let path = dir.join(UNIT_JSON);
                // Compact: what `batch merge` reads, not a page; a QFA unit's minute means
                // (its sensor against the fleet's, some 23 000) take 0.48 MB so, 1.78 MB
                // indented.
                let json = serde_json::to_string(&IndexedResult { index: i, result: r.clone() })
                    .map_err(OutputError::json(&path))?;
                std::fs::write(&path, json + "\n").map_err(OutputError::io(&path))?;
                pb.set_message(format!(
                    "{} not calibrated, {} failing a limit",
                    failed.load(Ordering::Relaxed),
                    limit_failed.load(Ordering::Relaxed)
                ));
                pb.inc(1);
                Ok((i, r))
            })
            .collect()
    });
    pb.finish_and_clear();
    let results = results.into_iter().collect::<Result<Vec<_>, _>>()?;
    let fleet = if opts.shard.is_some() { None } else { Some(finish_fleet(out, &results, &opts.unit)?) };
    Ok(BatchRun { results, fleet })
}

/// The fleet stage: figures, flags, decisions, certificates and the fleet page, from
/// results in batch order.
///
/// # Errors
/// A file cannot be written.
pub(crate) fn finish_fleet(
    out: &Path,
    results: &[(usize, UnitResult)],
    opts: &UnitOptions,
) -> Result<Fleet, BatchError> {
    let plain: Vec<UnitResult> = results.iter().map(|(_, r)| r.clone()).collect();
    let mut fleet = fleet::fleet(&plain, &opts.limits.limits);
    // Partial units: the population prior's table beside their own.
    let span = (fleet.span_c[0], fleet.span_c[1]);
    let mut uses = Vec::with_capacity(plain.len());
    let mut prior_failed: Vec<(String, prior::PriorError)> = Vec::new();
    for (r, f) in plain.iter().zip(&fleet.unit) {
        let deadband = opts.cal.deadband_c_per_min;
        // A static unit's axes, or a QFA unit's scale factor and bias; the bins its bias
        // rows cover.
        let formed = match &r.outcome {
            UnitOutcome::Calibrated(c) if f.partial && !fleet.population.is_empty() => {
                match (&c.normal, &c.qfa_normal) {
                    (Some(n), _) => Some((prior::prior_table(n, &fleet.population, span, deadband), n)),
                    (None, Some(q)) => Some((qfa::qfa_prior_table(q, &fleet.population, span, deadband), &q.bias)),
                    (None, None) => None,
                }
            }
            _ => None,
        };
        let use_ = match formed {
            Some((formed, covered)) => {
                let dir = out.join(&r.serial);
                match formed {
                    Ok(table) => {
                        let (bin, crc) = encoded(&table, &dir)?;
                        let toml = toml::to_string_pretty(&table).map_err(OutputError::toml(&dir))?;
                        let bin_path = dir.join("table_prior.bin");
                        std::fs::write(&bin_path, &bin).map_err(OutputError::io(&bin_path))?;
                        let toml_path = dir.join("table_prior.toml");
                        std::fs::write(
                            &toml_path,
                            format!("# qfa-thermal table from the population prior (the lab guide's \"Production batches\")\n{toml}"),
                        )
                        .map_err(OutputError::io(&toml_path))?;
                        let share = prior::covered_share(covered, span);
                        Some(prior::PriorUse {
                            table: "table_prior.bin".into(),
                            table_crc32: format!("{crc:08x}"),
                            covered_share: share,
                            mostly_prior: share < prior::MOSTLY_PRIOR,
                        })
                    }
                    Err(e) => {
                        // Never silent: the unit keeps its own table, and says why.
                        prior_failed.push((r.serial.clone(), e));
                        None
                    }
                }
            }
            None => None,
        };
        uses.push(use_);
    }
    fleet::apply_priors(&mut fleet, uses);
    for (serial, why) in prior_failed {
        if let Some(u) = fleet.unit.iter_mut().find(|u| u.serial == serial) {
            u.reasons.push(format!(
                "partial coverage, but no prior table could be formed ({why}): table.bin is its own fit"
            ));
            if u.decision == Decision::Pass {
                u.decision = Decision::Review;
            }
        }
    }
    fleet.counts = fleet::count(&fleet.unit);
    let from = opts.limits.source();
    for (r, f) in plain.iter().zip(&fleet.unit) {
        pages::write_certificate(&out.join(&r.serial), r, f, &from)?;
    }
    pages::write_fleet(out, &fleet, &plain, &from)?;
    Ok(fleet)
}

/// `batch merge OUT`: every `SERIAL/unit.json` under `out` (the shards of one batch, all
/// written into `out`), ordered by their place in the batch, then `finish_fleet`.
///
/// # Errors
/// No `unit.json`, two with one index, or an unreadable one.
pub fn merge(out: &Path, opts: &UnitOptions) -> Result<(Vec<(usize, UnitResult)>, Fleet), BatchError> {
    let mut found: Vec<(usize, UnitResult)> = Vec::new();
    let mut dirs: Vec<PathBuf> = std::fs::read_dir(out)
        .map_err(|source| BatchError::Io { path: out.to_path_buf(), source })?
        .filter_map(|e| e.ok().map(|e| e.path()))
        .filter(|p| p.join(UNIT_JSON).is_file())
        .collect();
    dirs.sort();
    for d in dirs {
        let p = d.join(UNIT_JSON);
        let text = std::fs::read_to_string(&p).map_err(|source| BatchError::Io { path: p.clone(), source })?;
        let r: IndexedResult =
            serde_json::from_str(&text).map_err(|source| BatchError::Json { path: p.clone(), source })?;
        found.push((r.index, r.result));
    }
    if found.is_empty() {
        return Err(BatchError::NothingToMerge { out: out.to_path_buf() });
    }
    found.sort_by_key(|(i, _)| *i);
    for w in found.windows(2) {
        if w[0].0 == w[1].0 {
            return Err(BatchError::MergeClash {
                serials: [w[0].1.serial.clone(), w[1].1.serial.clone()],
                place: w[0].0,
            });
        }
    }
    let fleet = finish_fleet(out, &found, opts)?;
    Ok((found, fleet))
}

/// Reasons shown where a unit has one line (the console, the fleet's verdict): the first
/// [`REASONS_SHOWN`] (flags come strongest first), then how many more its certificate lists.
#[must_use]
pub(crate) fn first_reasons(reasons: &[String]) -> String {
    let mut s = reasons.iter().take(REASONS_SHOWN).cloned().collect::<Vec<_>>().join("; ");
    if reasons.len() > REASONS_SHOWN {
        s.push_str(&format!("; and {} more on its certificate", reasons.len() - REASONS_SHOWN));
    }
    s
}

/// The units not passed, those with the same decision and reasons together (a flag
/// every unit shares, such as a missing `--time-unit`, is one line, not one per unit), in
/// batch order of each group's first unit: `(decision, reasons, serials)`.
#[must_use]
pub(crate) fn grouped(fleet: &Fleet) -> Vec<(Decision, String, Vec<String>)> {
    let mut out: Vec<(Decision, String, Vec<String>)> = Vec::new();
    for u in fleet.unit.iter().filter(|u| u.decision != Decision::Pass) {
        let r = first_reasons(&u.reasons);
        match out.iter_mut().find(|(d, x, _)| *d == u.decision && *x == r) {
            Some(g) => g.2.push(u.serial.clone()),
            None => out.push((u.decision, r, vec![u.serial.clone()])),
        }
    }
    out
}

/// The units' log warnings ([`FleetUnit::log_warnings`]), the units with the same warning
/// together, in batch order of each warning's first unit: `(warning, serials)`.
#[must_use]
pub(crate) fn log_warning_groups(fleet: &Fleet) -> Vec<(String, Vec<String>)> {
    let mut out: Vec<(String, Vec<String>)> = Vec::new();
    for u in &fleet.unit {
        for w in &u.log_warnings {
            match out.iter_mut().find(|(x, _)| x == w) {
                Some(g) => g.1.push(u.serial.clone()),
                None => out.push((w.clone(), vec![u.serial.clone()])),
            }
        }
    }
    out
}

/// `SN1`, or `3 units (SN1, SN2, SN3)`, or `40 units (SN1, SN2, SN3, … SN40)`.
#[must_use]
pub(crate) fn serial_list(serials: &[String]) -> String {
    match serials {
        [one] => one.clone(),
        many if many.len() <= 4 => format!("{} units ({})", many.len(), many.join(", ")),
        many => format!("{} units ({}, … {})", many.len(), many[..3].join(", "), many[many.len() - 1]),
    }
}

/// Reasons a one-line summary shows.
pub(crate) const REASONS_SHOWN: usize = 2;

/// The console's summary of a fleet: the verdict line, one line per unit not passed, and
/// where the detail is.
#[must_use]
pub fn console(fleet: &Fleet, out: &Path) -> String {
    let [pass, review, fail] = fleet.counts;
    let mut s = format!(
        "verdict: {} units: {pass} PASS, {review} REVIEW (limits met, outside the population), {fail} FAIL\n",
        fleet.units
    );
    if let Some(why) = fleet.not_compared() {
        s.push_str(&format!("fleet: {why}\n"));
    }
    if let Some(l) = &fleet.lots {
        let top: Vec<&str> = l.figures.iter().take(3).map(|f| f.name.as_str()).collect();
        s.push_str(&format!(
            "lots: two, {} and {} units, told apart most by {}; {}\n",
            l.sizes[0],
            l.sizes[1],
            top.join(", "),
            if l.compared_within {
                "each unit compared with its own lot".to_string()
            } else {
                format!(
                    "each unit compared with the whole fleet (a lot under {} units is too few to compare with)",
                    fleet::MIN_FLEET
                )
            }
        ));
    }
    for (decision, reasons, serials) in grouped(fleet) {
        let key = if decision == Decision::Fail { "fail" } else { "review" };
        s.push_str(&format!("{key}: {}: {reasons}\n", serial_list(&serials)));
    }
    for (warning, serials) in log_warning_groups(fleet) {
        s.push_str(&format!("log: {}: {warning}\n", serial_list(&serials)));
    }
    for u in &fleet.unit {
        if let Some(p) = u.prior.as_ref().filter(|_| u.flashable()) {
            s.push_str(&format!(
                "prior: {}: partial coverage ({}), flash {} (CRC-32 {}; its own rows cover {:.0} % of the fleet's span × \
                 both branches)\n",
                u.serial,
                u.coverage.words().unwrap_or_default(),
                p.table,
                p.table_crc32,
                100.0 * p.covered_share
            ));
        }
    }
    s.push_str(&format!(
        "detail: {}/fleet.html, fleet.json; each unit: {}/SERIAL/certificate.html\n",
        out.display(),
        out.display()
    ));
    s
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit's folder is cleared of every file a calibration of one log may write there
    /// (`qfa_calibrate::OUTPUT_FILES`): a file added to that list and not to this one would
    /// outlive a failed unit.
    #[test]
    fn a_unit_folder_clears_every_calibration_output() {
        for f in qfa_calibrate::OUTPUT_FILES {
            assert!(UNIT_FILES.contains(&f), "{f} is not in UNIT_FILES");
        }
    }

    /// A list of serials reads whole up to four, then the first three and the last.
    #[test]
    fn serial_lists_stay_one_line() {
        let s = |n: usize| (1..=n).map(|i| format!("S{i}")).collect::<Vec<_>>();
        assert_eq!(serial_list(&s(1)), "S1");
        assert_eq!(serial_list(&s(3)), "3 units (S1, S2, S3)");
        assert_eq!(serial_list(&s(40)), "40 units (S1, S2, S3, … S40)");
    }

    /// `K/N` parses for 0 ≤ K < N and nothing else.
    #[test]
    fn shard_parses_only_k_of_n() {
        assert_eq!("2/4".parse::<Shard>().unwrap(), Shard { k: 2, n: 4 });
        assert_eq!("0/1".parse::<Shard>().unwrap(), Shard { k: 0, n: 1 });
        for bad in ["4/4", "5/4", "1/0", "2", "a/b", "-1/3"] {
            assert!(bad.parse::<Shard>().is_err(), "{bad}");
        }
    }
}
