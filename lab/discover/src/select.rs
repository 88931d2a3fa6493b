//! The selection workflow without writing anything ([`analyze`]): rounds of candidates
//! under the block test, the one-standard-error rule, the backward step, the joint re-fit,
//! the intervals, and the model that is flashed; and the start model on every bin
//! ([`start_model`]).

use super::*;

/// Family-wise level of one selection round: the candidates of a round share it
/// (Bonferroni), so the chance that a log with nothing missing gets any addition in the
/// first round is at most this, if the block test holds its level.
pub(crate) const ALPHA: f64 = 0.05;

/// Per-bin held-out gain of `r` over `cur`, each channel in units of its held-out
/// variance before the candidate.
fn per_bin_gain(cur: &Residuals, r: &Residuals) -> Vec<f64> {
    let (v_sf, v_b) = (rms(&cur.sf).powi(2).max(1e-300), rms(&cur.bias).powi(2).max(1e-300));
    (0..cur.bias.len())
        .map(|i| {
            let mut d = 0.0;
            if cur.sf[i].is_finite() && r.sf[i].is_finite() {
                d += (cur.sf[i].powi(2) - r.sf[i].powi(2)) / v_sf;
            }
            if cur.bias[i].is_finite() && r.bias[i].is_finite() {
                d += (cur.bias[i].powi(2) - r.bias[i].powi(2)) / v_b;
            }
            d
        })
        .collect()
}

/// `r` gains over `cur` held out: the whitened test ([`whitened_gain`], level `alpha`)
/// and its confirmation on the residuals themselves ([`raw_gain`]) both pass. Returns
/// the two tests and the verdict.
fn gains(ch: &Channels, cur: &Residuals, r: &Residuals, alpha: f64) -> (stats::GainStat, stats::GainStat, bool) {
    let (g, raw) = (whitened_gain(ch, cur, r, alpha), raw_gain(ch, cur, r));
    let passes = g.passes() && raw.passes();
    (g, raw, passes)
}

/// The block test of `r`'s held-out gain over `cur` (level `alpha`), on both residuals
/// whitened by the noise model fitted to `r`, channel by channel (the larger model's
/// residual estimates the noise, as in an F-test: `cur` still holds the structure under
/// test). Blocks from the whitened `r`'s autocorrelation, as before whitening.
fn whitened_gain(ch: &Channels, cur: &Residuals, r: &Residuals, alpha: f64) -> stats::GainStat {
    let (mf, mb) = (noise::fit(ch, &r.sf), noise::fit(ch, &r.bias));
    let wr = Residuals { sf: mf.whiten(ch, &r.sf), bias: mb.whiten(ch, &r.bias) };
    let wc = Residuals { sf: mf.whiten(ch, &cur.sf), bias: mb.whiten(ch, &cur.bias) };
    let blocks = stats::blocks(ch, stats::block_len(ch, &[&wr.sf, &wr.bias]));
    stats::gain_stat(&blocks, &per_bin_gain(&wc, &wr), alpha)
}

/// The block test of `r`'s held-out gain over `cur` on the residuals themselves, at the
/// uncorrected level [`ALPHA`] (blocks from `r`'s autocorrelation). Why a second test:
/// the whitened test weighs the fast part of a residual most, and on the lab simulator's
/// clean logs it found a 30-s lag at t 6 to 10 that took the scale-factor gap from
/// 10.14 to 10.02 ppm and the bias gap from 7.01 to 7.04 µg: real (the rate estimator's
/// delay at ramp corners), but not a change a user would see.
fn raw_gain(ch: &Channels, cur: &Residuals, r: &Residuals) -> stats::GainStat {
    let blocks = stats::blocks(ch, stats::block_len(ch, &[&r.sf, &r.bias]));
    stats::gain_stat(&blocks, &per_bin_gain(cur, r), ALPHA)
}

