//! Discovery workflow (issue 4): find where the model and a thermal-test log disagree,
//! name the missing physical effect from the catalog, add it in the form the firmware
//! runs (a root-crate extension slot or Eq. 11 term), and show on held-out data that the
//! gap shrank. Says `none` when nothing significant is missing.
//!
//! # Workflow
//! 1. **Channels** ([`channels`]): pair the ±1 g runs of each program by time,
//!    `K1 = (A₊ − A₋)/2`, `K0 = (A₊ + A₋)/(2·K1)`, average into 60-s bins; T and Ṫ come
//!    from the root crate's `RateEstimator<32>` on raw = round(16·T), the mean of the two
//!    runs' readings. A single-channel log `time_s,temp_c,value` is the bias channel.
//! 2. **Start model** ([`Start`]): `simple` = K1 and K0 linear in ΔT (Eq. 3–4, the bias
//!    on a 16-point grid with equal branches); `paper` = Eq. 11 and a single-valued bias
//!    grid fitted by least squares with a gentle smoothness penalty.
//! 3. **Held-out rule** (every figure of merit is held out): a cycling log's programs are
//!    sorted by ramp rate and dealt alternately into two folds (0.3/0.7 and 0.5/0.9 °C/min
//!    for the paper's test); each fold is fitted on the other and evaluated on itself,
//!    so each bin's residual comes from a model that never saw its program. With one
//!    program, or a single-channel log, each trace is cut into 20-bin (20-min) time blocks
//!    dealt alternately into the two folds (interleaved blocks: every fold sees heating,
//!    cooling and holds at every temperature). Model states always run through the whole trace; only the fit skips
//!    the held-out bins. Nonlinear parameters are searched on the training fold only.
//! 4. **Localization** ([`localize`]): RMS of the held-out residual by heating / cooling
//!    ramps × program rate × temperature band, and holds by time since the last change.
//! 5. **Candidates**: each catalog effect not yet in the model. Nonlinear parameters by a
//!    coarse log-grid then golden section (τ, r) or Nelder–Mead (creep τ_ref, E; T_ref
//!    fixed at 22 °C); linear coefficients re-fitted by least squares for every trial;
//!    every trial scored by running the root crate's `AxisModel::evaluate`.
//! 6. **Selection**: gain = drop of the held-out Σ(residual/noise floor)² over both
//!    channels. The noise floor is the held-out residual's bin-to-bin part,
//!    1.4826·median|r[i+1] − r[i]|/√2. A candidate is significant if its gain exceeds the
//!    BIC-style penalty k·ln N (k added parameters) and 5 % of N (the affected channels'
//!    held-out bins: it must remove at least 5 % of a noise variance per bin), and the
//!    affected channel's held-out RMS must drop by at least 2 %. The best
//!    significant candidate (gain − penalty) is added; repeat until none is left.

pub mod channels;
pub mod fit;
pub mod output;
pub mod synth;

use std::path::Path;

use anyhow::Result;
use qfa_thermal::model::AxisModel;
use serde::Serialize;

pub use channels::{Channels, LogKind};
pub use fit::Effect;
use fit::{golden, nelder_mead2, Fitted, Nonlinear, Residuals, Setup, Structure};

/// Start model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Start {
    /// K1 and K0 linear in ΔT (paper Eq. 3–4).
    Simple,
    /// Eq. 11 scale factor, single-valued smooth bias.
    Paper,
}

impl std::str::FromStr for Start {
    type Err = anyhow::Error;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "simple" => Ok(Start::Simple),
            "paper" => Ok(Start::Paper),
            _ => anyhow::bail!("start must be simple or paper, not {s:?}"),
        }
    }
}

impl Start {
    /// Name as in the CLI and report.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Start::Simple => "simple",
            Start::Paper => "paper",
        }
    }
}

/// An effect added by the workflow.
#[derive(Clone, Debug, Serialize)]
pub struct EffectReport {
    /// Catalog name.
    pub name: String,
    /// `scale_factor`, `bias` or `both`.
    pub channel: String,
    /// Fitted parameters (from the fit on all data).
    pub params: std::collections::BTreeMap<String, f64>,
    /// Held-out gap of its channel before it was added (for `both`: the channel it
    /// improved more, relative to its noise floor).
    pub heldout_gap_before: f64,
    /// The same gap after.
    pub heldout_gap_after: f64,
}

