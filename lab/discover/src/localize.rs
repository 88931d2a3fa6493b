//! Where held-out residuals disagree with the model: the worst segments per channel
//! (ramps by rate and temperature band, holds by time since the last change).

use super::*;
use qfa_log::replay::Motion;

/// Localize the disagreement of held-out residuals `r`: worst segments per channel.
#[must_use]
pub(crate) fn localize(ch: &Channels, r: &Residuals, top: usize) -> Vec<Where> {
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
                if Motion::direction(f64::from(t.est_rate[row])) != Motion::Holding {
                    last_change = t.time_s[row];
                }
                row += 1;
            }
            let (tm, rm) = t.bin_means(b);
            let band = (tm / width).floor() * width;
            let motion = Motion::direction(rm);
            let seg = if motion != Motion::Holding {
                format!(
                    "{} ramps {rate:.1} °C/min, {band:.0}..{:.0} °C",
                    if motion == Motion::Heating { "heating" } else { "cooling" },
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
