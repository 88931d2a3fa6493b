//! Monte Carlo study: N seeds of the same scenario, in parallel, summarized by median and
//! 10th / 90th percentiles.
//!
//! Run `i` of base seed `S` uses the seed `splitmix64(S + i)`, whatever the shard or
//! thread that flies it, so a study split into shards and merged gives the same numbers
//! as one process. Each run draws, from its seed:
//!
//! * the temperature variation within the scenario's `[monte_carlo]` bounds: the drive
//!   profile and ground temperature shifted by U(−`temp_offset_c`, +`temp_offset_c`), the
//!   excursion from the ground temperature scaled by U(1 ∓ `temp_scale`);
//! * unit-to-unit spread: each thermal coefficient of each of the three accelerometers
//!   multiplied by `1 + unit_spread·N(0,1)`, each DS18B20 offset moved by
//!   `sensor_offset_c·N(0,1)`; each varied unit is **recalibrated** from its own
//!   simulated four-position test (the lab's fit), as a real unit would be;
//! * the non-thermal IMU errors ([`super::errors`]) and every noise sequence.
//!
//! Every run aligns (if the scenario does) and flies `none`, `simple`, `hysteresis`,
//! `discovered` (each varied unit's own discovery run on its calibration log; off with
//! `--no-mc-discovered`) and `oracle` in lock-step ([`super::mc_variants`]). The thermal share removed by a variant
//! is `(simple − variant)/(simple − oracle)` on that run's **thermal-only** CEP rate (the
//! radial growth of variant − oracle position, same sensor data; the oracle's is 0 by
//! construction), so the gyro error's sign cannot flip it. The share on total CEP is kept
//! per run in `mc_runs.csv` for comparison.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use rand::{Rng, RngExt, SeedableRng};
use rand_distr::{Distribution, StandardNormal};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::align::AlignErrors;
use super::run::{self, Figures};
use super::scenario::{Scenario, Variation};
use super::{mc_variants, share, thermal_ceps, truths_seeded, units, NavigateArgs, Tables};
use crate::simulate::truth::Truth;

/// What to run.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    /// Runs in the whole study.
    pub runs: u64,
    /// Base seed.
    pub seed: u64,
    /// Worker threads (0: all cores).
    pub jobs: usize,
    /// This shard `(k, n)`: the runs `i` with `i mod n = k`.
    pub shard: (u64, u64),
    /// Run the discovery workflow on each unit's calibration log and fly `discovered`
    /// (about doubles a run's cost).
    pub discover: bool,
    /// The lab program each run's units are calibrated on.
    pub lab: super::calib::LabProgram,
    /// Experiment only: every table's rate limit, °C/min, in place of the fitted one.
    pub rate_limit_override: Option<f32>,
}

impl Plan {
    /// From the command-line arguments.
    #[must_use]
    pub fn of(args: &NavigateArgs, sc: &Scenario, shard: (u64, u64)) -> Self {
        Self {
            runs: args.runs,
            seed: args.mc_seed.unwrap_or(sc.seed),
            jobs: args.jobs,
            shard,
            discover: !args.no_mc_discovered,
            lab: args.lab_program,
            rate_limit_override: args.rate_limit_override,
        }
    }

    /// Run indices of this shard.
    #[must_use]
    pub fn indices(&self) -> Vec<u64> {
        (0..self.runs).filter(|i| i % self.shard.1.max(1) == self.shard.0).collect()
    }
}

/// One run's figures.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Outcome {
    /// Run index.
    pub run: u64,
    /// Its seed.
    pub seed: u64,
    /// Temperature shift drawn, °C.
    pub temp_offset_c: f64,
    /// Excursion scale drawn.
    pub temp_scale: f64,
    /// Case temperature range flown, °C.
    pub case_temp_range_c: [f64; 2],
    /// Total CEP rate per variant, nmile/h.
    pub cep_nmi_per_h: BTreeMap<String, f64>,
    /// Thermal-only CEP rate per variant (variant − oracle), nmile/h.
    pub thermal_cep_nmi_per_h: BTreeMap<String, f64>,
    /// Thermal share removed per variant (on the thermal-only CEP rate).
    pub thermal_share_removed: BTreeMap<String, f64>,
    /// The same share on total CEP rate (sign-sensitive: for comparison only).
    pub share_removed_total_cep: BTreeMap<String, f64>,
    /// Alignment errors per variant (empty: alignment off).
    pub alignment: BTreeMap<String, AlignErrors>,
    /// Share of the flight's IMU cycles with `RATE_OUT_OF_RANGE`, per table variant.
    #[serde(default)]
    pub rate_clamped_share: BTreeMap<String, f64>,
    /// Share of the flight's IMU cycles with `TEMP_OUT_OF_RANGE`, per table variant.
    #[serde(default)]
    pub temp_clamped_share: BTreeMap<String, f64>,
    /// Wall time of the run (calibration and flight), s.
    pub wall_s: f64,
}

