//! Held-out evaluation: a structure's residuals on the folds, each fold fitted on its
//! training bins with its own nonlinear parameters; their gaps; and the peers on the same
//! folds.

use super::*;

pub(super) fn gaps(kind: LogKind, r: &Residuals) -> Gaps {
    match kind {
        LogKind::Cycling => Gaps::Cycling { scale_factor_ppm: rms(&r.sf), bias_ug: rms(&r.bias) },
        LogKind::Single => Gaps::Single { value_rms: rms(&r.bias) },
    }
}

/// The flash rule's score of a held-out residual: Σ over the log's channels of (held-out
/// RMS / noise floor)², `floors` the scale factor's and the bias's. Lower is better.
pub(crate) fn flash_score(kind: LogKind, r: &Residuals, floors: [f64; 2]) -> f64 {
    let b = (rms(&r.bias) / floors[1]).powi(2);
    if kind == LogKind::Cycling {
        b + (rms(&r.sf) / floors[0]).powi(2)
    } else {
        b
    }
}

/// The peer that predicts the bias better held out than a model whose bias RMS is `bias`,
/// by `calibrate`'s rule: beyond [`qfa_calibrate::verdict::PEER_TOLERANCE`] (two fits of
/// one cubic, the grid's and the formula's, differ by up to 0.2 %).
pub(crate) fn peer_better(peers: &[PeerGap], bias: f64) -> Option<PeerBetter> {
    let best =
        peers.iter().filter_map(|p| p.heldout_rms.map(|x| (p.peer.clone(), x))).min_by(|a, b| a.1.total_cmp(&b.1));
    best.filter(|p| bias > p.1 * (1.0 + qfa_calibrate::verdict::PEER_TOLERANCE))
        .map(|(peer, heldout_rms)| PeerBetter { peer, heldout_rms })
}

/// Copy `r`'s residuals on the bins `test` marks into `out` (a fold's held-out bins).
pub(crate) fn fill_heldout(out: &mut Residuals, test: &[bool], r: &Residuals) {
    for (i, _) in test.iter().enumerate().filter(|(_, &t)| t) {
        out.sf[i] = r.sf[i];
        out.bias[i] = r.bias[i];
    }
}

/// Held-out evaluation of a structure with per-fold nonlinear parameters.
pub(super) fn heldout(
    setup: &Setup,
    s: &Structure,
    nls: &[Nonlinear],
    masks: &[Vec<bool>],
    trains: &[Vec<bool>],
) -> Residuals {
    let n = setup.ch.n_bins();
    let mut out = Residuals { sf: vec![f64::NAN; n], bias: vec![f64::NAN; n] };
    for (k, test) in masks.iter().enumerate() {
        let f = setup.fit(s, &nls[k], &trains[k]);
        fill_heldout(&mut out, test, &setup.residuals(&f.pred));
    }
    out
}

/// The peers of [`qfa_calibrate::peers`] on the held-out folds, bias channel: each
/// fold's peer is fitted on the bin means of its training bins (raw temperature reading,
/// bias) in log order and scored on the fold's held-out bins.
pub(super) fn peer_gaps(ch: &Channels, masks: &[Vec<bool>], trains: &[Vec<bool>]) -> Vec<PeerGap> {
    use qfa_calibrate::peers::PeerKind;
    let unit = if ch.kind == LogKind::Cycling { 1e6 } else { 1.0 };
    let (mut temp, mut y) = (Vec::new(), Vec::new());
    for t in &ch.traces {
        for b in &t.bins {
            let m = (b.hi - b.lo) as f64;
            temp.push(t.temp_raw[b.lo..b.hi].iter().map(|&r| f64::from(r) / 16.0).sum::<f64>() / m);
            y.push(b.bias);
        }
    }
    PeerKind::ALL
        .into_iter()
        .map(|kind| {
            let mut res = vec![f64::NAN; y.len()];
            for (test, train) in masks.iter().zip(trains) {
                let idx: Vec<usize> = (0..y.len()).filter(|&i| train[i] && y[i].is_finite()).collect();
                let tt: Vec<f64> = idx.iter().map(|&i| temp[i]).collect();
                let ty: Vec<f64> = idx.iter().map(|&i| y[i]).collect();
                match kind.fit(&tt, &ty) {
                    Ok(p) => {
                        for i in (0..y.len()).filter(|&i| test[i]) {
                            res[i] = (y[i] - p.eval(temp[i])) * unit;
                        }
                    }
                    Err(e) => {
                        return PeerGap {
                            peer: kind.label().into(),
                            heldout_rms: None,
                            error: Some(format!("fit on a fold: {e}")),
                        }
                    }
                }
            }
            if res.iter().all(|x| !x.is_finite()) {
                return PeerGap { peer: kind.label().into(), heldout_rms: None, error: Some("no held-out bin".into()) };
            }
            PeerGap { peer: kind.label().into(), heldout_rms: Some(rms(&res)), error: None }
        })
        .collect()
}