/// The selection rule, in words (report.json and report.md).
fn selection_rule_text() -> String {
    format!(
        "paired block test of the held-out gain: both held-out residuals whitened by the noise model \
         fitted to the one with the candidate (white + Gauss–Markov, its ARMA(1, 1) innovations clipped at \
         4 SD); per bin, the drop of (residual/RMS)² summed over the channels; bins grouped into blocks of four \
         times the whitened residual's 1/e autocorrelation lag (≥ 10 bins, ≥ 8 blocks); significant when gain > \
         t(1 − {ALPHA}/m, blocks − 1) × SE of the block sums (m = {} catalog effects, every round), when the \
         same gain on the unwhitened residuals passes the same test at level {ALPHA}, and, for an effect with a weight of its own (drift rate, \
         play weight, Eq. 11 term; not a lag or a creep), when |weight| > z(1 − {ALPHA}/(2m)) × its \
         moving-block bootstrap SE (held-out residuals resampled, the effect's nonlinear parameters \
         searched again on each of 30 resamples); a candidate with a parameter at a search limit is not added; \
         the best is the largest gain; by the one-standard-error rule the candidate with fewest \
         parameters whose gain is within one SE of the best's is added (the others are listed as \
         confusable); at the end each added effect must still be significant given the others \
         (backward step), else it is removed",
        Effect::ALL.len()
    )
}

/// The start model fitted on every bin of `ch` (no held-out split): the "before" of a
/// discovery whose figures are scored on data outside `ch`.
#[must_use]
pub(crate) fn start_model(ch: &Channels, start: Start) -> AxisModel {
    let setup = Setup::new(ch);
    setup.fit(&Structure::start(start), &Nonlinear::default(), &vec![true; ch.n_bins()]).model
}

/// Renew the timing offset's basis for structure `s` (the derivative of its all-bin fit's
/// prediction), fit δ on every bin, hold it there, and return the held-out residual with it
/// held. A round's candidates are scored with δ held: let free, δ would follow the bias
/// channel as soon as a rate term took over its part on the scale factor, and the rate
/// term would then be credited with a bias-only Ṫ term the catalog leaves out (an ε of 6.3
/// and an η of −0.05 "found" on a clean log of the first independent generator, δ moving
/// from +0.5 to +12.8 s). Held, a rate term must gain on what the offset cannot explain.
///
/// Once `s` holds ε·Ṫ on the scale factor (the `paper` start, or `rate_hysteresis`
/// named), no offset is fitted: ε and δ are then one signal on the scale factor, and the
/// bias channel alone cannot tell them apart (its δ term is small and its slow noise
/// large: a 10-µg Gauss–Markov bias drove δ to its limit on the lab simulator's logs, and
/// a rate term was then "found" to undo it). ε then carries any offset.
fn renew_offset(
    setup: &mut Setup<'_>,
    s: &Structure,
    nl_all: &Nonlinear,
    nls: &[Nonlinear],
    masks: &[Vec<bool>],
    trains: &[Vec<bool>],
) -> Residuals {
    let all = vec![true; setup.ch.n_bins()];
    setup.offset_fixed = None;
    setup.offset_basis = None;
    if setup.ch.kind == LogKind::Cycling && !s.sf_eps {
        setup.offset_basis = Some(setup.offset_basis_of(&setup.fit(s, nl_all, &all).model));
        setup.offset_fixed = setup.fit(s, nl_all, &all).offset.map(|o| o.seconds);
    }
    heldout(setup, s, nls, masks, trains)
}

/// An effect the selection added: the effect, the held-out RMS of the channel it acts on
/// before and after it, its gain, and the candidates confusable with it.
type Added = (Effect, f64, f64, GainStat, Vec<String>);

/// A significant candidate of a round: its gain less critical × SE, the effect, its
/// per-fold nonlinear parameters, its held-out residual and its gain.
type Significant = (f64, Effect, Vec<Nonlinear>, Residuals, GainStat);

/// A candidate significant but pinned at a search limit, with the limits it sits at.
type Pinned = (Effect, Vec<String>);

/// The model the selection holds between its steps.
struct Selection {
    /// Structure.
    s: Structure,
    /// Nonlinear parameters per fold (searched on its training bins).
    nls: Vec<Nonlinear>,
    /// Nonlinear parameters searched on every bin.
    nl_all: Nonlinear,
    /// Held-out residual.
    cur: Residuals,
}

