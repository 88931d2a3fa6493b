//! The Monte Carlo study's summary: statistics over the runs ([`Stats`]), the merge of
//! shards into one study ([`summarize`], [`merge`]), `mc_runs.csv` and the distribution
//! plots ([`write_outputs`]), and the console table ([`table`]).

use std::collections::BTreeMap;
use std::fmt::{self, Write as _};
use std::path::{Path, PathBuf};

use serde::{Deserialize, Serialize};

use super::align::AlignErrors;
use super::mc::{Outcome, Partial};
use super::plot::PlotError;
use super::scenario::{Scenario, Variation};
use qfa_report::plot_png::Plot;

/// Why the runs could not be summarized, merged or written.
#[derive(Debug)]
#[non_exhaustive]
pub enum SummaryError {
    /// No value to take statistics of.
    NoValues,
    /// A value that is not finite.
    NonFinite,
    /// The statistics of one column (a variant's figure) failed.
    Column {
        /// The column: the variant.
        column: String,
        /// Why ([`SummaryError::NoValues`] or [`SummaryError::NonFinite`]).
        source: Box<SummaryError>,
    },
    /// No partial result to combine.
    NoPartials,
    /// A shard from another study: its scenario, seed or run count differ from the first's.
    OtherStudy {
        /// The shard, `(k, n)`.
        shard: (u64, u64),
    },
    /// A run found in two partial results.
    Duplicate {
        /// The run.
        run: u64,
    },
    /// Runs of the study that no partial result holds.
    Missing {
        /// The missing runs, in order.
        missing: Vec<u64>,
        /// The study's run count.
        runs: u64,
    },
    /// The study's scenario (as its partial results carry it) does not parse.
    Scenario(toml::de::Error),
    /// A folder that could not be created.
    CreateDir {
        /// The folder.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A file or folder that could not be read.
    Read {
        /// The file or folder.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A file that could not be written.
    Write {
        /// The file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// A partial result that is not one.
    Parse {
        /// The file.
        path: PathBuf,
        /// The JSON parser's error.
        source: serde_json::Error,
    },
    /// A distribution plot could not be drawn.
    Plot(PlotError),
    /// No `mc_partial_*.json` in the folders given.
    NoneFound {
        /// The folders (or files) given.
        dirs: Vec<PathBuf>,
    },
    /// No partial result carries the nominal run (shard 0's).
    NoNominal,
    /// The nominal run's report is not a JSON object.
    NominalNotObject,
    /// The summary could not be turned into JSON.
    Json(serde_json::Error),
}

impl fmt::Display for SummaryError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoValues => f.write_str("no values"),
            Self::NonFinite => f.write_str("non-finite value"),
            Self::Column { column, .. } => f.write_str(column),
            Self::NoPartials => f.write_str("no partial results"),
            Self::OtherStudy { shard: (k, n) } => {
                write!(f, "shard {k}/{n} is from another study (scenario, seed or run count differ)")
            }
            Self::Duplicate { run } => write!(f, "run {run} appears twice"),
            Self::Missing { missing, runs } => {
                write!(f, "{} of {runs} runs missing (first: {:?})", missing.len(), &missing[..missing.len().min(10)])
            }
            Self::Scenario(e) => write!(f, "{e}"),
            Self::CreateDir { path, .. } => write!(f, "creating {}", path.display()),
            Self::Read { path, .. } => write!(f, "reading {}", path.display()),
            Self::Write { path, .. } => write!(f, "writing {}", path.display()),
            Self::Parse { path, .. } => write!(f, "parsing {}", path.display()),
            Self::Plot(_) => f.write_str("plot"),
            Self::NoneFound { dirs } => write!(f, "no mc_partial_*.json found in {dirs:?}"),
            Self::NoNominal => f.write_str("no shard 0 (the nominal run) among the partial results"),
            Self::NominalNotObject => f.write_str("nominal report is not an object"),
            Self::Json(e) => write!(f, "{e}"),
        }
    }
}

impl SummaryError {
    /// This error of the statistics of column `column`.
    fn in_column(self, column: &str) -> Self {
        Self::Column { column: column.to_string(), source: Box::new(self) }
    }
}