/// Held-out gaps: RMS residuals.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum Gaps {
    /// Cycling log.
    Cycling {
        /// Scale factor, ppm.
        scale_factor_ppm: f64,
        /// Bias, µg.
        bias_ug: f64,
    },
    /// Single-channel log, value units.
    Single {
        /// RMS of the value residual.
        value_rms: f64,
    },
}

/// A localized disagreement.
#[derive(Clone, Debug, Serialize)]
pub struct Where {
    /// Channel.
    pub channel: String,
    /// Human-readable segment.
    pub segment: String,
    /// Held-out RMS there (ppm, µg or value units).
    pub rms: f64,
}

/// One candidate tried in one round.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateTrial {
    /// Catalog name.
    pub name: String,
    /// Channel.
    pub channel: String,
    /// Held-out normalized gain.
    pub gain: f64,
    /// Penalty k·ln N.
    pub penalty: f64,
    /// Passed the significance threshold.
    pub significant: bool,
    /// Held-out gaps with it.
    pub gaps: Gaps,
}

/// The discovery report; `report.json` is its serialization.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Start model.
    pub start: Start,
    /// Effects added, in order.
    pub effects: Vec<EffectReport>,
    /// Held-out gaps of the start model.
    pub heldout_gap_before: Gaps,
    /// Held-out gaps of the final model.
    pub heldout_gap_after: Gaps,
    /// Where the start model disagrees most (held out).
    #[serde(rename = "where")]
    pub where_: Vec<Where>,
    /// Noise floors of the final held-out residual.
    pub noise_floor: Gaps,
    /// Every candidate of every round (for the Markdown report).
    #[serde(skip)]
    pub rounds: Vec<Vec<CandidateTrial>>,
    /// Where the final model disagrees most.
    #[serde(skip)]
    pub where_after: Vec<Where>,
    /// The final model.
    #[serde(skip)]
    pub model: Option<AxisModel>,
    /// Held-out residuals before and after.
    #[serde(skip)]
    pub residuals: (Residuals, Residuals),
    /// The held-out rule applied.
    #[serde(skip)]
    pub heldout_rule: String,
}

/// Bins per time block of the single-trace held-out split (20 min at 60-s bins): short
/// enough that both folds see every temperature region on heating and cooling.
const TIME_BLOCK_BINS: usize = 20;

/// Held-out folds: per fold, the mask of its test bins.
fn folds(ch: &Channels) -> (Vec<Vec<bool>>, String) {
    let n = ch.n_bins();
    let mut masks = vec![vec![false; n]; 2];
    let mut offs = Vec::new();
    let mut o = 0;
    for t in &ch.traces {
        offs.push(o);
        o += t.bins.len();
    }
    if ch.kind == LogKind::Cycling && ch.traces.len() >= 2 {
        let mut order: Vec<usize> = (0..ch.traces.len()).collect();
        order.sort_by(|&a, &b| ch.traces[a].ramp_rate().total_cmp(&ch.traces[b].ramp_rate()).then(a.cmp(&b)));
        let mut desc = [Vec::new(), Vec::new()];
        for (rank, &ti) in order.iter().enumerate() {
            let k = rank % 2;
            let t = &ch.traces[ti];
            for b in 0..t.bins.len() {
                masks[k][offs[ti] + b] = true;
            }
            desc[k].push(format!("{} ({:.1} °C/min)", t.program, t.ramp_rate()));
        }
        let rule = format!(
            "leave-programs-out, 2 folds by ramp-rate rank: fold A = {}; fold B = {}; each fold fitted on the other",
            desc[0].join(", "),
            desc[1].join(", ")
        );
        (masks, rule)
    } else {
        for (ti, t) in ch.traces.iter().enumerate() {
            let m = t.bins.len();
            for b in 0..m {
                masks[(b / TIME_BLOCK_BINS) % 2][offs[ti] + b] = true;
            }
        }
        let rule = format!(
            "split in time: blocks of {TIME_BLOCK_BINS} bins dealt alternately into 2 folds; each fold fitted on the other"
        );
        (masks, rule)
    }
}