/// The workflow without writing anything.
#[must_use]
pub fn analyze(ch: &Channels, start: Start) -> Report {
    let mut setup = Setup::new(ch);
    let (masks, trains, rule) = folds(ch);
    let all = vec![true; ch.n_bins()];
    let mut m = start_selection(&mut setup, start, &masks, &trains);
    let before = m.cur.clone();
    let (mut effects, rounds, pinned) = forward_rounds(&mut setup, &mut m, &masks, &trains);
    backward_step(&setup, &mut m, &mut effects, &masks, &trains);
    joint_refit(&mut setup, &mut m, &effects);
    let final_fit: Fitted = setup.fit(&m.s, &m.nl_all, &all);
    let (timing_offset, effects) = intervals(&mut setup, &m, &final_fit, effects);
    let cur = m.cur;
    let floor = match ch.kind {
        LogKind::Cycling => {
            Gaps::Cycling { scale_factor_ppm: noise_floor(ch, &cur.sf), bias_ug: noise_floor(ch, &cur.bias) }
        }
        LogKind::Single => Gaps::Single { value_rms: noise_floor(ch, &cur.bias) },
    };
    let peers = peer_gaps(ch, &masks, &trains);
    let named_ext = final_fit.model.ext;
    let (named_flashed, flashed) = choose_flashed(ch, &before, &cur, &peers);
    let flashed_model = if named_flashed {
        final_fit.model
    } else {
        setup.fit(&Structure::start(start), &Nonlinear::default(), &all).model
    };
    let residual_vs_floor = unexplained::floor_ratios(ch, &cur);
    let noise = unexplained::noise_tests(ch, &cur);
    let unexplained = unexplained::find_unexplained(ch, &cur, &masks, &trains, &pinned, &residual_vs_floor, &noise);
    let timing_offset = timing_offset.map(|o| TimingOffsetReport {
        shares_a_branch_level: unexplained.iter().any(|u| u.branch_level.is_some()),
        ..o
    });
    Report {
        start,
        effects,
        heldout_gap_before: gaps(ch.kind, &before),
        heldout_gap_after: gaps(ch.kind, &cur),
        where_: localize(ch, &before, 5),
        unexplained,
        residual_vs_floor,
        noise,
        timing_offset,
        noise_floor: floor,
        peers,
        selection_rule: selection_rule_text(),
        rounds,
        where_after: localize(ch, &cur, 5),
        model: Some(flashed_model),
        flashed,
        table: None,
        named_ext,
        residuals: (before, cur),
        heldout_rule: rule,
    }
}

/// The start model with its held-out residual; on a cycling log the search weights are set
/// to its noise floors and the timing offset is renewed ([`renew_offset`]).
fn start_selection(setup: &mut Setup<'_>, start: Start, masks: &[Vec<bool>], trains: &[Vec<bool>]) -> Selection {
    let ch = setup.ch;
    let s = Structure::start(start);
    let nls = vec![Nonlinear::default(); masks.len()];
    let nl_all = Nonlinear::default();
    let mut cur = heldout(setup, &s, &nls, masks, trains);
    if ch.kind == LogKind::Cycling {
        // The timing offset is a nuisance of every fit (see `Setup::offset_basis`), weighted
        // by the start model's noise floors.
        setup.sigma_sf = noise_floor(ch, &cur.sf);
        setup.sigma_b = noise_floor(ch, &cur.bias);
        cur = renew_offset(setup, &s, &nl_all, &nls, masks, trains);
    }
    Selection { s, nls, nl_all, cur }
}