impl std::error::Error for SummaryError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Column { source, .. } => Some(&**source),
            Self::CreateDir { source, .. } | Self::Read { source, .. } | Self::Write { source, .. } => Some(source),
            Self::Parse { source, .. } => Some(source),
            Self::Plot(e) => Some(e),
            // Printed as they are (above): their causes come next.
            Self::Scenario(e) => e.source(),
            Self::Json(e) => e.source(),
            _ => None,
        }
    }
}

/// Median and 10th / 90th percentiles (linear interpolation between order statistics).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Stats {
    /// Median.
    pub median: f64,
    /// 10th percentile.
    pub p10: f64,
    /// 90th percentile.
    pub p90: f64,
    /// Mean.
    pub mean: f64,
    /// Smallest.
    pub min: f64,
    /// Largest.
    pub max: f64,
}

/// Percentile `p` (0..=1) of sorted `v` (non-empty).
fn percentile(v: &[f64], p: f64) -> f64 {
    let x = p * (v.len() - 1) as f64;
    let i = x.floor() as usize;
    let j = (i + 1).min(v.len() - 1);
    v[i] + (x - i as f64) * (v[j] - v[i])
}

impl Stats {
    /// Of `values`.
    ///
    /// # Errors
    /// No values, or a non-finite one.
    pub fn of(values: &[f64]) -> Result<Self, SummaryError> {
        crate::ensure(!values.is_empty(), SummaryError::NoValues)?;
        crate::ensure(values.iter().all(|x| x.is_finite()), SummaryError::NonFinite)?;
        let mut v = values.to_vec();
        v.sort_by(f64::total_cmp);
        Ok(Self {
            median: percentile(&v, 0.5),
            p10: percentile(&v, 0.1),
            p90: percentile(&v, 0.9),
            mean: v.iter().sum::<f64>() / v.len() as f64,
            min: v[0],
            max: v[v.len() - 1],
        })
    }
}

/// Alignment error statistics (absolute values).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct AlignStats {
    /// |roll error|, arcsec.
    pub roll_arcsec: Stats,
    /// |pitch error|, arcsec.
    pub pitch_arcsec: Stats,
    /// |heading error|, mrad.
    pub heading_mrad: Stats,
}

/// One shard's timing.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct ShardTiming {
    /// `(k, n)`.
    pub shard: (u64, u64),
    /// Runs flown.
    pub runs: usize,
    /// Worker threads.
    pub jobs: usize,
    /// Wall time, s.
    pub wall_s: f64,
    /// Runs per minute of wall time.
    pub runs_per_minute: f64,
}

/// `report.json`'s `monte_carlo` object.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Summary {
    /// Runs.
    pub runs: u64,
    /// Base seed.
    pub seed: u64,
    /// `(simple − v)/(simple − oracle)` on the thermal-only CEP rate, per variant.
    pub thermal_share_removed: BTreeMap<String, Stats>,
    /// Total CEP rate per variant, nmile/h.
    pub cep_nmi_per_h: BTreeMap<String, Stats>,
    /// Thermal-only CEP rate per variant, nmile/h.
    pub thermal_cep_nmi_per_h: BTreeMap<String, Stats>,
    /// Share on total CEP rate per variant (sign-sensitive; for comparison).
    pub share_removed_total_cep: BTreeMap<String, Stats>,
    /// Alignment errors (absolute) per variant.
    pub alignment: BTreeMap<String, AlignStats>,
    /// Share of the flight's IMU cycles with the rate clamped, per table variant.
    #[serde(default)]
    pub rate_clamped_share: BTreeMap<String, Stats>,
    /// Share of the flight's IMU cycles with the temperature clamped, per table variant.
    #[serde(default)]
    pub temp_clamped_share: BTreeMap<String, Stats>,
    /// The variation bounds flown.
    pub variation: Variation,
    /// Timing per shard (one entry when not sharded).
    pub timing: Vec<ShardTiming>,
}

fn stats_by(
    outs: &[&Outcome],
    f: impl Fn(&Outcome) -> &BTreeMap<String, f64>,
) -> Result<BTreeMap<String, Stats>, SummaryError> {
    let mut m: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for o in outs {
        for (k, v) in f(o) {
            m.entry(k.clone()).or_default().push(*v);
        }
    }
    m.into_iter().map(|(k, v)| Ok((k.clone(), Stats::of(&v).map_err(|e| e.in_column(&k))?))).collect()
}