/// Robust noise floor of a per-bin residual from consecutive-bin differences.
fn noise_floor(ch: &Channels, v: &[f64]) -> f64 {
    let mut d = Vec::new();
    let mut o = 0;
    for t in &ch.traces {
        let m = t.bins.len();
        for i in o + 1..o + m {
            let x = v[i] - v[i - 1];
            if x.is_finite() {
                d.push(x.abs());
            }
        }
        o += m;
    }
    if d.is_empty() {
        return 1.0;
    }
    d.sort_by(f64::total_cmp);
    let med = d[d.len() / 2];
    (1.4826 * med / std::f64::consts::SQRT_2).max(1e-12)
}

fn rms(v: &[f64]) -> f64 {
    let (s, n) = v.iter().filter(|x| x.is_finite()).fold((0.0, 0usize), |(s, n), x| (s + x * x, n + 1));
    if n == 0 {
        0.0
    } else {
        (s / n as f64).sqrt()
    }
}

fn gaps(kind: LogKind, r: &Residuals) -> Gaps {
    match kind {
        LogKind::Cycling => Gaps::Cycling { scale_factor_ppm: rms(&r.sf), bias_ug: rms(&r.bias) },
        LogKind::Single => Gaps::Single { value_rms: rms(&r.bias) },
    }
}

/// Held-out evaluation of a structure with per-fold nonlinear parameters.
fn heldout(setup: &Setup, s: &Structure, nls: &[Nonlinear], masks: &[Vec<bool>]) -> Residuals {
    let n = setup.ch.n_bins();
    let mut out = Residuals { sf: vec![f64::NAN; n], bias: vec![f64::NAN; n] };
    for (k, test) in masks.iter().enumerate() {
        let train: Vec<bool> = test.iter().map(|&t| !t).collect();
        let f = setup.fit(s, &nls[k], &train);
        let r = setup.residuals(&f.pred);
        for (i, _) in test.iter().enumerate().filter(|(_, &t)| t) {
            out.sf[i] = r.sf[i];
            out.bias[i] = r.bias[i];
        }
    }
    out
}

/// Search the nonlinear parameters `e` adds, on the `train` bins.
fn search(setup: &Setup, s: &Structure, nl: &Nonlinear, e: Effect, train: &[bool]) -> Nonlinear {
    let obj = |n: &Nonlinear| {
        let f = setup.fit(s, n, train);
        setup.score(&setup.residuals(&f.pred), train)
    };
    let grid_1d = |pts: &[f64], set: &dyn Fn(f64) -> Nonlinear| -> Nonlinear {
        let vals: Vec<f64> = pts.iter().map(|&p| obj(&set(p))).collect();
        let b = (0..pts.len()).min_by(|&i, &j| vals[i].total_cmp(&vals[j])).unwrap_or(0);
        let lo = pts[b.saturating_sub(1)].ln();
        let hi = pts[(b + 1).min(pts.len() - 1)].ln();
        let (x, fx) = golden(|x| obj(&set(x.exp())), lo, hi, 9);
        if fx < vals[b] {
            set(x.exp())
        } else {
            set(pts[b])
        }
    };
    match e {
        Effect::SensorLag => grid_1d(&[30.0, 60.0, 120.0, 240.0, 480.0, 960.0, 1920.0, 3840.0], &|t| Nonlinear {
            lag_tau_s: Some(t as f32),
            ..*nl
        }),
        Effect::BiasBranchHysteresis => grid_1d(&[0.15, 0.3, 0.6, 1.2, 2.5, 5.0, 10.0, 20.0], &|r| Nonlinear {
            play_r_c: Some(r as f32),
            ..*nl
        }),
        Effect::BiasCreep => {
            let set = |x: [f64; 2]| Nonlinear {
                creep: Some((x[0].exp().clamp(1.0, 1e6) as f32, (x[1] * 1000.0).clamp(0.0, 20_000.0) as f32)),
                ..*nl
            };
            let mut best = ([0.0, 0.0], f64::INFINITY);
            for &tau in &[150.0f64, 450.0, 1350.0, 4000.0, 12_000.0, 36_000.0] {
                for &ek in &[0.0, 2.5, 5.0] {
                    let x = [tau.ln(), ek];
                    let v = obj(&set(x));
                    if v < best.1 {
                        best = (x, v);
                    }
                }
            }
            let (x, v) = nelder_mead2(|x| obj(&set(x)), best.0, [0.5, 1.0], 24);
            set(if v < best.1 { x } else { best.0 })
        }
        _ => *nl,
    }
}