/// The forward rounds: each scores every candidate left ([`try_candidates`]) and adds the
/// one the one-standard-error rule picks among the significant ones ([`one_se_pick`]),
/// until a round has none. Returns the effects added, every round's trials, and the last
/// round's candidates pinned at a search limit.
fn forward_rounds(
    setup: &mut Setup<'_>,
    m: &mut Selection,
    masks: &[Vec<bool>],
    trains: &[Vec<bool>],
) -> (Vec<Added>, Vec<Vec<CandidateTrial>>, Vec<Pinned>) {
    let ch = setup.ch;
    let cyc = ch.kind == LogKind::Cycling;
    let all = vec![true; ch.n_bins()];
    let mut effects: Vec<Added> = Vec::new();
    let mut rounds = Vec::new();
    loop {
        // Weights of the parameter search: each channel's bin-to-bin noise floor (close to
        // inverse-variance weights). Weighting by the held-out RMS instead lets the channel
        // with the larger gap starve the other: a lag's τ then comes out ~0.6 % off from
        // the bias channel alone, and a small ε·Ṫ is "discovered" to mop up the rest.
        setup.sigma_sf = if cyc { noise_floor(ch, &m.cur.sf) } else { 1.0 };
        setup.sigma_b = noise_floor(ch, &m.cur.bias);
        let (trials, mut sig, pinned) = try_candidates(setup, m, masks, trains);
        rounds.push(trials);
        // Best by gain; then the one-standard-error rule: every significant candidate whose
        // gain is within one SE of the best's is confusable with it, and the one with
        // fewest parameters among them is added. (A paired version, 2 SE of the per-block
        // difference, was tried: the residuals of a lag, a creep and a play on one channel
        // are so alike that 2 % gain differences came out "significant", and the choice
        // then depended on which pair was compared.)
        sig.sort_by(|a, b| b.4.gain.total_cmp(&a.4.gain));
        if sig.is_empty() {
            return (effects, rounds, pinned);
        }
        let (pick, conf_names) = one_se_pick(&sig, cyc);
        let (_, e, nls2, r, g) = sig.swap_remove(pick);
        let (gb, ga) = channel_gaps(e, &m.cur, &r, cyc);
        m.s = m.s.with(e);
        m.nls = nls2;
        m.nl_all = search(setup, &m.s, &m.nl_all, e, &all);
        effects.push((e, gb, ga, g, conf_names));
        m.cur = r;
        if cyc {
            m.cur = renew_offset(setup, &m.s, &m.nl_all, &m.nls, masks, trains);
        }
    }
}

/// One round's candidates: every effect `m` can still take, its nonlinear parameters
/// searched per fold and its held-out residual scored by the block test against `m`'s
/// (level [`ALPHA`] over the catalog) and, for an effect with a weight, the weight test.
/// Returns every trial, the significant candidates, and those pinned at a search limit
/// (significant, but not added).
fn try_candidates(
    setup: &Setup<'_>,
    m: &Selection,
    masks: &[Vec<bool>],
    trains: &[Vec<bool>],
) -> (Vec<CandidateTrial>, Vec<Significant>, Vec<Pinned>) {
    let ch = setup.ch;
    let cyc = ch.kind == LogKind::Cycling;
    let nf = masks.len();
    let cands: Vec<Effect> = Effect::ALL.into_iter().filter(|&e| m.s.can_add(e, &m.nl_all, ch.kind)).collect();
    // Bonferroni over the whole catalog, the same in every round: the family is every
    // effect the workflow could ever add. (Per round, over the candidates left, made
    // later rounds laxer and let a lag log pick up a 0.06 µg/h drift at t = 2.31.)
    let alpha = ALPHA / Effect::ALL.len() as f64;
    let mut trials = Vec::new();
    let mut sig: Vec<Significant> = Vec::new();
    let mut pinned = Vec::new();
    for e in cands {
        let s2 = m.s.with(e);
        let nls2: Vec<Nonlinear> = (0..nf).map(|k| search(setup, &s2, &m.nls[k], e, &trains[k])).collect();
        let r = heldout(setup, &s2, &nls2, masks, trains);
        let (g, raw, passes) = gains(ch, &m.cur, &r, alpha);
        let wz = if passes { weight_z(setup, &s2, &nls2[0], e, &r) } else { None };
        let z_crit = stats::normal_quantile(1.0 - alpha / 2.0);
        let significant = passes && wz.as_ref().is_none_or(|w| w.z > z_crit);
        let mut bound: Vec<String> = nls2.iter().flat_map(|n| at_bound(e, n)).collect();
        bound.dedup();
        trials.push(CandidateTrial {
            name: e.name().into(),
            channel: if cyc { e.channel().into() } else { "value".into() },
            gain: g.clone(),
            raw_gain: raw,
            weight: wz,
            significant,
            at_bound: bound.clone(),
            gaps: gaps(ch.kind, &r),
        });
        if significant && !bound.is_empty() {
            pinned.push((e, bound));
            continue;
        }
        if significant {
            sig.push((g.gain - g.critical * g.se, e, nls2, r, g));
        }
    }
    (trials, sig, pinned)
}

