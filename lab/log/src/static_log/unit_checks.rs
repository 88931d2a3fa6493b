//! The unit checks of a static log: whether the time, acceleration and temperature units
//! the rows were read in fit what the rows show, and the evidence said when they do not.

use super::*;

/// The sampling of the kept rows (`time_s` from the first, s; `temp_c`, °C; `lines`, their
/// line numbers), after the time-unit check: a median row interval outside 10 µs…60 s, or
/// a temperature changing faster than [`MAX_SLEW_C_PER_MIN`], refuses the time unit.
pub(super) fn check_time_unit(
    time_s: &[f64],
    temp_c: &[f64],
    lines: &[u64],
    layout: &Layout,
) -> Result<Sampling, StaticError> {
    let intervals: Vec<f64> = time_s.windows(2).map(|w| w[1] - w[0]).collect();
    // At least MIN_ROWS − 1 intervals (the rows were counted before).
    let med = median(&intervals).unwrap_or(0.0);
    let slew = max_slew(time_s, temp_c);
    if !INTERVAL_S.contains(&med) || slew.c_per_min > MAX_SLEW_C_PER_MIN {
        return Err(time_unit_mismatch(time_s, temp_c, lines, med, &slew, layout));
    }
    Ok(Sampling {
        median_interval_s: med,
        irregular_intervals: intervals.iter().filter(|&&d| d < 0.5 * med || d > 2.0 * med).count(),
        gaps_over_30s: intervals.iter().filter(|&&d| d > 30.0).count(),
        max_interval_s: intervals.iter().copied().fold(0.0, f64::max),
        max_slew_c_per_min: slew.c_per_min,
    })
}

/// The time-unit error of [`check_time_unit`]: the slew (with the rows it runs between) when
/// the interval is plausible, else the interval, and the other units that make both
/// plausible.
pub(super) fn time_unit_mismatch(
    time_s: &[f64],
    temp_c: &[f64],
    lines: &[u64],
    med: f64,
    slew: &Slew,
    layout: &Layout,
) -> StaticError {
    let time_unit = layout.time_unit;
    // Which other units would make both the interval and the slew plausible.
    let fits = TimeUnit::ALL
        .into_iter()
        .filter(|&u| u != time_unit)
        .filter_map(|u| {
            let k = u.seconds() / time_unit.seconds();
            let t: Vec<f64> = time_s.iter().map(|x| x * k).collect();
            let s = max_slew(&t, temp_c).c_per_min;
            (INTERVAL_S.contains(&(med * k)) && s <= MAX_SLEW_C_PER_MIN)
                .then(|| (u.name(), format!("rows {} s apart, {s:.1} °C/min", sig3(med * k))))
        })
        .collect();
    let (evidence, expected) = if INTERVAL_S.contains(&med) {
        // The filtered values are the ones the range is of; at these rows they are the
        // readings themselves unless a neighbour was a bad one.
        let at = |i: usize| -> (u64, f64) { (lines[i], centred_median(temp_c, i)) };
        let (a, b) = (at(slew.from), at(slew.to));
        (
            format!(
                "the temperature changes by {:.0} °C/min ({:.2} °C within {:.3} s: from {:.2} °C at line {} to \
                 {:.2} °C at line {})",
                slew.c_per_min, slew.range_c, slew.window_s, a.1, a.0, b.1, b.0
            ),
            format!("a board in a climate chamber changes by at most {MAX_SLEW_C_PER_MIN:.0} °C/min"),
        )
    } else {
        (format!("the median row interval is {} s", sig3(med)), "a logger writes a row every 10 µs..60 s".to_string())
    };
    StaticError::Unit(Box::new(UnitMismatch {
        option: ReaderOption::TimeUnit,
        stated: time_unit.name(),
        source: layout.time_src.clone(),
        evidence,
        expected,
        fits,
    }))
}

/// The median |a| over the `rows` kept rows, g, after the acceleration-unit check: the
/// median must lie in [`REST_G`] (0.67…1.5 g) with every axis, at most 1.5 g with fewer;
/// outside, the unit is refused, naming the units that fit.
pub(super) fn check_accel_unit(axes: &[AxisColumn], rows: usize, layout: &Layout) -> Result<f64, StaticError> {
    let accel_unit = layout.accel_unit;
    // A board at rest reads |a| = 1 g: with every axis the median |a| is checked from both
    // sides, with fewer axes (a projection) only from above.
    let mag: Vec<f64> =
        (0..rows).map(|k| axes.iter().map(|a| a.accel_g[k] * a.accel_g[k]).sum::<f64>().sqrt()).collect();
    let med_mag = median(&mag).unwrap_or(0.0);
    let all_axes = axes.len() == 3;
    let lo = if all_axes { REST_G.0 } else { 0.0 };
    if !(lo..=REST_G.1).contains(&med_mag) {
        let fits = AccelUnit::ALL
            .into_iter()
            .filter(|&u| u != accel_unit)
            .map(|u| (u, med_mag * u.g() / accel_unit.g()))
            .filter(|(_, m)| (REST_G.0..=REST_G.1).contains(m))
            .map(|(u, m)| (u.name(), format!("median |a| {} g", sig3(m))))
            .collect();
        let cols = axes.iter().map(|a| a.column.as_str()).collect::<Vec<_>>().join(", ");
        let expected = if all_axes {
            format!("a board at rest reads |a| = 1 g ({:.2}..{:.2} g)", REST_G.0, REST_G.1)
        } else {
            format!("a board at rest reads at most {:.2} g on {} of its axes", REST_G.1, axes.len())
        };
        return Err(StaticError::Unit(Box::new(UnitMismatch {
            option: ReaderOption::AccelUnit,
            stated: accel_unit.name(),
            source: layout.accel_src.clone(),
            evidence: format!("the median |a| over {cols} is {} g", sig3(med_mag)),
            expected,
            fits,
        })));
    }
    Ok(med_mag)
}