/// Combine partial results of one study: same scenario, seed and run count, every run
/// index exactly once.
///
/// # Errors
/// Mixed studies, duplicated or missing runs, statistics of no runs.
pub fn summarize(parts: &[Partial]) -> Result<(Summary, Vec<Outcome>), SummaryError> {
    let first = parts.first().ok_or(SummaryError::NoPartials)?;
    for p in parts {
        crate::ensure(
            p.scenario_toml == first.scenario_toml && p.seed == first.seed && p.runs == first.runs,
            SummaryError::OtherStudy { shard: p.shard },
        )?;
    }
    let mut outs: Vec<Outcome> = parts.iter().flat_map(|p| p.outcomes.iter().cloned()).collect();
    outs.sort_by_key(|o| o.run);
    for w in outs.windows(2) {
        crate::ensure(w[0].run != w[1].run, SummaryError::Duplicate { run: w[0].run })?;
    }
    let have: std::collections::BTreeSet<u64> = outs.iter().map(|o| o.run).collect();
    let missing: Vec<u64> = (0..first.runs).filter(|i| !have.contains(i)).collect();
    crate::ensure(missing.is_empty(), SummaryError::Missing { missing, runs: first.runs })?;
    let refs: Vec<&Outcome> = outs.iter().collect();
    let mut alignment = BTreeMap::new();
    if let Some(o) = outs.first() {
        for n in o.alignment.keys() {
            let col = |f: &dyn Fn(&AlignErrors) -> f64| -> Result<Stats, SummaryError> {
                Stats::of(&outs.iter().filter_map(|o| o.alignment.get(n)).map(|a| f(a).abs()).collect::<Vec<_>>())
            };
            alignment.insert(
                n.clone(),
                AlignStats {
                    roll_arcsec: col(&|a| a.roll_arcsec)?,
                    pitch_arcsec: col(&|a| a.pitch_arcsec)?,
                    heading_mrad: col(&|a| a.heading_mrad)?,
                },
            );
        }
    }
    let sc: Scenario = toml::from_str(&first.scenario_toml).map_err(SummaryError::Scenario)?;
    let sum = Summary {
        runs: first.runs,
        seed: first.seed,
        thermal_share_removed: stats_by(&refs, |o| &o.thermal_share_removed)?,
        cep_nmi_per_h: stats_by(&refs, |o| &o.cep_nmi_per_h)?,
        thermal_cep_nmi_per_h: stats_by(&refs, |o| &o.thermal_cep_nmi_per_h)?,
        share_removed_total_cep: stats_by(&refs, |o| &o.share_removed_total_cep)?,
        alignment,
        rate_clamped_share: stats_by(&refs, |o| &o.rate_clamped_share)?,
        temp_clamped_share: stats_by(&refs, |o| &o.temp_clamped_share)?,
        variation: sc.monte_carlo,
        timing: parts
            .iter()
            .map(|p| ShardTiming {
                shard: p.shard,
                runs: p.outcomes.len(),
                jobs: p.jobs,
                wall_s: p.wall_s,
                runs_per_minute: p.outcomes.len() as f64 / (p.wall_s / 60.0),
            })
            .collect(),
    };
    Ok((sum, outs))
}

/// Summarize `parts` and write `mc_runs.csv` and, with `plots`, `mc_thermal_share.png`,
/// `mc_thermal_cep.png` and `mc_cep.png` (empirical distribution functions) to `out`;
/// returns the study and the plots written (for the page, which inlines these bytes).
///
/// # Errors
/// As [`summarize`], I/O or drawing.
pub fn write_outputs(out: &Path, parts: &[Partial], plots: bool) -> Result<(Summary, Vec<Plot>), SummaryError> {
    let (sum, outs) = summarize(parts)?;
    std::fs::create_dir_all(out).map_err(|e| SummaryError::CreateDir { path: out.into(), source: e })?;
    let names: Vec<String> = sum.cep_nmi_per_h.keys().cloned().collect();
    write_file(&out.join("mc_runs.csv"), &runs_csv(&names, &outs))?;
    let drawn = if plots { plot_runs(&names, &outs)? } else { Vec::new() };
    for plot in &drawn {
        let path = out.join(&plot.file);
        std::fs::write(&path, plot.png()).map_err(|e| SummaryError::Write { path, source: e })?;
    }
    Ok((sum, drawn))
}