/// The lab's one-standard-error rule ([`qfa_calibrate::select::one_se_rule`]) on the
/// significant candidates `sig` (best gain first) that act on a channel the best also acts
/// on, each gain taken as a loss: the one with the fewest parameters whose gain is within
/// one SE of the best's (on a tie, the larger gain). Returns its index and the names of the
/// others within that SE, confusable with it.
fn one_se_pick(sig: &[Significant], cyc: bool) -> (usize, Vec<String>) {
    // Effects on disjoint channels explain different data: never confusable
    // (`temp_quadratic` on the scale factor and on the bias both get added).
    let a = sig[0].1;
    let rivals: Vec<usize> = (0..sig.len())
        .filter(|&j| {
            let b = sig[j].1;
            j == 0 || (cyc && a.touches_sf() && b.touches_sf()) || (a.touches_bias() && b.touches_bias())
        })
        .collect();
    let cands: Vec<qfa_calibrate::select::Candidate> = rivals
        .iter()
        .map(|&j| qfa_calibrate::select::Candidate {
            unknowns: sig[j].1.n_params(),
            loss: -sig[j].4.gain,
            se: sig[j].4.se,
        })
        .collect();
    let (pick, within) = qfa_calibrate::select::one_se_rule(&cands).map_or((0, vec![0]), |(p, w)| (rivals[p], w));
    let within: Vec<usize> = within.iter().map(|&k| rivals[k]).collect();
    let conf_names: Vec<String> =
        within.into_iter().filter(|&j| j != pick).map(|j| sig[j].1.name().to_string()).collect();
    (pick, conf_names)
}

/// The held-out RMS, before (`cur`) and after (`r`) effect `e` is added, of the channel it
/// acts on (for `both`: the one it improved more).
fn channel_gaps(e: Effect, cur: &Residuals, r: &Residuals, cyc: bool) -> (f64, f64) {
    let rel = |a: &[f64], b: &[f64]| 1.0 - (rms(b) / rms(a).max(1e-300)).powi(2);
    let use_sf = cyc
        && (e.channel() == "scale_factor" || (e.channel() == "both" && rel(&cur.sf, &r.sf) >= rel(&cur.bias, &r.bias)));
    if use_sf {
        (rms(&cur.sf), rms(&r.sf))
    } else {
        (rms(&cur.bias), rms(&r.bias))
    }
}

/// Backward step: drop an added effect the others make redundant (its removal costs no
/// significant held-out gain). Later additions first; nonlinear parameters of the rest
/// stay as fitted.
fn backward_step(
    setup: &Setup<'_>,
    m: &mut Selection,
    effects: &mut Vec<Added>,
    masks: &[Vec<bool>],
    trains: &[Vec<bool>],
) {
    let ch = setup.ch;
    let mut k = effects.len();
    while k > 0 && effects.len() > 1 {
        k -= 1;
        let e = effects[k].0;
        let s_minus = m.s.without(e);
        let nls_minus: Vec<Nonlinear> = m.nls.iter().map(|n| n.without(e)).collect();
        let r_minus = heldout(setup, &s_minus, &nls_minus, masks, trains);
        if !gains(ch, &r_minus, &m.cur, ALPHA / Effect::ALL.len() as f64).2 {
            effects.remove(k);
            m.s = s_minus;
            m.nls = nls_minus;
            m.nl_all = m.nl_all.without(e);
            m.cur = r_minus;
        }
    }
}