fn effect_params(e: Effect, m: &AxisModel) -> std::collections::BTreeMap<String, f64> {
    let mut p = std::collections::BTreeMap::new();
    let s = &m.scale;
    match e {
        Effect::TempQuadSf => {
            p.insert("beta".into(), f64::from(s.beta));
        }
        Effect::TempQuadBias => {
            // Curvature of the grid: second difference / step².
            let g = &m.bias.heating_g;
            let h = f64::from(m.bias.t_step_c);
            let n = g.len();
            let c: f64 = (1..n - 1).map(|i| f64::from(g[i + 1] - 2.0 * g[i] + g[i - 1])).sum::<f64>()
                / ((n - 2) as f64 * h * h);
            p.insert("beta_g_per_c2".into(), c / 2.0);
        }
        Effect::RateHysteresis => {
            p.insert("epsilon".into(), f64::from(s.epsilon));
        }
        Effect::RateSquared => {
            p.insert("alpha".into(), f64::from(s.alpha));
        }
        Effect::RateTempCoupling => {
            p.insert("eta".into(), f64::from(s.eta));
        }
        Effect::SensorLag => {
            if let Some(l) = m.ext.sensor_lag {
                p.insert("tau_s".into(), f64::from(l.tau_s));
            }
        }
        Effect::BiasBranchHysteresis => {
            if let Some(h) = m.ext.bias_branch_hysteresis {
                p.insert("half_width_c".into(), f64::from(h.half_width_c));
                p.insert("weight_g".into(), f64::from(h.weight_g));
            }
        }
        Effect::BiasCreep => {
            if let Some(c) = m.ext.bias_creep {
                p.insert("gain_g_per_c".into(), f64::from(c.gain_g_per_c));
                p.insert("tau_ref_s".into(), f64::from(c.tau_ref_s));
                p.insert("t_ref_c".into(), f64::from(c.t_ref_c));
                p.insert("activation_k".into(), f64::from(c.activation_k));
            }
        }
    }
    p
}

/// Localize the disagreement of held-out residuals `r`: worst segments per channel.
#[must_use]
pub fn localize(ch: &Channels, r: &Residuals, top: usize) -> Vec<Where> {
    use std::collections::BTreeMap;
    // Temperature bands: a round width giving 4..8 bands.
    let (mut lo, mut hi) = (f64::INFINITY, f64::NEG_INFINITY);
    for t in &ch.traces {
        for &x in &t.est_t {
            lo = lo.min(f64::from(x));
            hi = hi.max(f64::from(x));
        }
    }
    let width = [5.0, 10.0, 20.0, 30.0, 50.0].into_iter().find(|w| (hi - lo) / w <= 7.0).unwrap_or(100.0);
    let mut acc: BTreeMap<(usize, String), (f64, usize)> = BTreeMap::new();
    let mut i = 0;
    for t in &ch.traces {
        let rate = t.ramp_rate();
        let mut last_change = t.time_s.first().copied().unwrap_or(0.0);
        let mut row = 0;
        for b in &t.bins {
            while row < b.hi {
                if t.est_rate[row].abs() > 0.05 {
                    last_change = t.time_s[row];
                }
                row += 1;
            }
            let m = (b.hi - b.lo) as f64;
            let tm: f64 = t.est_t[b.lo..b.hi].iter().map(|&x| f64::from(x)).sum::<f64>() / m;
            let rm: f64 = t.est_rate[b.lo..b.hi].iter().map(|&x| f64::from(x)).sum::<f64>() / m;
            let band = (tm / width).floor() * width;
            let seg = if rm.abs() > 0.05 {
                format!(
                    "{} ramps {rate:.1} °C/min, {band:.0}..{:.0} °C",
                    if rm > 0.0 { "heating" } else { "cooling" },
                    band + width
                )
            } else {
                let since = (b.time_s - last_change) / 60.0;
                let bucket = if since < 10.0 {
                    "0..10 min"
                } else if since < 30.0 {
                    "10..30 min"
                } else {
                    "over 30 min"
                };
                format!("holds {bucket} after a temperature change, {band:.0}..{:.0} °C", band + width)
            };
            for (c, v) in [(0usize, r.sf[i]), (1, r.bias[i])] {
                if v.is_finite() {
                    let e = acc.entry((c, seg.clone())).or_insert((0.0, 0));
                    e.0 += v * v;
                    e.1 += 1;
                }
            }
            i += 1;
        }
    }
    let mut out = Vec::new();
    for c in 0..2 {
        let name = match (c, ch.kind) {
            (0, _) => "scale_factor",
            (_, LogKind::Cycling) => "bias",
            _ => "value",
        };
        let mut v: Vec<Where> = acc
            .iter()
            .filter(|((cc, _), (_, n))| *cc == c && *n >= 5)
            .map(|((_, seg), (s, n))| Where { channel: name.into(), segment: seg.clone(), rms: (s / *n as f64).sqrt() })
            .collect();
        v.sort_by(|a, b| b.rms.total_cmp(&a.rms));
        v.truncate(top);
        out.extend(v);
    }
    out
}

