//! The selection workflow without writing anything ([`analyze`]): rounds of candidates
//! under the block test, the one-standard-error rule, the backward step, the joint re-fit,
//! the intervals, and the model that is flashed; and the start model on every bin
//! ([`start_model`]).

use super::*;

/// Family-wise level of one selection round: the candidates of a round share it
/// (Bonferroni), so the chance that a log with nothing missing gets any addition in the
/// first round is at most this, if the block test holds its level.
pub const ALPHA: f64 = 0.05;

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

/// The selection rule, in words (report.json and report.md).
fn selection_rule_text() -> String {
    format!(
        "paired block test of the held-out gain: per bin, the drop of (residual/RMS)² summed over the \
         channels; bins grouped into blocks of four times the residual's 1/e autocorrelation lag (≥ 10 bins, \
         ≥ 8 blocks); significant when gain > t(1 − {ALPHA}/m, blocks − 1) × SE of the block sums \
         (m = {} catalog effects, every round) and, for an effect with a weight of its own (drift rate, \
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
pub fn start_model(ch: &Channels, start: Start) -> AxisModel {
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

/// The workflow without writing anything.
#[must_use]
pub fn analyze(ch: &Channels, start: Start) -> Report {
    let mut setup = Setup::new(ch);
    let (masks, trains, rule) = folds(ch);
    let nf = masks.len();
    let all = vec![true; ch.n_bins()];
    let cyc = ch.kind == LogKind::Cycling;

    let mut s = Structure::start(start);
    let mut nls = vec![Nonlinear::default(); nf];
    let mut nl_all = Nonlinear::default();
    let mut cur = heldout(&setup, &s, &nls, &masks, &trains);
    if cyc {
        // The timing offset is a nuisance of every fit (see `Setup::offset_basis`), weighted
        // by the start model's noise floors.
        setup.sigma_sf = noise_floor(ch, &cur.sf);
        setup.sigma_b = noise_floor(ch, &cur.bias);
        cur = renew_offset(&mut setup, &s, &nl_all, &nls, &masks, &trains);
    }
    let before = cur.clone();
    let mut effects: Vec<(Effect, f64, f64, GainStat, Vec<String>)> = Vec::new();
    let mut rounds = Vec::new();
    let mut pinned: Vec<(Effect, Vec<String>)>;
    loop {
        // Weights of the parameter search: each channel's bin-to-bin noise floor (close to
        // inverse-variance weights). Weighting by the held-out RMS instead lets the channel
        // with the larger gap starve the other: a lag's τ then comes out ~0.6 % off from
        // the bias channel alone, and a small ε·Ṫ is "discovered" to mop up the rest.
        setup.sigma_sf = if cyc { noise_floor(ch, &cur.sf) } else { 1.0 };
        setup.sigma_b = noise_floor(ch, &cur.bias);
        let cands: Vec<Effect> = Effect::ALL.into_iter().filter(|&e| s.can_add(e, &nl_all, ch.kind)).collect();
        // Bonferroni over the whole catalog, the same in every round: the family is every
        // effect the workflow could ever add. (Per round, over the candidates left, made
        // later rounds laxer and let a lag log pick up a 0.06 µg/h drift at t = 2.31.)
        let alpha = ALPHA / Effect::ALL.len() as f64;
        let mut trials = Vec::new();
        let mut sig: Vec<(f64, Effect, Vec<Nonlinear>, Residuals, GainStat)> = Vec::new();
        pinned = Vec::new();
        for e in cands {
            let s2 = s.with(e);
            let nls2: Vec<Nonlinear> = (0..nf).map(|k| search(&setup, &s2, &nls[k], e, &trains[k])).collect();
            let r = heldout(&setup, &s2, &nls2, &masks, &trains);
            // Blocks from the residual with the candidate in (the larger model's residual
            // estimates the noise, as in an F-test): the current residual still holds the
            // structure under test, whose long correlation would leave too few blocks.
            let blocks = stats::blocks(ch, stats::block_len(ch, &[&r.sf, &r.bias]));
            let g = stats::gain_stat(&blocks, &per_bin_gain(&cur, &r), alpha);
            let wz = if g.gain > 0.0 && g.t > g.critical { weight_z(&setup, &s2, &nls2[0], e, &r) } else { None };
            let z_crit = stats::normal_quantile(1.0 - alpha / 2.0);
            let significant = g.gain > 0.0 && g.t > g.critical && wz.as_ref().is_none_or(|w| w.z > z_crit);
            let mut bound: Vec<String> = nls2.iter().flat_map(|n| at_bound(e, n)).collect();
            bound.dedup();
            trials.push(CandidateTrial {
                name: e.name().into(),
                channel: if cyc { e.channel().into() } else { "value".into() },
                gain: g.clone(),
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
        rounds.push(trials);
        // Best by gain; then the one-standard-error rule: every significant candidate whose
        // gain is within one SE of the best's is confusable with it, and the one with
        // fewest parameters among them is added. (A paired version, 2 SE of the per-block
        // difference, was tried: the residuals of a lag, a creep and a play on one channel
        // are so alike that 2 % gain differences came out "significant", and the choice
        // then depended on which pair was compared.)
        sig.sort_by(|a, b| b.4.gain.total_cmp(&a.4.gain));
        if sig.is_empty() {
            break;
        }
        let mut pick = 0;
        let mut confusable = Vec::new();
        for j in 1..sig.len() {
            // Effects on disjoint channels explain different data: never confusable
            // (`temp_quadratic` on the scale factor and on the bias both get added).
            let (a, b) = (sig[0].1, sig[j].1);
            let overlap = (cyc && a.touches_sf() && b.touches_sf()) || (a.touches_bias() && b.touches_bias());
            if overlap && sig[0].4.gain - sig[j].4.gain < sig[0].4.se {
                confusable.push(j);
                let (pj, pp) = (sig[j].1.n_params(), sig[pick].1.n_params());
                if pj < pp || (pj == pp && sig[j].4.gain > sig[pick].4.gain) {
                    pick = j;
                }
            }
        }
        let conf_names: Vec<String> =
            std::iter::once(0).chain(confusable).filter(|&j| j != pick).map(|j| sig[j].1.name().to_string()).collect();
        let (_, e, nls2, r, g) = sig.swap_remove(pick);
        // Gap of the channel the effect acts on (for `both`: the one it improved more).
        let rel = |a: &[f64], b: &[f64]| 1.0 - (rms(b) / rms(a).max(1e-300)).powi(2);
        let use_sf = cyc
            && (e.channel() == "scale_factor"
                || (e.channel() == "both" && rel(&cur.sf, &r.sf) >= rel(&cur.bias, &r.bias)));
        let (gb, ga) = if use_sf { (rms(&cur.sf), rms(&r.sf)) } else { (rms(&cur.bias), rms(&r.bias)) };
        s = s.with(e);
        nls = nls2;
        nl_all = search(&setup, &s, &nl_all, e, &all);
        effects.push((e, gb, ga, g, conf_names));
        cur = r;
        if cyc {
            cur = renew_offset(&mut setup, &s, &nl_all, &nls, &masks, &trains);
        }
    }
    // Backward step: drop an added effect the others make redundant (its removal costs no
    // significant held-out gain). Later additions first; nonlinear parameters of the rest
    // stay as fitted.
    let mut k = effects.len();
    while k > 0 && effects.len() > 1 {
        k -= 1;
        let e = effects[k].0;
        let s_minus = s.without(e);
        let nls_minus: Vec<Nonlinear> = nls.iter().map(|n| n.without(e)).collect();
        let r_minus = heldout(&setup, &s_minus, &nls_minus, &masks, &trains);
        let blocks = stats::blocks(ch, stats::block_len(ch, &[&cur.sf, &cur.bias]));
        let g = stats::gain_stat(&blocks, &per_bin_gain(&r_minus, &cur), ALPHA / Effect::ALL.len() as f64);
        if !(g.gain > 0.0 && g.t > g.critical) {
            effects.remove(k);
            s = s_minus;
            nls = nls_minus;
            nl_all = nl_all.without(e);
            cur = r_minus;
        }
    }
    // Re-optimise the nonlinear parameters jointly (cyclic coordinate search on all data)
    // when more than one nonlinear effect was added.
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
                nl_all = search(&setup, &s, &nl_all, e, &all);
            }
        }
    }
    let final_fit: Fitted = setup.fit(&s, &nl_all, &all);
    // Parameter intervals: profile for nonlinear, block bootstrap for linear coefficients.
    let res_all = setup.residuals(&final_fit.pred);
    setup.sigma_sf = if cyc { rms(&res_all.sf).max(1e-12) } else { 1.0 };
    setup.sigma_b = rms(&res_all.bias).max(1e-12);
    let kappa = stats::inflation(ch, &res_all.sf).max(stats::inflation(ch, &res_all.bias));
    let timing_offset = final_fit.offset.map(|o| {
        let half = 1.96 * o.se_white_s * kappa.sqrt();
        TimingOffsetReport {
            seconds: o.seconds,
            ci95: [o.seconds - half, o.seconds + half],
            limit_s: setup.offset_limit_s,
            at_limit: o.at_limit,
        }
    });
    let len_all = stats::block_len(ch, &[&res_all.sf, &res_all.bias]);
    let eff_list: Vec<Effect> = effects.iter().map(|x| x.0).collect();
    let lin_sd = if eff_list.is_empty() {
        Vec::new()
    } else {
        bootstrap_linear(&setup, &s, &nl_all, &final_fit, &eff_list, len_all)
    };
    let effects = effects
        .into_iter()
        .enumerate()
        .map(|(k, (e, gb, ga, g, confusable_with))| {
            let params = effect_params(e, &final_fit, ch.bias_unit);
            let mut params_ci = std::collections::BTreeMap::new();
            let bound = at_bound(e, &nl_all);
            let cs = coords(e, &nl_all);
            let mut ends: Vec<std::collections::BTreeMap<String, f64>> = Vec::new();
            for (i, c) in cs.iter().enumerate() {
                let other = cs.iter().enumerate().find(|(j, _)| *j != i).map(|(_, o)| o);
                let (ci, at_ends) = profile(&setup, &s, &nl_all, c, other, e, 3.84 * kappa);
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
            for (key, &v) in &params {
                if params_ci.contains_key(key) {
                    continue;
                }
                let (ci, method) = if key == "t_ref_c" {
                    ([v, v], "fixed reference, not fitted".to_string())
                } else {
                    let sd = lin_sd.get(k).and_then(|m| m.get(key)).copied().unwrap_or(f64::NAN);
                    let mut ci = [v - 1.96 * sd, v + 1.96 * sd];
                    for m in &ends {
                        if let Some(&x) = m.get(key) {
                            ci = [ci[0].min(x), ci[1].max(x)];
                        }
                    }
                    let widened = if ends.is_empty() { "" } else { ", widened to its values at the nonlinear parameters' profile ends" };
                    (ci, format!("moving-block bootstrap (40 × {len_all}-bin blocks) with nonlinear parameters fixed{widened}"))
                };
                params_ci.insert(key.clone(), ParamCi { value: v, ci95: ci, at_bound: false, method });
            }
            EffectReport {
                name: e.name().into(),
                channel: if cyc { e.channel().into() } else { "value".into() },
                params,
                params_ci,
                gain: g,
                in_table: e.in_firmware(),
                confusable_with,
                heldout_gap_before: gb,
                heldout_gap_after: ga,
            }
        })
        .collect();
    let floor = match ch.kind {
        LogKind::Cycling => {
            Gaps::Cycling { scale_factor_ppm: noise_floor(ch, &cur.sf), bias_ug: noise_floor(ch, &cur.bias) }
        }
        LogKind::Single => Gaps::Single { value_rms: noise_floor(ch, &cur.bias) },
    };
    // What is flashed: the named model, unless the start model predicts better held out
    // (Σ over channels of (held-out RMS / noise floor)², on the residuals the selection
    // used). The block test only adds an effect that gains, but the backward step and the
    // joint re-fit can still leave a model that does worse; then the start is flashed.
    let floors = [noise_floor(ch, &cur.sf), noise_floor(ch, &cur.bias)];
    let score = |r: &Residuals| {
        let b = (rms(&r.bias) / floors[1]).powi(2);
        if cyc {
            b + (rms(&r.sf) / floors[0]).powi(2)
        } else {
            b
        }
    };
    let peers = peer_gaps(ch, &masks, &trains);
    let named_flashed = score(&cur) <= score(&before);
    let flashed_gaps = gaps(ch.kind, if named_flashed { &cur } else { &before });
    let flashed_bias = match flashed_gaps {
        Gaps::Cycling { bias_ug, .. } => bias_ug,
        Gaps::Single { value_rms } => value_rms,
    };
    let best_peer =
        peers.iter().filter_map(|p| p.heldout_rms.map(|x| (p.peer.clone(), x))).min_by(|a, b| a.1.total_cmp(&b.1));
    let flashed = Flashed {
        model: if named_flashed { "named model" } else { "start model" }.into(),
        heldout: flashed_gaps,
        peer_better: best_peer.filter(|p| p.1 < flashed_bias).map(|(peer, x)| PeerBetter { peer, heldout_rms: x }),
    };
    let flashed_model = if named_flashed {
        final_fit.model
    } else {
        setup.fit(&Structure::start(start), &Nonlinear::default(), &all).model
    };
    let residual_vs_floor = unexplained::floor_ratios(ch, &cur);
    let noise = unexplained::noise_tests(ch, &cur);
    let unexplained = unexplained::find_unexplained(ch, &cur, &masks, &trains, &pinned, &residual_vs_floor, &noise);
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
        residuals: (before, cur),
        heldout_rule: rule,
    }
}