/// Re-optimise the nonlinear parameters jointly (two cycles of coordinate search on every
/// bin) when more than one nonlinear effect was added, or one beside a timing offset.
fn joint_refit(setup: &mut Setup<'_>, m: &mut Selection, effects: &[Added]) {
    let all = vec![true; setup.ch.n_bins()];
    let nonlin: Vec<Effect> = effects
        .iter()
        .map(|x| x.0)
        .filter(|e| matches!(e, Effect::SensorLag | Effect::BiasBranchHysteresis | Effect::BiasCreep))
        .collect();
    // With the timing offset let free again, so a lag's τ and δ (both delays) settle
    // together rather than in the order they were found (τ came out 469 s for a true 480
    // with δ still held at the start model's value).
    setup.offset_fixed = None;
    if nonlin.len() > 1 || (setup.offset_basis.is_some() && !nonlin.is_empty()) {
        for _ in 0..2 {
            for &e in &nonlin {
                m.nl_all = search(setup, &m.s, &m.nl_all, e, &all);
            }
        }
    }
}

/// The intervals of the final fit: with the search weights set to its residual RMS, the
/// timing offset's 95 % interval (its white SE widened by √κ, κ = N/N_eff of the
/// residual) and each added effect's report with its parameters' intervals
/// ([`effect_report`]).
fn intervals(
    setup: &mut Setup<'_>,
    m: &Selection,
    final_fit: &Fitted,
    effects: Vec<Added>,
) -> (Option<TimingOffsetReport>, Vec<EffectReport>) {
    let ch = setup.ch;
    let cyc = ch.kind == LogKind::Cycling;
    // Parameter intervals: profile for nonlinear, block bootstrap for linear coefficients.
    let res_all = setup.residuals(&final_fit.pred);
    setup.sigma_sf = if cyc { rms(&res_all.sf).max(1e-12) } else { 1.0 };
    setup.sigma_b = rms(&res_all.bias).max(1e-12);
    let setup: &Setup<'_> = setup;
    let kappa = stats::inflation(ch, &res_all.sf).max(stats::inflation(ch, &res_all.bias));
    let timing_offset = final_fit.offset.map(|o| {
        let half = 1.96 * o.se_white_s * kappa.sqrt();
        TimingOffsetReport {
            seconds: o.seconds,
            ci95: [o.seconds - half, o.seconds + half],
            limit_s: setup.offset_limit_s,
            at_limit: o.at_limit,
            shares_a_branch_level: false,
        }
    });
    let len_all = stats::block_len(ch, &[&res_all.sf, &res_all.bias]);
    let eff_list: Vec<Effect> = effects.iter().map(|x| x.0).collect();
    let lin_sd = if eff_list.is_empty() {
        Vec::new()
    } else {
        bootstrap_linear(setup, &m.s, &m.nl_all, final_fit, &eff_list, len_all)
    };
    let effects = effects
        .into_iter()
        .enumerate()
        .map(|(k, added)| effect_report(setup, m, final_fit, added, kappa, lin_sd.get(k), len_all))
        .collect();
    (timing_offset, effects)
}

/// The report of one added effect: its parameters from the final fit, each with a 95 %
/// interval: a profile for a nonlinear one ([`profile_cis`]), else from the moving-block
/// bootstrap SDs `lin_sd` over `len_all`-bin blocks ([`linear_cis`]).
fn effect_report(
    setup: &Setup<'_>,
    m: &Selection,
    final_fit: &Fitted,
    added: Added,
    kappa: f64,
    lin_sd: Option<&std::collections::BTreeMap<String, f64>>,
    len_all: usize,
) -> EffectReport {
    let (e, gb, ga, g, confusable_with) = added;
    let params = effect_params(e, final_fit, setup.ch.bias_unit);
    let (mut params_ci, ends) = profile_cis(setup, m, e, kappa);
    linear_cis(&params, &mut params_ci, lin_sd, &ends, len_all);
    EffectReport {
        name: e.name().into(),
        channel: if setup.ch.kind == LogKind::Cycling { e.channel().into() } else { "value".into() },
        params,
        params_ci,
        gain: g,
        in_table: e.in_firmware(),
        not_in_table: (!e.in_firmware()).then(|| "no root-crate slot yet".to_string()),
        confusable_with,
        heldout_gap_before: gb,
        heldout_gap_after: ga,
    }
}