/// `mc_runs.csv`: one row per run, the figures of each variant in `names`.
fn runs_csv(names: &[String], outs: &[Outcome]) -> String {
    let mut s = String::from("run,seed,temp_offset_c,temp_scale,case_min_c,case_max_c");
    for n in names {
        let _ = write!(s, ",{n}_cep_nmi_per_h,{n}_thermal_cep_nmi_per_h,{n}_thermal_share,{n}_share_total_cep,{n}_roll_arcsec,{n}_pitch_arcsec,{n}_heading_mrad,{n}_rate_clamped_share,{n}_temp_clamped_share");
    }
    s.push_str(",clamped_warning");
    s.push_str(",wall_s\n");
    for o in outs {
        let _ = write!(
            s,
            "{},{},{:.3},{:.4},{:.2},{:.2}",
            o.run, o.seed, o.temp_offset_c, o.temp_scale, o.case_temp_range_c[0], o.case_temp_range_c[1]
        );
        for n in names {
            let a = o.alignment.get(n).copied().unwrap_or_default();
            let _ = write!(
                s,
                ",{:.5},{:.5},{:.4},{:.4},{:.2},{:.2},{:.4}",
                o.cep_nmi_per_h[n],
                o.thermal_cep_nmi_per_h[n],
                o.thermal_share_removed[n],
                o.share_removed_total_cep[n],
                a.roll_arcsec,
                a.pitch_arcsec,
                a.heading_mrad
            );
            // The oracle has no status word: "n/a", not a 0 that reads as "never clamped".
            for m in [&o.rate_clamped_share, &o.temp_clamped_share] {
                match m.get(n) {
                    Some(x) => {
                        let _ = write!(s, ",{x:.4}");
                    }
                    None => s.push_str(",n/a"),
                }
            }
        }
        // Variants clamped on most of the flight, `;`-separated (empty: none).
        let warn: Vec<String> = names
            .iter()
            .filter(|n| {
                [&o.rate_clamped_share, &o.temp_clamped_share]
                    .iter()
                    .any(|m| m.get(*n).is_some_and(|x| *x > super::accel::CLAMPED_WARN_SHARE))
            })
            .map(|n| format!("{n} clamped"))
            .collect();
        let _ = write!(s, ",{}", warn.join(";"));
        let _ = writeln!(s, ",{:.2}", o.wall_s);
    }
    s
}

/// `mc_cep.png`, `mc_thermal_cep.png` and `mc_thermal_share.png` (in this order): each
/// variant's empirical distribution over the runs.
fn plot_runs(names: &[String], outs: &[Outcome]) -> Result<Vec<Plot>, SummaryError> {
    let col = |f: &dyn Fn(&Outcome) -> &BTreeMap<String, f64>, scale: f64, skip: &[&str]| -> Vec<(String, Vec<f64>)> {
        names
            .iter()
            .filter(|n| !skip.contains(&n.as_str()))
            .map(|n| (n.clone(), outs.iter().map(|o| f(o)[n] * scale).collect()))
            .collect()
    };
    let title = format!("{} runs", outs.len());
    Ok(vec![
        super::plot::plot_distributions(
            "mc_cep.png",
            &format!("CEP rate (radial growth) per variant; {title}"),
            "CEP (nmile/h)",
            &col(&|o| &o.cep_nmi_per_h, 1.0, &[]),
        )
        .map_err(SummaryError::Plot)?,
        super::plot::plot_distributions(
            "mc_thermal_cep.png",
            &format!("thermal-only CEP rate (variant − oracle, same sensor data); {title}"),
            "thermal-only CEP (nmile/h)",
            &col(&|o| &o.thermal_cep_nmi_per_h, 1.0, &["none", "oracle"]),
        )
        .map_err(SummaryError::Plot)?,
        super::plot::plot_distributions(
            "mc_thermal_share.png",
            &format!("thermal share removed, (simple − v)/(simple − oracle) on thermal-only CEP; {title}"),
            "thermal share removed (%)",
            // `none` (several hundred % negative) would squash the scale.
            &col(&|o| &o.thermal_share_removed, 100.0, &["none", "simple", "oracle"]),
        )
        .map_err(SummaryError::Plot)?,
    ])
}

