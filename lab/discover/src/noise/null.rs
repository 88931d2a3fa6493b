//! The null distribution of [`super::test`]'s statistics: series drawn from the fitted
//! model, each tested as the log is.

use super::split::{clipped, max_split, max_split_gls};
use super::{fit_runs, max_run_noise, NoiseModel, NULL_DRAWS};
use qfa_rng::{normal, seeded, stream_seed, GaussMarkov, Stream};

/// Stream `index` (the tested series) under base seed 0: a log always gets one answer.
const NULL_DRAWS_STREAM: Stream = Stream::named("change-point null draws");

/// The critical values of [`test`]'s three statistics under the fitted model.
pub(super) struct NullCriticals {
    /// The difference of segment means' largest |z|.
    pub(super) means: f64,
    /// The whitened search's largest |z|.
    pub(super) whitened: f64,
    /// The noisiest run's bin-to-bin noise over the median run's.
    pub(super) run_noise: f64,
}

/// Critical values of the two change-point searches that hold level `alpha` jointly over
/// the null draws' maxima `a` and `b` (one pair per draw): the `k`-th largest of each, `k`
/// the largest for which at most `alpha` of the draws exceed either. The two searches are
/// correlated (both look for a step), so this is less strict than `alpha / 2` for each.
pub(super) fn joint_criticals(a: &[f64], b: &[f64], alpha: f64) -> (f64, f64) {
    let n = a.len();
    let (mut sa, mut sb) = (a.to_vec(), b.to_vec());
    sa.sort_by(f64::total_cmp);
    sb.sort_by(f64::total_cmp);
    let allowed = (alpha * n as f64).floor() as usize;
    let mut best = (sa[n - 1], sb[n - 1]);
    for k in 2..=n {
        let (ca, cb) = (sa[n - k], sb[n - k]);
        let over = a.iter().zip(b).filter(|(x, y)| **x > ca || **y > cb).count();
        if over > allowed {
            break;
        }
        best = (ca, cb);
    }
    best
}

/// The critical values at level `alpha` of the change-point searches (jointly) and of the
/// noisiest run over runs drawn from `model`, one per mask of `masks` (its length the
/// run's, its values where a split may fall), drawn from stream `index` of the null draws'
/// family.
pub(super) fn null_quantile(model: &NoiseModel, masks: &[Vec<bool>], alpha: f64, index: u64) -> NullCriticals {
    let mut rng = seeded(stream_seed(0, NULL_DRAWS_STREAM, index));
    let phi = model.phi();
    let mut draws: Vec<(f64, f64, f64)> = (0..NULL_DRAWS)
        .map(|_| {
            let series: Vec<Vec<f64>> = masks
                .iter()
                .map(|mask| {
                    let mut g = GaussMarkov::stationary(model.slow_sd, &mut rng);
                    (0..mask.len()).map(|_| g.step(phi, &mut rng) + model.white * normal(&mut rng)).collect()
                })
                .collect();
            let refs: Vec<&[f64]> = series.iter().map(Vec::as_slice).collect();
            // Each draw is tested as the log is: against the model fitted to the draw
            // itself, so that the fit's own error is in the null (see the module docs).
            let refit = fit_runs(&refs, model.bin_s);
            let top =
                refs.iter().filter_map(|v| max_split(&refit, &clipped(&refit, v)).map(|m| m.0)).fold(0.0f64, f64::max);
            let top_gls = refs
                .iter()
                .zip(masks)
                .filter_map(|(v, mask)| max_split_gls(&refit, v, mask).map(|m| m.0))
                .fold(0.0f64, f64::max);
            (top, top_gls, max_run_noise(&refs).map_or(0.0, |r| r.0))
        })
        .collect();
    let (a, b): (Vec<f64>, Vec<f64>) = draws.iter().map(|d| (d.0, d.1)).unzip();
    let (means, whitened) = joint_criticals(&a, &b, alpha);
    draws.sort_by(|x, y| x.2.total_cmp(&y.2));
    let i = (((1.0 - alpha) * NULL_DRAWS as f64).ceil() as usize).min(NULL_DRAWS) - 1;
    NullCriticals { means, whitened, run_noise: draws[i].2 }
}