/// A shard's result, `mc_partial_K_of_N.json`.
#[derive(Clone, Debug, Serialize, Deserialize)]
pub struct Partial {
    /// Scenario name.
    pub scenario: String,
    /// The scenario itself (TOML), so merge can refuse mixed studies.
    pub scenario_toml: String,
    /// Runs in the whole study.
    pub runs: u64,
    /// Base seed.
    pub seed: u64,
    /// `(k, n)`.
    pub shard: (u64, u64),
    /// Worker threads used.
    pub jobs: usize,
    /// Wall time of this shard's runs, s.
    pub wall_s: f64,
    /// The runs.
    pub outcomes: Vec<Outcome>,
    /// The nominal single-run report (shard 0 only).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub nominal: Option<serde_json::Value>,
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
    pub fn of(values: &[f64]) -> anyhow::Result<Self> {
        anyhow::ensure!(!values.is_empty(), "no values");
        anyhow::ensure!(values.iter().all(|x| x.is_finite()), "non-finite value");
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

fn splitmix64(mut z: u64) -> u64 {
    z = z.wrapping_add(0x9E37_79B9_7F4A_7C15);
    z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
    z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
    z ^ (z >> 31)
}

/// The three units with their unit-to-unit spread drawn from `rng`.
pub fn varied_units<R: Rng + ?Sized>(v: &Variation, rng: &mut R) -> [Truth; 3] {
    let mut us = units();
    let mut f = |x: &mut f64| {
        let z: f64 = StandardNormal.sample(rng);
        *x *= 1.0 + v.unit_spread * z;
    };
    for u in &mut us {
        let s = &mut u.scale;
        for c in [&mut s.mu, &mut s.beta, &mut s.epsilon, &mut s.eta, &mut s.alpha] {
            let mut x = f64::from(*c);
            f(&mut x);
            *c = x as f32;
        }
        let b = &mut u.bias;
        for c in [&mut b.k0_g, &mut b.b1_g_per_c, &mut b.b2_g_per_c2] {
            f(c);
        }
    }
    for u in &mut us {
        let z: f64 = StandardNormal.sample(rng);
        u.sensor.offset_c += v.sensor_offset_c * z;
    }
    us
}

/// What run `i` of a study flies.
#[derive(Clone, Debug)]
pub struct Draw {
    /// The scenario with the run's seed and temperature variation.
    pub scenario: Scenario,
    /// The three units with their spread.
    pub units: [Truth; 3],
    /// The run's seed, `splitmix64(base + i)`.
    pub seed: u64,
    /// Temperature shift, °C.
    pub temp_offset_c: f64,
    /// Excursion scale.
    pub temp_scale: f64,
}

/// The draws of run `i` of base seed `seed` (see the module doc).
#[must_use]
pub fn draw(sc: &Scenario, seed: u64, i: u64) -> Draw {
    let rs = splitmix64(seed.wrapping_add(i));
    let mut rng = rand::rngs::Xoshiro256PlusPlus::seed_from_u64(rs);
    let v = sc.monte_carlo;
    let off = if v.temp_offset_c > 0.0 { rng.random_range(-v.temp_offset_c..=v.temp_offset_c) } else { 0.0 };
    let scale = if v.temp_scale > 0.0 { 1.0 + rng.random_range(-v.temp_scale..=v.temp_scale) } else { 1.0 };
    let mut s = sc.clone().with_temperature_variation(off, scale);
    s.seed = rs;
    let units = varied_units(&v, &mut rng);
    Draw { scenario: s, units, seed: rs, temp_offset_c: off, temp_scale: scale }
}

/// The tables run `d` flies: its units calibrated (`discover` adds the `discovered`
/// variant), carrying the triad's known misalignment matrix.
///
/// # Errors
/// Calibration.
pub fn tables_of(d: &Draw, discover: bool) -> anyhow::Result<Tables> {
    tables_on(d, &super::calib::CalibOptions { discover, ..super::calib::CalibOptions::default() })
}

/// [`tables_of`] with the calibration options `opts`.
///
/// # Errors
/// Calibration.
pub fn tables_on(d: &Draw, opts: &super::calib::CalibOptions) -> anyhow::Result<Tables> {
    let mut tables = super::calibrate_opts(&d.units, d.seed, 1, opts)?;
    tables.misalignment = d.scenario.imu.accel.carried_misalignment();
    Ok(tables)
}

/// Fly draw `d` with `tables` (possibly edited, for an experiment) and return the
/// hysteresis variant's thermal share removed, `(simple − hysteresis)/(simple − oracle)`.
///
/// # Errors
/// Flight, or a share that cannot be computed.
pub fn hysteresis_share(d: &Draw, tables: &Tables) -> anyhow::Result<f64> {
    let r = run::fly(&d.scenario, &mut truths_seeded(&d.units, d.seed), mc_variants(tables)?)?;
    let th = thermal_ceps(&r)?;
    share(th["simple"], th["hysteresis"], th["oracle"])
}

/// Fly run `i` of base seed `seed`; `discover` adds the `discovered` variant.
///
/// # Errors
/// Calibration, flight, or a share that cannot be computed.
pub fn one(sc: &Scenario, seed: u64, i: u64, discover: bool) -> anyhow::Result<Outcome> {
    one_on(sc, seed, i, &super::calib::CalibOptions { discover, ..super::calib::CalibOptions::default() })
}

/// [`one`] with the units calibrated with `opts` (validation is never run here).
///
/// # Errors
/// Calibration, flight, or a share that cannot be computed.
pub fn one_on(sc: &Scenario, seed: u64, i: u64, opts: &super::calib::CalibOptions) -> anyhow::Result<Outcome> {
    let t0 = Instant::now();
    let d = draw(sc, seed, i);
    let tables = tables_on(&d, opts).with_context(|| format!("run {i}: calibration"))?;
    let Draw { scenario: s, units: us, seed: rs, temp_offset_c: off, temp_scale: scale } = d;
    let res =
        run::fly(&s, &mut truths_seeded(&us, rs), mc_variants(&tables)?).with_context(|| format!("run {i}: flight"))?;
    let cep: BTreeMap<String, f64> =
        res.names.iter().zip(&res.tracks).map(|(n, tr)| (n.clone(), Figures::of(&res.t, tr).cep_nmi_per_h)).collect();
    let thermal = thermal_ceps(&res)?;
    let mut ts = BTreeMap::new();
    let mut tot = BTreeMap::new();
    for n in cep.keys() {
        ts.insert(
            n.clone(),
            share(thermal["simple"], thermal[n], thermal["oracle"]).with_context(|| format!("run {i}"))?,
        );
        tot.insert(n.clone(), share(cep["simple"], cep[n], cep["oracle"]).with_context(|| format!("run {i}"))?);
    }
    let lo = res.temps.iter().map(|t| t[1]).fold(f64::INFINITY, f64::min);
    let hi = res.temps.iter().map(|t| t[1]).fold(f64::NEG_INFINITY, f64::max);
    let flags = super::flag_shares(&res).with_context(|| format!("run {i}"))?;
    Ok(Outcome {
        rate_clamped_share: flags.iter().map(|(n, f)| (n.clone(), f.rate_clamped)).collect(),
        temp_clamped_share: flags.iter().map(|(n, f)| (n.clone(), f.temp_clamped)).collect(),
        run: i,
        seed: rs,
        temp_offset_c: off,
        temp_scale: scale,
        case_temp_range_c: [lo, hi],
        cep_nmi_per_h: cep,
        thermal_cep_nmi_per_h: thermal,
        thermal_share_removed: ts,
        share_removed_total_cep: tot,
        alignment: res.names.iter().cloned().zip(res.alignment.iter().copied()).collect(),
        wall_s: t0.elapsed().as_secs_f64(),
    })
}

/// Fly the runs of `plan`'s shard on `plan.jobs` threads (rayon), with a progress bar
/// when `progress`.
///
/// # Errors
/// Thread pool, or the first failed run.
pub fn run(sc: &Scenario, plan: &Plan, progress: bool) -> anyhow::Result<Partial> {
    let idx = plan.indices();
    let mut b = rayon::ThreadPoolBuilder::new();
    if plan.jobs > 0 {
        b = b.num_threads(plan.jobs);
    }
    let pool = b.build().context("thread pool")?;
    let jobs = pool.current_num_threads();
    let pb = if progress { indicatif::ProgressBar::new(idx.len() as u64) } else { indicatif::ProgressBar::hidden() };
    pb.set_style(
        indicatif::ProgressStyle::with_template(
            "monte carlo {pos}/{len} runs [{elapsed_precise} < {eta_precise}] {msg}",
        )
        .unwrap_or_else(|_| indicatif::ProgressStyle::default_bar()),
    );
    pb.set_message(format!("{jobs} jobs"));
    let t0 = Instant::now();
    let outcomes: Vec<anyhow::Result<Outcome>> = pool.install(|| {
        idx.par_iter()
            .map(|&i| {
                let opts = super::calib::CalibOptions {
                    discover: plan.discover,
                    validate: false,
                    lab: plan.lab,
                    rate_limit_override: plan.rate_limit_override,
                };
                let r = one_on(sc, plan.seed, i, &opts);
                pb.inc(1);
                r
            })
            .collect()
    });
    pb.finish_and_clear();
    let wall_s = t0.elapsed().as_secs_f64();
    let outcomes = outcomes.into_iter().collect::<anyhow::Result<Vec<_>>>()?;
    Ok(Partial {
        scenario: sc.name.clone(),
        scenario_toml: toml::to_string(sc)?,
        runs: plan.runs,
        seed: plan.seed,
        shard: plan.shard,
        jobs,
        wall_s,
        outcomes,
        nominal: None,
    })
}

fn stats_by(
    outs: &[&Outcome],
    f: impl Fn(&Outcome) -> &BTreeMap<String, f64>,
) -> anyhow::Result<BTreeMap<String, Stats>> {
    let mut m: BTreeMap<String, Vec<f64>> = BTreeMap::new();
    for o in outs {
        for (k, v) in f(o) {
            m.entry(k.clone()).or_default().push(*v);
        }
    }
    m.into_iter().map(|(k, v)| Ok((k.clone(), Stats::of(&v).with_context(|| k.clone())?))).collect()
}

/// Combine partial results of one study: same scenario, seed and run count, every run
/// index exactly once.
///
/// # Errors
/// Mixed studies, duplicated or missing runs, statistics of no runs.
pub fn summarize(parts: &[Partial]) -> anyhow::Result<(Summary, Vec<Outcome>)> {
    let first = parts.first().ok_or_else(|| anyhow::anyhow!("no partial results"))?;
    for p in parts {
        anyhow::ensure!(
            p.scenario_toml == first.scenario_toml && p.seed == first.seed && p.runs == first.runs,
            "shard {}/{} is from another study (scenario, seed or run count differ)",
            p.shard.0,
            p.shard.1
        );
    }
    let mut outs: Vec<Outcome> = parts.iter().flat_map(|p| p.outcomes.iter().cloned()).collect();
    outs.sort_by_key(|o| o.run);
    for w in outs.windows(2) {
        anyhow::ensure!(w[0].run != w[1].run, "run {} appears twice", w[0].run);
    }
    let have: std::collections::BTreeSet<u64> = outs.iter().map(|o| o.run).collect();
    let missing: Vec<u64> = (0..first.runs).filter(|i| !have.contains(i)).collect();
    anyhow::ensure!(
        missing.is_empty(),
        "{} of {} runs missing (first: {:?})",
        missing.len(),
        first.runs,
        &missing[..missing.len().min(10)]
    );
    let refs: Vec<&Outcome> = outs.iter().collect();
    let mut alignment = BTreeMap::new();
    if let Some(o) = outs.first() {
        for n in o.alignment.keys() {
            let col = |f: &dyn Fn(&AlignErrors) -> f64| -> anyhow::Result<Stats> {
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
    let sc: Scenario = toml::from_str(&first.scenario_toml)?;
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
/// `mc_thermal_cep.png` and `mc_cep.png` (empirical distribution functions) to `out`.
///
/// # Errors
/// As [`summarize`], I/O or drawing.
pub fn write_outputs(out: &Path, parts: &[Partial], plots: bool) -> anyhow::Result<Summary> {
    let (sum, outs) = summarize(parts)?;
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let names: Vec<String> = sum.cep_nmi_per_h.keys().cloned().collect();
    let mut s = String::from("run,seed,temp_offset_c,temp_scale,case_min_c,case_max_c");
    for n in &names {
        let _ = write!(s, ",{n}_cep_nmi_per_h,{n}_thermal_cep_nmi_per_h,{n}_thermal_share,{n}_share_total_cep,{n}_roll_arcsec,{n}_pitch_arcsec,{n}_heading_mrad,{n}_rate_clamped_share,{n}_temp_clamped_share");
    }
    s.push_str(",clamped_warning");
    s.push_str(",wall_s\n");
    for o in &outs {
        let _ = write!(
            s,
            "{},{},{:.3},{:.4},{:.2},{:.2}",
            o.run, o.seed, o.temp_offset_c, o.temp_scale, o.case_temp_range_c[0], o.case_temp_range_c[1]
        );
        for n in &names {
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
    std::fs::write(out.join("mc_runs.csv"), s)?;
    if plots {
        let col =
            |f: &dyn Fn(&Outcome) -> &BTreeMap<String, f64>, scale: f64, skip: &[&str]| -> Vec<(String, Vec<f64>)> {
                names
                    .iter()
                    .filter(|n| !skip.contains(&n.as_str()))
                    .map(|n| (n.clone(), outs.iter().map(|o| f(o)[n] * scale).collect()))
                    .collect()
            };
        let title = format!("{} runs", outs.len());
        super::plot::plot_distributions(
            &out.join("mc_thermal_share.png"),
            &format!("thermal share removed, (simple − v)/(simple − oracle) on thermal-only CEP; {title}"),
            "thermal share removed (%)",
            // `none` (several hundred % negative) would squash the scale.
            &col(&|o| &o.thermal_share_removed, 100.0, &["none", "simple", "oracle"]),
        )
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        super::plot::plot_distributions(
            &out.join("mc_thermal_cep.png"),
            &format!("thermal-only CEP rate (variant − oracle, same sensor data); {title}"),
            "thermal-only CEP (nmile/h)",
            &col(&|o| &o.thermal_cep_nmi_per_h, 1.0, &["none", "oracle"]),
        )
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
        super::plot::plot_distributions(
            &out.join("mc_cep.png"),
            &format!("CEP rate (radial growth) per variant; {title}"),
            "CEP (nmile/h)",
            &col(&|o| &o.cep_nmi_per_h, 1.0, &[]),
        )
        .map_err(|e| anyhow::anyhow!("plot: {e}"))?;
    }
    Ok(sum)
}

/// `qfa-lab navigate merge DIR…`: read every `mc_partial_*.json` in `dirs`, combine,
/// write `report.json` (the nominal run's keys from shard 0 plus `monte_carlo`),
/// `mc_runs.csv` and the plots to `out`.
///
/// # Errors
/// I/O, parse, or [`summarize`]'s checks.
pub fn merge(dirs: &[PathBuf], out: &Path, plots: bool) -> anyhow::Result<Summary> {
    let mut parts = Vec::new();
    for d in dirs {
        let mut files: Vec<PathBuf> = if d.is_dir() {
            std::fs::read_dir(d)
                .with_context(|| format!("reading {}", d.display()))?
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
            let text = std::fs::read_to_string(&f).with_context(|| format!("reading {}", f.display()))?;
            parts.push(serde_json::from_str::<Partial>(&text).with_context(|| format!("parsing {}", f.display()))?);
        }
    }
    anyhow::ensure!(!parts.is_empty(), "no mc_partial_*.json found in {dirs:?}");
    let sum = write_outputs(out, &parts, plots)?;
    let mut rep = match parts.iter().find_map(|p| p.nominal.clone()) {
        Some(v) => v,
        None => anyhow::bail!("no shard 0 (the nominal run) among the partial results"),
    };
    let obj = rep.as_object_mut().ok_or_else(|| anyhow::anyhow!("nominal report is not an object"))?;
    obj.insert("monte_carlo".into(), serde_json::to_value(&sum)?);
    std::fs::write(out.join("report.json"), serde_json::to_string_pretty(&rep)?)?;
    Ok(sum)
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

    #[test]
    fn shards_partition_the_runs() {
        let mut all = Vec::new();
        for k in 0..3 {
            all.extend(
                Plan {
                    runs: 10,
                    seed: 1,
                    jobs: 1,
                    shard: (k, 3),
                    discover: false,
                    lab: super::super::calib::LabProgram::Paper,
                    rate_limit_override: None,
                }
                .indices(),
            );
        }
        all.sort_unstable();
        assert_eq!(all, (0..10).collect::<Vec<_>>());
    }
}