/// Write `text` to `path`, the error naming the file.
fn write_file(path: &Path, text: &str) -> Result<(), SummaryError> {
    std::fs::write(path, text).map_err(|e| SummaryError::Write { path: path.into(), source: e })
}

/// Read every `mc_partial_*.json` in `dirs`, combine, write `mc_runs.csv` and the plots
/// to `out`; returns the study, its report (the nominal run's keys from shard 0 plus
/// `monte_carlo`) and the plots written, which [`super::merge`] writes as `report.json` with its verdict.
///
/// # Errors
/// I/O, parse, or [`summarize`]'s checks.
pub fn merge(
    dirs: &[PathBuf],
    out: &Path,
    plots: bool,
) -> Result<(Summary, serde_json::Value, Vec<Plot>), SummaryError> {
    let mut parts = Vec::new();
    for d in dirs {
        let mut files: Vec<PathBuf> = if d.is_dir() {
            std::fs::read_dir(d)
                .map_err(|e| SummaryError::Read { path: d.clone(), source: e })?
                .filter_map(Result::ok)
                .map(|e| e.path())
                .filter(|p| {
                    p.file_name()
                        .and_then(|n| n.to_str())
                        .is_some_and(|n| n.starts_with("mc_partial_") && n.ends_with(".json"))
                })
                .collect()
        } else {
            vec![d.clone()]
        };
        files.sort();
        for f in files {
            let text = std::fs::read_to_string(&f).map_err(|e| SummaryError::Read { path: f.clone(), source: e })?;
            parts.push(serde_json::from_str::<Partial>(&text).map_err(|e| SummaryError::Parse { path: f, source: e })?);
        }
    }
    crate::ensure(!parts.is_empty(), SummaryError::NoneFound { dirs: dirs.to_vec() })?;
    let (sum, drawn) = write_outputs(out, &parts, plots)?;
    let mut rep = match parts.iter().find_map(|p| p.nominal.clone()) {
        Some(v) => v,
        None => return Err(SummaryError::NoNominal),
    };
    let obj = rep.as_object_mut().ok_or(SummaryError::NominalNotObject)?;
    obj.insert("monte_carlo".into(), serde_json::to_value(&sum).map_err(SummaryError::Json)?);
    Ok((sum, rep, drawn))
}

