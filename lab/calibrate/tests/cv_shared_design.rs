//! Cross-validation with one design per fold for a log's axes gives each axis the bits a
//! fit of that axis alone gives.

use qfa_calibrate::fit::{fit_static_traced, FitError, StaticSeries, StaticTraces};
use qfa_calibrate::static_cal::{candidates, cv_rms_axes, StaticCalOptions, CV_FOLDS};

/// Each axis's figure, as cross-validation fitted it before the axes shared a design: a
/// fit of that axis alone per fold (`fit_static_traced`, a design of its own), scored on
/// the held-out rows inside the fold's grid, which `cv_rms_axes` must equal. So this checks the sharing (each axis's own fits, errors
/// and sums); that a fit's bits did not move is shown by the outputs of the real log and
/// the simulated ones, byte for byte, before and after.
fn cv_rms_alone(
    series: &StaticSeries<'_>,
    traces: &StaticTraces,
    rows: &[usize],
    k: usize,
    opts: &StaticCalOptions,
) -> Result<f64, FitError> {
    let (n, m) = (series.rows(), rows.len());
    let (mut sum, mut count) = (0.0, 0usize);
    for f in 0..k {
        let chunk = &rows[m * f / k..m * (f + 1) / k];
        let mut train = vec![false; n];
        rows.iter().for_each(|&i| train[i] = true);
        chunk.iter().for_each(|&i| train[i] = false);
        let fit = fit_static_traced(series, traces, &train, opts.grid_points, opts.block)?;
        let (Some(&lo), Some(&hi)) = (chunk.first(), chunk.last()) else { continue };
        let tr = series.model_trace_rows(&fit.axis, lo..hi + 1);
        let grid = f64::from(fit.axis.bias.t_start_c)..=f64::from(fit.axis.bias.t_end_c());
        for &i in chunk.iter().filter(|&&i| tr.valid[i - lo] && grid.contains(&tr.temp_c[i - lo])) {
            let r = series.accel_g[i] - fit.reference_g - tr.ext_k0_g[i - lo];
            sum += r * r;
            count += 1;
        }
    }
    if count == 0 {
        return Err(FitError::TooFewRows { rows: 0, unknowns: traces.structure.unknowns(opts.grid_points) });
    }
    Ok((sum / count as f64).sqrt())
}

/// Over random logs, every candidate structure and several row sets, the shared design
/// gives each axis the bits (or the error) a fit of that axis alone gives, including an
/// axis whose tables the root crate refuses while the others are fitted.
#[test]
fn axes_sharing_a_design_get_what_their_own_fits_give() {
    let mut rng = qfa_rng::seeded(qfa_rng::stream_seed(11, qfa_rng::Stream::named("shared design test"), 0));
    let opts = StaticCalOptions::default();
    let (mut compared, mut refused) = (0usize, 0usize);
    for _ in 0..3 {
        let n = 1500 + qfa_rng::below(&mut rng, 1500);
        let rate = 0.02 + 0.03 * qfa_rng::uniform(&mut rng);
        let time: Vec<f64> = (0..n).map(|i| i as f64).collect();
        // Up, then down, with noise on the reading.
        let temp: Vec<f64> = (0..n)
            .map(|i| {
                let leg = if i < n / 2 { i as f64 } else { (n - i) as f64 };
                15.0 + rate * leg + 0.05 * qfa_rng::normal(&mut rng)
            })
            .collect();
        let axis = |rng: &mut qfa_rng::LabRng, scale: f64| -> Vec<f64> {
            let slope = 1e-4 * qfa_rng::normal(rng);
            temp.iter().map(|t| scale * (slope * t + 2e-5 * qfa_rng::uniform(rng))).collect()
        };
        // The third axis's curve is far outside what a table may hold.
        let outputs = [axis(&mut rng, 1.0), axis(&mut rng, 1.0), axis(&mut rng, 1e9)];
        let view = StaticSeries::view_of(&time, &temp, opts.deadband_c_per_min);
        let axes: Vec<StaticSeries<'_>> = outputs.iter().map(|a| StaticSeries { view: &view, accel_g: a }).collect();
        let all: Vec<usize> = (0..n).collect();
        let first_half: Vec<usize> = (0..n / 2 + n / 10).collect();
        for st in candidates() {
            let traces = StaticTraces::new(&axes[0], &st, opts.deadband_c_per_min);
            for rows in [&all, &first_half] {
                let shared = cv_rms_axes(&axes, &traces, rows, CV_FOLDS, &opts);
                for (series, got) in axes.iter().zip(&shared) {
                    let alone = cv_rms_alone(series, &traces, rows, CV_FOLDS, &opts);
                    match (got, &alone) {
                        (Ok(a), Ok(b)) => assert_eq!(a.to_bits(), b.to_bits(), "{}", st.name()),
                        (a, b) => {
                            assert_eq!(a, b, "{}", st.name());
                            refused += 1;
                        }
                    }
                    compared += 1;
                }
            }
        }
    }
    assert_eq!(compared, 3 * candidates().len() * 2 * 3);
    assert!(refused > 0 && refused < compared / 2, "{refused} of {compared} refused: the refusal case is not tried");
}