/// Run the workflow on `input` from `start` and write the outputs to `out_dir`.
///
/// # Errors
/// Output files could not be written.
pub fn discover(input: &Channels, start: Start, out_dir: &Path) -> Result<Report> {
    let report = analyze(input, start);
    output::write(input, &report, out_dir)?;
    Ok(report)
}

/// The workflow without writing anything.
#[must_use]
pub fn analyze(ch: &Channels, start: Start) -> Report {
    let mut setup = Setup::new(ch);
    let (masks, rule) = folds(ch);
    let nf = masks.len();
    let trains: Vec<Vec<bool>> = masks.iter().map(|m| m.iter().map(|&t| !t).collect()).collect();
    let all = vec![true; ch.n_bins()];
    let cyc = ch.kind == LogKind::Cycling;

    let mut s = Structure::start(start);
    let mut nls = vec![Nonlinear::default(); nf];
    let mut nl_all = Nonlinear::default();
    let mut cur = heldout(&setup, &s, &nls, &masks);
    let before = cur.clone();
    let n_bins = ch.n_bins() as f64;
    let mut effects = Vec::new();
    let mut rounds = Vec::new();
    loop {
        setup.sigma_sf = if cyc { noise_floor(ch, &cur.sf) } else { 1.0 };
        setup.sigma_b = noise_floor(ch, &cur.bias);
        let cur_score = setup.score(&cur, &all);
        let mut trials = Vec::new();
        let mut best: Option<(f64, Effect, Vec<Nonlinear>, Residuals, f64)> = None;
        for e in Effect::ALL {
            if !s.can_add(e, &nl_all, ch.kind) {
                continue;
            }
            let s2 = s.with(e);
            let nls2: Vec<Nonlinear> = (0..nf).map(|k| search(&setup, &s2, &nls[k], e, &trains[k])).collect();
            let r = heldout(&setup, &s2, &nls2, &masks);
            let gain = cur_score - setup.score(&r, &all);
            let n_aff = n_bins * f64::from(u8::from(cyc && e.touches_sf()) + u8::from(e.touches_bias()));
            let penalty = e.n_params() as f64 * n_bins.ln();
            // Practical significance too: the affected channel's held-out RMS must drop by
            // ≥ 2 % (low-frequency noise such as bias instability is not in the floor).
            let drop = |a: &[f64], b: &[f64]| 1.0 - rms(b) / rms(a).max(1e-300);
            let rel = f64::max(
                if cyc && e.touches_sf() { drop(&cur.sf, &r.sf) } else { 0.0 },
                if e.touches_bias() { drop(&cur.bias, &r.bias) } else { 0.0 },
            );
            let significant = gain > penalty && gain > 0.05 * n_aff && rel >= 0.02;
            trials.push(CandidateTrial {
                name: e.name().into(),
                channel: if e == Effect::TempQuadBias && !cyc { "bias".into() } else { e.channel().into() },
                gain,
                penalty,
                significant,
                gaps: gaps(ch.kind, &r),
            });
            if significant && best.as_ref().is_none_or(|b| gain - penalty > b.0) {
                best = Some((gain - penalty, e, nls2, r, gain));
            }
        }
        rounds.push(trials);
        let Some((_, e, nls2, r, _)) = best else { break };
        // Gap of the channel the effect acts on (for `both`: the one it improved more).
        let (sf_gain, b_gain) = (
            (rms(&cur.sf) / setup.sigma_sf).powi(2) - (rms(&r.sf) / setup.sigma_sf).powi(2),
            (rms(&cur.bias) / setup.sigma_b).powi(2) - (rms(&r.bias) / setup.sigma_b).powi(2),
        );
        let use_sf = cyc && (e.channel() == "scale_factor" || (e.channel() == "both" && sf_gain >= b_gain));
        let (gb, ga) = if use_sf { (rms(&cur.sf), rms(&r.sf)) } else { (rms(&cur.bias), rms(&r.bias)) };
        s = s.with(e);
        nls = nls2;
        nl_all = search(&setup, &s, &nl_all, e, &all);
        effects.push((e, gb, ga));
        cur = r;
    }
    let final_fit: Fitted = setup.fit(&s, &nl_all, &all);
    let effects = effects
        .into_iter()
        .map(|(e, gb, ga)| EffectReport {
            name: e.name().into(),
            channel: e.channel().into(),
            params: effect_params(e, &final_fit.model),
            heldout_gap_before: gb,
            heldout_gap_after: ga,
        })
        .collect();
    let floor = match ch.kind {
        LogKind::Cycling => {
            Gaps::Cycling { scale_factor_ppm: noise_floor(ch, &cur.sf), bias_ug: noise_floor(ch, &cur.bias) }
        }
        LogKind::Single => Gaps::Single { value_rms: noise_floor(ch, &cur.bias) },
    };
    Report {
        start,
        effects,
        heldout_gap_before: gaps(ch.kind, &before),
        heldout_gap_after: gaps(ch.kind, &cur),
        where_: localize(ch, &before, 5),
        noise_floor: floor,
        rounds,
        where_after: localize(ch, &cur, 5),
        model: Some(final_fit.model),
        residuals: (before, cur),
        heldout_rule: rule,
    }
}

