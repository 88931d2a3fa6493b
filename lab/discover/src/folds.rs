//! The held-out folds of a discovery: programs dealt by ramp rate, or time blocks of one trace.

use super::*;

/// Bins per time block of the single-trace held-out split (20 min at 60-s bins): short
/// enough that every fold sees every temperature region on heating and cooling.
pub(super) const TIME_BLOCK_BINS: usize = 20;
/// Folds of the single-trace split (blocks dealt round-robin).
pub(super) const TIME_FOLDS: usize = 2;
/// Bins on each side of a held-out block that its training set leaves out. Tried: 3
/// folds of 60-bin blocks with a 30-bin buffer (so noise slower than the blocks cannot
/// leak from training into held-out bins); the training folds then miss whole
/// temperature regions and the held-out gap of a clean log grew 5× (1.7 → 8.3 µg), so
/// the buffer is off and slow noise is left to the block test.
pub(super) const BUFFER_BINS: usize = 0;

/// Held-out folds: per fold, the mask of its test bins and the mask of its training bins.
pub(super) fn folds(ch: &Channels) -> (Vec<Vec<bool>>, Vec<Vec<bool>>, String) {
    let n = ch.n_bins();
    let mut offs = Vec::new();
    let mut o = 0;
    for t in &ch.traces {
        offs.push(o);
        o += t.bins.len();
    }
    if ch.kind == LogKind::Cycling && ch.traces.len() >= 2 {
        let mut masks = vec![vec![false; n]; 2];
        let mut order: Vec<usize> = (0..ch.traces.len()).collect();
        order.sort_by(|&a, &b| ch.traces[a].ramp_rate().total_cmp(&ch.traces[b].ramp_rate()).then(a.cmp(&b)));
        let mut desc = [Vec::new(), Vec::new()];
        for (rank, &ti) in order.iter().enumerate() {
            let k = rank % 2;
            let t = &ch.traces[ti];
            for b in 0..t.bins.len() {
                masks[k][offs[ti] + b] = true;
            }
            desc[k].push(format!("{} ({})", t.program, t.ramp_rate_words()));
        }
        let rule = format!(
            "leave-programs-out, 2 folds by ramp-rate rank: fold A = {}; fold B = {}; each fold fitted on the other",
            desc[0].join(", "),
            desc[1].join(", ")
        );
        let trains = masks.iter().map(|m| m.iter().map(|&t| !t).collect()).collect();
        (masks, trains, rule)
    } else {
        let mut masks = vec![vec![false; n]; TIME_FOLDS];
        let mut trains = vec![vec![false; n]; TIME_FOLDS];
        for (ti, t) in ch.traces.iter().enumerate() {
            let m = t.bins.len();
            for b in 0..m {
                masks[(b / TIME_BLOCK_BINS) % TIME_FOLDS][offs[ti] + b] = true;
            }
            for k in 0..TIME_FOLDS {
                for b in 0..m {
                    let lo = b.saturating_sub(BUFFER_BINS);
                    let hi = (b + BUFFER_BINS + 1).min(m);
                    trains[k][offs[ti] + b] = (lo..hi).all(|j| !masks[k][offs[ti] + j]);
                }
            }
        }
        let rule = format!(
            "split in time: blocks of {TIME_BLOCK_BINS} bins dealt round-robin into {TIME_FOLDS} folds; each fold \
             fitted on the others less {BUFFER_BINS} bins either side of its blocks"
        );
        (masks, trains, rule)
    }
}

/// Noise floor of a per-bin residual: the bin-to-bin noise of its fitted noise model
/// ([`super::noise::NoiseModel::floor`]), robust to glitches and steps.
pub(crate) fn noise_floor(ch: &Channels, v: &[f64]) -> f64 {
    super::noise::fit(ch, v).floor()
}