/// How each unit was decided and what the kept rows show in it (`med_mag`, the median |a|
/// over `n_axes` axes, g; `temp_c`, the kept temperatures, °C), with the other temperature
/// units every reading of the file (`file_temps`) would also fit.
pub(super) fn unit_evidence(
    layout: &Layout,
    sampling: &Sampling,
    med_mag: f64,
    n_axes: usize,
    temp_c: &[f64],
    file_temps: &[f64],
) -> UnitEvidence {
    let temp_range = range_c(temp_c, TempUnit::C);
    UnitEvidence {
        units: vec![
            (
                ReaderOption::TimeUnit,
                layout.time_unit.name(),
                layout.time_src.clone(),
                format!(
                    "rows {} s apart, fastest change {:.1} °C/min",
                    sig3(sampling.median_interval_s),
                    sampling.max_slew_c_per_min
                ),
            ),
            (
                ReaderOption::AccelUnit,
                layout.accel_unit.name(),
                layout.accel_src.clone(),
                format!("median |a| {} g over {} axis(es)", sig3(med_mag), n_axes),
            ),
            (
                ReaderOption::TempUnit,
                layout.temp_unit.name(),
                layout.temp_src.clone(),
                format!("{:.1}..{:.1} °C", temp_range.0, temp_range.1),
            ),
        ],
        median_abs_g: med_mag,
        all_axes: n_axes == 3,
        temp_range_c: temp_range,
        temp_also_plausible: temp_fits(file_temps, layout.temp_unit).into_iter().map(|(u, r)| (u.name(), r)).collect(),
    }
}

/// The columns used, `(role, column, unit)`: time, temperature, then each axis.
pub(super) fn columns_used(layout: &Layout, axes: &[AxisColumn]) -> Vec<(String, String, String)> {
    let mut columns = vec![
        ("time".to_string(), layout.header[layout.ti].clone(), format!("{:?}", layout.time_unit).to_lowercase()),
        (
            "temp".to_string(),
            layout.header[layout.tc].clone(),
            format!("deg{}", layout.temp_unit.name()).replace("degK", "K"),
        ),
    ];
    for a in axes {
        columns.push((a.name.clone(), a.column.clone(), format!("{:?}", layout.accel_unit).to_lowercase()));
    }
    columns
}

/// `x` with three significant digits (`0.00957`, `9.57`, `957`).
pub(super) fn sig3(x: f64) -> String {
    if x == 0.0 || !x.is_finite() {
        return format!("{x}");
    }
    let digits = (2 - x.abs().log10().floor() as i32).max(0) as usize;
    format!("{x:.digits$}")
}

/// Range of `v` (in `unit`), °C.
pub(super) fn range_c(v: &[f64], unit: TempUnit) -> (f64, f64) {
    v.iter().map(|&x| unit.to_c(x)).fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), x| (a.min(x), b.max(x)))
}

/// The temperature units other than `stated` in which every reading of `v` lies in
/// [`TEMP_RANGE_C`], with the range each gives, °C.
pub(super) fn temp_fits(v: &[f64], stated: TempUnit) -> Vec<(TempUnit, (f64, f64))> {
    TempUnit::ALL
        .into_iter()
        .filter(|&u| u != stated)
        .map(|u| (u, range_c(v, u)))
        .filter(|(_, (lo, hi))| TEMP_RANGE_C.contains(lo) && TEMP_RANGE_C.contains(hi))
        .collect()
}

/// A column's unit from the option, else from the column names (`(unit in the name, name)`
/// per column); an option contradicting a name is refused. `None`: neither states it.
pub(super) fn resolve<U: Copy + PartialEq>(
    option: Option<U>,
    named: &[(Option<U>, &String)],
    which: ReaderOption,
    name: fn(U) -> &'static str,
) -> Result<Option<(U, UnitSource)>, StaticError> {
    if let Some(u) = option {
        if let Some((Some(n), col)) = named.iter().find(|(n, _)| n.is_some_and(|n| n != u)) {
            return Err(StaticError::Unit(Box::new(UnitMismatch {
                option: which,
                stated: name(u),
                source: UnitSource::Option,
                evidence: format!("the column `{col}` is named for {}", name(*n)),
                expected: "a unit in a column's name and the one passed must agree".to_string(),
                fits: vec![(name(*n), "the column name's unit".to_string())],
            })));
        }
        return Ok(Some((u, UnitSource::Option)));
    }
    match named.first() {
        Some((Some(u), col)) if named.iter().all(|(n, _)| *n == Some(*u)) => {
            Ok(Some((*u, UnitSource::ColumnName((*col).clone()))))
        }
        _ => Ok(None),
    }
}