/// The Monte Carlo table: variant × median [p10, p90] of CEP and of the thermal share.
#[must_use]
pub fn table(s: &Summary) -> String {
    let mut t = format!(
        "monte carlo: {} runs (seed {})\n{:<11} {:>28} {:>30} {:>28}\n",
        s.runs,
        s.seed,
        "variant",
        "CEP nmi/h med [p10, p90]",
        "thermal CEP nmi/h med [p10,p90]",
        "thermal share med [p10, p90]"
    );
    for n in super::VARIANTS {
        let (Some(c), Some(th), Some(sh)) =
            (s.cep_nmi_per_h.get(n), s.thermal_cep_nmi_per_h.get(n), s.thermal_share_removed.get(n))
        else {
            continue;
        };
        let _ = writeln!(
            t,
            "{n:<11} {:>8.3} [{:>7.3}, {:>7.3}] {:>10.4} [{:>7.4}, {:>7.4}] {:>7.1}% [{:>6.1}%, {:>6.1}%]",
            c.median,
            c.p10,
            c.p90,
            th.median,
            th.p10,
            th.p90,
            100.0 * sh.median,
            100.0 * sh.p10,
            100.0 * sh.p90
        );
    }
    for (n, r) in &s.rate_clamped_share {
        let tc = s.temp_clamped_share.get(n);
        let _ = writeln!(
            t,
            "clamped {n:<11} rate {:.1}% [{:.1}, {:.1}]  temperature {} of the flight's cycles{}",
            100.0 * r.median,
            100.0 * r.p10,
            100.0 * r.p90,
            tc.map_or("not computed".to_string(), |x| format!(
                "{:.1}% [{:.1}, {:.1}]",
                100.0 * x.median,
                100.0 * x.p10,
                100.0 * x.p90
            )),
            if r.median > super::accel::CLAMPED_WARN_SHARE {
                "  WARNING: rate clamped on most of the flight in most runs"
            } else {
                ""
            }
        );
    }
    for (n, a) in &s.alignment {
        let _ = writeln!(
            t,
            "alignment |error| {n:<11} roll {:.1}″ [{:.1}, {:.1}]  pitch {:.1}″ [{:.1}, {:.1}]  heading {:.3} mrad [{:.3}, {:.3}]",
            a.roll_arcsec.median,
            a.roll_arcsec.p10,
            a.roll_arcsec.p90,
            a.pitch_arcsec.median,
            a.pitch_arcsec.p10,
            a.pitch_arcsec.p90,
            a.heading_mrad.median,
            a.heading_mrad.p10,
            a.heading_mrad.p90
        );
    }
    for tm in &s.timing {
        let _ = writeln!(
            t,
            "shard {}/{}: {} runs on {} jobs in {:.1} s: runs_per_minute={:.2}",
            tm.shard.0, tm.shard.1, tm.runs, tm.jobs, tm.wall_s, tm.runs_per_minute
        );
    }
    t
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn percentiles_interpolate_between_order_statistics() {
        // 0..=10: p10 = 1, median = 5, p90 = 9 exactly.
        let v: Vec<f64> = (0..=10).rev().map(f64::from).collect();
        let s = Stats::of(&v).unwrap();
        assert_eq!((s.p10, s.median, s.p90, s.min, s.max, s.mean), (1.0, 5.0, 9.0, 0.0, 10.0, 5.0));
        let s = Stats::of(&[1.0, 2.0]).unwrap();
        assert!((s.median - 1.5).abs() < 1e-12 && (s.p10 - 1.1).abs() < 1e-12);
        assert!(Stats::of(&[]).is_err());
        assert!(Stats::of(&[1.0, f64::NAN]).is_err());
    }

    fn outcome(run: u64, share: f64) -> Outcome {
        let m = |v: f64| -> BTreeMap<String, f64> { [("hysteresis".to_string(), v)].into_iter().collect() };
        Outcome {
            run,
            seed: run,
            temp_offset_c: 0.0,
            temp_scale: 1.0,
            case_temp_range_c: [0.0, 1.0],
            cep_nmi_per_h: m(1.0 + share),
            thermal_cep_nmi_per_h: m(1.0 - share),
            thermal_share_removed: m(share),
            share_removed_total_cep: m(share),
            alignment: BTreeMap::new(),
            rate_clamped_share: m(0.5),
            temp_clamped_share: m(0.0),
            wall_s: 1.0,
        }
    }

    fn partial(shard: (u64, u64), runs: &[u64]) -> Partial {
        Partial {
            scenario: "s".into(),
            scenario_toml: "x".into(),
            runs: 4,
            seed: 9,
            shard,
            jobs: 1,
            wall_s: 60.0,
            outcomes: runs.iter().map(|&r| outcome(r, r as f64 / 10.0)).collect(),
            nominal: None,
        }
    }

    #[test]
    fn merge_needs_every_run_once_from_one_study() {
        let scenario_toml = toml::to_string(&Scenario::builtin()).unwrap();
        let fix = |mut p: Partial| {
            p.scenario_toml.clone_from(&scenario_toml);
            p
        };
        let (a, b) = (fix(partial((0, 2), &[0, 2])), fix(partial((1, 2), &[1, 3])));
        let (sum, outs) = summarize(&[b.clone(), a.clone()]).unwrap();
        assert_eq!(outs.iter().map(|o| o.run).collect::<Vec<_>>(), vec![0, 1, 2, 3]);
        // Shares 0, 0.1, 0.2, 0.3: median 0.15, p10 0.03, p90 0.27.
        let h = sum.thermal_share_removed["hysteresis"];
        assert!(
            (h.median - 0.15).abs() < 1e-12 && (h.p10 - 0.03).abs() < 1e-12 && (h.p90 - 0.27).abs() < 1e-12,
            "{h:?}"
        );
        assert_eq!(sum.timing.len(), 2);
        assert!(summarize(std::slice::from_ref(&a)).unwrap_err().to_string().contains("missing"));
        assert!(summarize(&[a.clone(), a.clone(), b.clone()]).unwrap_err().to_string().contains("twice"));
        let mut other = b.clone();
        other.seed = 10;
        assert!(summarize(&[a, other]).unwrap_err().to_string().contains("another study"));
    }
}
