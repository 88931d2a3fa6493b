//! The temperature sensor against the fleet: each unit's offset and drift from the fleet's
//! median reading on the steady minutes of the shared clock (the fleet's module docs).

use super::{median, Calibrated, Measured};

/// The fleet's median reading moves less than this on a steady minute, °C/min.
pub(crate) const STEADY_C_PER_MIN: f64 = 0.1;
/// Units a minute needs for its median to be formed.
pub(super) const MIN_UNITS_PER_MINUTE: usize = 3;
/// Steady minutes a sensor comparison needs.
const MIN_STEADY_MINUTES: usize = 10;
/// The smallest change of a sensor's reading against the fleet's, over the span of a log's
/// steady minutes, that the drift's yardstick tells from none, °C: 1.6 of the DS18B20's
/// 1/16-°C steps. The drift's robust scale is at least this over the fleet's median span:
/// 0.05 °C/h on a 2-h static chamber run (the floor it had as a constant), 0.0003 °C/h on
/// a QFA campaign of 376 h, where a constant 0.05 °C/h would have let a sensor drift by
/// 19 °C before its drift counted as one robust SD.
pub(crate) const DRIFT_RESOLUTION_C: f64 = 0.1;
/// The drift's floor when no unit's drift was measured (no yardstick is formed then).
const DRIFT_FLOOR_WITHOUT_SPAN_C_PER_H: f64 = 0.05;

/// Each unit's sensor offset and drift against the fleet, and the drift's floor.
pub(crate) struct Sensors {
    /// Per unit (in the batch's order): offset °C, drift °C/h.
    pub(crate) unit: Vec<(Measured, Measured)>,
    /// The drift's robust scale's floor, °C/h: [`DRIFT_RESOLUTION_C`] over the median span
    /// of the units' steady minutes.
    pub(crate) drift_floor_c_per_h: f64,
}

/// Each unit's sensor offset and drift against the fleet's median reading (module docs),
/// the median formed without the units whose log does not fit the batch (`input_fault`).
/// A minute is one of a leg's ([`crate::unit::SensorLeg`]): a static log's shared clock,
/// or one program's run of a cycling log, which every unit ran through alike.
pub(super) fn sensors(cal: &[Option<&Calibrated>], input_fault: &[bool]) -> Sensors {
    use std::collections::BTreeMap;
    let mut per_minute: BTreeMap<(&str, i64), Vec<f64>> = BTreeMap::new();
    for c in cal.iter().zip(input_fault).filter(|(_, f)| !**f).filter_map(|(c, _)| *c) {
        for leg in &c.temp_minutes {
            for &(k, t) in &leg.minutes {
                per_minute.entry((leg.leg.as_str(), k)).or_default().push(t);
            }
        }
    }
    let med: BTreeMap<(&str, i64), f64> = per_minute
        .into_iter()
        .filter(|(_, v)| v.len() >= MIN_UNITS_PER_MINUTE)
        .filter_map(|(k, v)| median(&v).map(|m| (k, m)))
        .collect();
    let steady: BTreeMap<(&str, i64), f64> = med
        .iter()
        .filter(|((leg, k), _)| match (med.get(&(*leg, *k - 1)), med.get(&(*leg, *k + 1))) {
            (Some(a), Some(b)) => ((b - a) / 2.0).abs() < STEADY_C_PER_MIN,
            _ => false,
        })
        .map(|(k, v)| (*k, *v))
        .collect();
    let not = |why: &str| Measured::NotComputed { not_computed: why.to_string() };
    let mut spans_h = Vec::new();
    let unit = cal
        .iter()
        .zip(input_fault)
        .map(|(c, &fault)| {
            let Some(c) = c else { return (not("not calibrated"), not("not calibrated")) };
            let d: Vec<(f64, f64)> = c
                .temp_minutes
                .iter()
                .flat_map(|leg| {
                    let steady = &steady;
                    leg.minutes.iter().filter_map(move |(k, t)| {
                        steady.get(&(leg.leg.as_str(), *k)).map(|m| (leg.start_h + *k as f64 / 60.0, t - m))
                    })
                })
                .collect();
            if d.len() < MIN_STEADY_MINUTES {
                let why = format!(
                    "{} steady minutes shared with at least {MIN_UNITS_PER_MINUTE} units; {MIN_STEADY_MINUTES} needed",
                    d.len()
                );
                return (not(&why), not(&why));
            }
            let diffs: Vec<f64> = d.iter().map(|p| p.1).collect();
            let offset = median(&diffs).map_or_else(|| not("no minute"), Measured::Value);
            if !fault {
                let (lo, hi) = d.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p.0), h.max(p.0)));
                spans_h.push(hi - lo);
            }
            (offset, drift_c_per_h(&d))
        })
        .collect();
    let drift_floor_c_per_h =
        median(&spans_h).filter(|&h| h > 0.0).map_or(DRIFT_FLOOR_WITHOUT_SPAN_C_PER_H, |h| DRIFT_RESOLUTION_C / h);
    Sensors { unit, drift_floor_c_per_h }
}

/// The slope of `(hour, °C)` points, °C/h, by the lab's one solver (time from the middle
/// of the span); not computed when the points span no time, where any slope fits.
fn drift_c_per_h(points: &[(f64, f64)]) -> Measured {
    let not = |why: String| Measured::NotComputed { not_computed: why };
    let (lo, hi) = points.iter().fold((f64::INFINITY, f64::NEG_INFINITY), |(l, h), p| (l.min(p.0), h.max(p.0)));
    if hi <= lo {
        return not("the steady minutes span no time".to_string());
    }
    let mid = 0.5 * (lo + hi);
    let x: Vec<f64> = points.iter().flat_map(|p| [1.0, p.0 - mid]).collect();
    let y: Vec<f64> = points.iter().map(|p| p.1).collect();
    match qfa_calibrate::solver::lstsq(&x, 2, &y) {
        Ok(fit) => Measured::Value(fit.coef[1]),
        Err(e) => not(format!("the drift could not be fitted: {e}")),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A sensor's drift: the slope of points on a line, whatever their spacing and level;
    /// points at one time have no slope and say so (never 0).
    #[test]
    fn a_drift_is_the_slope_of_the_points_and_none_without_a_span() {
        let points: Vec<(f64, f64)> = [0.0, 0.5, 1.7, 3.0, 4.2].iter().map(|&h| (h, 0.3 - 0.02 * h)).collect();
        let Measured::Value(d) = drift_c_per_h(&points) else { panic!("no drift") };
        assert!((d + 0.02).abs() < 1e-12, "{d}");
        let flat: Vec<(f64, f64)> = (0..5).map(|i| (2.0, f64::from(i))).collect();
        assert!(matches!(drift_c_per_h(&flat), Measured::NotComputed { .. }));
    }
}
