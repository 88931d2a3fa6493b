//! Each figure's yardstick: the median and robust scale of the units of full coverage (or
//! of a unit's own lot), and the units beyond the flag line (the fleet's module docs).

use super::{value_of, words, Calibrated, Feature, FeatureStats, Flag, Measured, Side, UnitResult, Z_FLAG};

/// What a figure's units are compared with: the fleet's units of full coverage, or, when
/// the fleet holds two lots, a unit's own lot.
pub(super) struct Yardstick<'a> {
    pub(super) results: &'a [UnitResult],
    pub(super) cal: &'a [Option<&'a Calibrated>],
    pub(super) sensor: &'a [(Measured, Measured)],
    pub(super) partial: &'a [bool],
    /// Whether a unit measures the yardstick: full coverage, and a log that fits the batch.
    pub(super) reference: &'a [bool],
    pub(super) lots: Option<&'a crate::lots::Lots>,
}

/// The median and robust scale (at least `floor`) of `values`.
fn median_scale(values: &[f64], floor: f64) -> Option<[f64; 2]> {
    let (med, sd) = qfa_log::robust::median_and_sd(values)?;
    Some([med, sd.max(floor)])
}

/// The fleet's robust statistics of `feat` (median and scale over the units of full
/// coverage, and over each lot's), each unit outside its yardstick flagged in `flags`;
/// `None` when no unit gives a value.
pub(super) fn feature_stats(feat: Feature, y: &Yardstick<'_>, flags: &mut [Vec<Flag>]) -> Option<FeatureStats> {
    let values: Vec<(usize, f64)> = y
        .cal
        .iter()
        .enumerate()
        .filter_map(|(i, c)| {
            let c = (*c)?;
            value_of(c, (&y.sensor[i].0, &y.sensor[i].1), &feat.name).filter(|v| v.is_finite()).map(|v| (i, v))
        })
        .collect();
    let of = |keep: &dyn Fn(usize) -> bool| -> Vec<f64> {
        values.iter().filter(|(i, _)| y.reference[*i] && keep(*i)).map(|(_, v)| *v).collect()
    };
    let reference = of(&|_| true);
    let [med, scale] = median_scale(&reference, feat.floor)?;
    let within = y.lots.filter(|l| l.compared_within);
    let lot_of = |i: usize| within.and_then(|l| l.lot_of(i));
    let lots: Vec<[f64; 2]> = (0..if within.is_some() { 2 } else { 0 })
        .map(|k| median_scale(&of(&|i| lot_of(i) == Some(k)), feat.floor).unwrap_or([med, scale]))
        .collect();
    let stats = FeatureStats {
        n: values.len(),
        yardstick_n: reference.len(),
        median: med,
        scale,
        values: values.iter().map(|(i, v)| (y.results[*i].serial.clone(), *v)).collect(),
        feature: feat,
        lots,
    };
    let feat = &stats.feature;
    for &(i, v) in &values {
        if feat.full_coverage_only && y.partial[i] {
            continue;
        }
        let against = lot_of(i).map_or_else(|| "the fleet's".to_string(), |k| format!("its lot's (lot {})", k + 1));
        let z = stats.distance(v, lot_of(i));
        let med = stats.yardstick(lot_of(i))[0];
        let out = match feat.side {
            Side::Both => z.abs() > Z_FLAG,
            Side::High => z > Z_FLAG,
        };
        if out {
            flags[i].push(Flag {
                feature: feat.name.clone(),
                value: v,
                median: med,
                z,
                text: format!(
                    "{}{} {v:.3} {} against {against} {:.3} ({z:+.1} robust SDs; flagged beyond ±{Z_FLAG})",
                    words(&feat.name).map_or_else(String::new, |w| format!("{w}: ")),
                    feat.name,
                    feat.unit,
                    // No "-0.000": a median that rounds to zero reads as zero.
                    if (med * 1e3).round() == 0.0 { 0.0 } else { med },
                ),
            });
        }
    }
    Some(stats)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::fleet::MIN_FLEET;
    use qfa_rng::{normal, seeded, stream_seed, Stream};

    /// The share of good units a fleet of `n` flags on 12 figures drawn normal (each unit
    /// against the fleet's median and robust scale, itself included, as the fleet forms
    /// them), over 4 000 fleets.
    fn false_share(n: usize) -> f64 {
        let mut flagged = 0usize;
        for f in 0..4000u64 {
            let mut r = seeded(stream_seed(n as u64, Stream::named("fleet size oracle"), f));
            let x: Vec<Vec<f64>> = (0..12).map(|_| (0..n).map(|_| normal(&mut r)).collect()).collect();
            let yard: Vec<[f64; 2]> = x.iter().map(|col| median_scale(col, 0.0).unwrap()).collect();
            flagged +=
                (0..n).filter(|&i| x.iter().zip(&yard).any(|(col, [m, s])| ((col[i] - m) / s).abs() > Z_FLAG)).count();
        }
        flagged as f64 / (4000 * n) as f64
    }

    /// A fleet of `MIN_FLEET` units holds the goal of at most one good unit in 50 beyond the
    /// flag line on normal figures (the figures' law is the oracle: no unit is an outlier).
    /// At 10 units the share is about 2.7 %: the check fails there.
    #[test]
    fn a_fleet_of_min_fleet_units_flags_under_one_good_unit_in_50() {
        let at_min = false_share(MIN_FLEET);
        assert!(at_min < 0.02, "{at_min}");
        assert!(false_share(10) > 0.02, "the oracle cannot tell 10 units from {MIN_FLEET}");
    }
}