/// CLI entry: `qfa-lab discover --log LOG.csv --start simple|paper --out DIR`.
///
/// # Errors
/// Reading the log or writing the outputs failed.
pub fn run_cli(log: &Path, start: Start, out_dir: &Path) -> Result<Report> {
    let ch = Channels::read(log, 60.0)?;
    let r = discover(&ch, start, out_dir)?;
    println!("{}", serde_json::to_string_pretty(&r)?);
    Ok(r)
}

/// Demo hook (issue 3's demo runs one discovery): start `simple` on a unit's cycling log.
/// With the simulator's Eq. 11 truth this should rediscover the paper's structure
/// (`temp_quadratic` and the rate terms). Returns a one-line summary.
#[must_use]
pub fn demo_hook(log: &Path, out: &Path) -> Option<String> {
    let run = || -> Result<Report> {
        let ch = Channels::read(log, 60.0)?;
        discover(&ch, Start::Simple, out)
    };
    match run() {
        Ok(r) => {
            let names: Vec<&str> = r.effects.iter().map(|e| e.name.as_str()).collect();
            let gap = |g: &Gaps| match g {
                Gaps::Cycling { scale_factor_ppm, bias_ug } => format!("{scale_factor_ppm:.1} ppm / {bias_ug:.1} µg"),
                Gaps::Single { value_rms } => format!("{value_rms:.3}"),
            };
            Some(format!(
                "start simple → added [{}]; held-out gap (scale factor / bias) {} → {}; {}",
                if names.is_empty() { "none".to_string() } else { names.join(", ") },
                gap(&r.heldout_gap_before),
                gap(&r.heldout_gap_after),
                out.join("report.md").display()
            ))
        }
        Err(e) => Some(format!("failed: {e:#}")),
    }
}