/// The 95 % profile interval of each nonlinear parameter of effect `e` (threshold 3.84·κ,
/// the effect's other nonlinear parameter re-optimised), and the effect's parameters at
/// every profile end.
fn profile_cis(
    setup: &Setup<'_>,
    m: &Selection,
    e: Effect,
    kappa: f64,
) -> (std::collections::BTreeMap<String, ParamCi>, Vec<std::collections::BTreeMap<String, f64>>) {
    let mut params_ci = std::collections::BTreeMap::new();
    let bound = at_bound(e, &m.nl_all);
    let cs = coords(e, &m.nl_all);
    let mut ends: Vec<std::collections::BTreeMap<String, f64>> = Vec::new();
    for (i, c) in cs.iter().enumerate() {
        let other = cs.iter().enumerate().find(|(j, _)| *j != i).map(|(_, o)| o);
        let (ci, at_ends) = profile(setup, &m.s, &m.nl_all, c, other, e, 3.84 * kappa);
        ends.extend(at_ends);
        let v = (c.5)(c.1);
        params_ci.insert(
            c.0.to_string(),
            ParamCi {
                value: v,
                ci95: ci,
                at_bound: bound.iter().any(|b| b.starts_with(c.0)),
                method: format!(
                    "profile, threshold 3.84·N/N_eff (N/N_eff = {kappa:.1}){}",
                    if other.is_some() { ", the other nonlinear parameter re-optimised" } else { "" }
                ),
            },
        );
    }
    (params_ci, ends)
}

/// The 95 % interval of each parameter in `params` that has none yet: a fixed reference is
/// its own; a linear coefficient is ±1.96 SD of its moving-block bootstrap (`sd`, NaN
/// without one; 40 resamples of `len_all`-bin blocks), widened to its values at the
/// nonlinear parameters' profile `ends`.
fn linear_cis(
    params: &std::collections::BTreeMap<String, f64>,
    params_ci: &mut std::collections::BTreeMap<String, ParamCi>,
    sd: Option<&std::collections::BTreeMap<String, f64>>,
    ends: &[std::collections::BTreeMap<String, f64>],
    len_all: usize,
) {
    for (key, &v) in params {
        if params_ci.contains_key(key) {
            continue;
        }
        let (ci, method) = if key == "t_ref_c" {
            ([v, v], "fixed reference, not fitted".to_string())
        } else {
            let sd = sd.and_then(|m| m.get(key)).copied().unwrap_or(f64::NAN);
            let mut ci = [v - 1.96 * sd, v + 1.96 * sd];
            for m in ends {
                if let Some(&x) = m.get(key) {
                    ci = [ci[0].min(x), ci[1].max(x)];
                }
            }
            let widened =
                if ends.is_empty() { "" } else { ", widened to its values at the nonlinear parameters' profile ends" };
            (ci, format!("moving-block bootstrap (40 × {len_all}-bin blocks) with nonlinear parameters fixed{widened}"))
        };
        params_ci.insert(key.clone(), ParamCi { value: v, ci95: ci, at_bound: false, method });
    }
}

/// What is flashed: the named model (residual `cur`), unless the start model (`before`)
/// predicts better held out (Σ over channels of (held-out RMS / noise floor)², on the
/// residuals the selection used); and the peer that predicts the bias better, if any.
/// Returns whether the named model is flashed, and the report's entry.
fn choose_flashed(ch: &Channels, before: &Residuals, cur: &Residuals, peers: &[PeerGap]) -> (bool, Flashed) {
    // The block test only adds an effect that gains, but the backward step and the joint
    // re-fit can still leave a model that does worse; then the start is flashed.
    let floors = [noise_floor(ch, &cur.sf), noise_floor(ch, &cur.bias)];
    let named_flashed = flash_score(ch.kind, cur, floors) <= flash_score(ch.kind, before, floors);
    let flashed_gaps = gaps(ch.kind, if named_flashed { cur } else { before });
    let flashed_bias = match flashed_gaps {
        Gaps::Cycling { bias_ug, .. } => bias_ug,
        Gaps::Single { value_rms } => value_rms,
    };
    let flashed = Flashed {
        model: if named_flashed { "named model" } else { "start model" }.into(),
        heldout: Some(flashed_gaps),
        not_computed: None,
        peer_better: peer_better(peers, flashed_bias),
    };
    (named_flashed, flashed)
}
