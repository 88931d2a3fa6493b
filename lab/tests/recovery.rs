//! Recovery of known coefficients from simulated logs, and held-out compensation.
//!
//! Short programs (pure ramps 22 → −30 → +50 → 22 °C at three rates, 30-min hold) and
//! 2-s rows keep these at a few seconds in debug builds. Tolerances are stated per
//! coefficient with the reason; expected values come from the truth presets (the paper's
//! Eq. 15–17), never from the code under test.

use qfa_calibrate::compensate::compensate_run;
use qfa_calibrate::fit::{fit, FitOptions, T0_C};
use qfa_calibrate::report::bias_in_place;
use qfa_calibrate::{calibrate_log, CalibrateOptions};
use qfa_log::cycling::Log;
use qfa_log::pairing::PairedLog;
use qfa_sim::profile::{paper_positions, Program};
use qfa_sim::simulate;
use qfa_sim::truth::Truth;
use qfa_thermal::model::Branch;

fn ramps(rate: f64) -> Program {
    Program::staircase(&format!("ramp-{rate}"), rate, 30.0, 0.0, -30, 50)
}

fn short_log(truth: &Truth, rates: &[f64], row_s: u32, seed: u64) -> Log {
    let programs: Vec<Program> = rates.iter().map(|&r| ramps(r)).collect();
    simulate(truth, &programs, &paper_positions(), row_s, seed, 2, None)
}

fn rel(a: f64, b: f64) -> f64 {
    (a - b).abs() / b.abs()
}

/// Noiseless unit #2 (the one with a sizeable η), sensor offset 0: every Eq. 11
/// coefficient comes back. Tolerances: the fit sees the firmware's T̂ and Ṫ (12-bit
/// quantized, 32-sample LS window, reading applied to the row it ends) instead of the
/// exact case temperature. The 32-sample LS window (1-s rows, as on target) reports the
/// rate of 16 s ago, so after each turnaround of these pure ramps the rate it sees lags the
/// true one; that biases the rate terms ε and η by several percent (measured: ε −7 %,
/// η +5 %), hence 10 % on ε, η and α, tighter on the temperature terms.
#[test]
fn eq11_coefficients_recovered_from_noiseless_log() {
    let mut truth = Truth::jb_kt8(2).noiseless();
    truth.sensor.offset_c = 0.0;
    let rates = [0.5, 1.0, 1.5];
    let log = short_log(&truth, &rates, 1, 3);
    let programs: Vec<String> = log.programs();
    let f = fit(&qfa_log::pairing::PairedLog::new(&log), &FitOptions::new(programs), None).unwrap();
    let c = &f.sf_hysteresis.coef;
    let s = truth.scale;
    println!("fitted [γ μ β ε η α] = {c:?}, cond {:.1}", f.sf_hysteresis.cond);
    let want = [s.gamma, s.mu, s.beta, s.epsilon, s.eta, s.alpha].map(f64::from);
    assert!(rel(c[0], want[0]) < 3e-6, "γ {} vs {}", c[0], want[0]);
    assert!(rel(c[1], want[1]) < 0.01, "μ {} vs {}", c[1], want[1]);
    assert!(rel(c[2], want[2]) < 0.05, "β {} vs {}", c[2], want[2]);
    assert!(rel(c[3], want[3]) < 0.10, "ε {} vs {}", c[3], want[3]);
    assert!(rel(c[4], want[4]) < 0.10, "η {} vs {}", c[4], want[4]);
    assert!(rel(c[5], want[5]) < 0.10, "α {} vs {}", c[5], want[5]);
    // Bias: the grid nodes follow the smooth truth within 1 µg on both branches.
    let g = &f.hysteresis.axes[0].bias;
    for (i, (&h, &cg)) in g.heating_g.iter().zip(&g.cooling_g).enumerate() {
        let t = f64::from(g.t_start_c) + f64::from(g.t_step_c) * i as f64;
        let b = truth.bias.at(t - T0_C);
        assert!((f64::from(h) - b).abs() < 1e-6, "heating node {i} at {t}: {h} vs {b}");
        assert!((f64::from(cg) - b).abs() < 1e-6, "cooling node {i} at {t}: {cg} vs {b}");
    }
    // Simple model: a line through the curved truth. Independent reference: the LS line of
    // the truth polynomial sampled uniformly over −30..50 °C (the ramps spend equal time
    // per degree); ±5 µg at T0 and ±0.1 µg/°C on the slope cover the hold's extra weight.
    let ts: Vec<f64> = (0..=800).map(|i| -30.0 + 0.1 * f64::from(i) - T0_C).collect();
    let n = ts.len() as f64;
    let (mx, my) = (ts.iter().sum::<f64>() / n, ts.iter().map(|&d| truth.bias.at(d)).sum::<f64>() / n);
    let sxy: f64 = ts.iter().map(|&d| (d - mx) * (truth.bias.at(d) - my)).sum();
    let sxx: f64 = ts.iter().map(|&d| (d - mx) * (d - mx)).sum();
    let (slope, icept) = (sxy / sxx, my - sxy / sxx * mx);
    let sb = &f.bias_simple.coef;
    assert!((sb[0] - icept).abs() < 5e-6, "k0 {} vs {}", sb[0], icept);
    assert!((sb[1] - slope).abs() < 0.1e-6, "k1 {} vs {}", sb[1], slope);
    // The flashable bytes decode to the same table.
    let bytes = f.hysteresis.to_bytes().unwrap();
    assert_eq!(qfa_thermal::Table::decode(&bytes).unwrap(), f.hysteresis);
}

/// With the truth's own coefficients in a table, the root crate's compensator returns the
/// input of a noiseless run on average (mean error within 3 µg; one pulse is 3 µg).
/// Row by row it cannot be exact: the 32-sample LS rate of 12-bit readings jitters by
/// about ±0.005–0.02 °C/min, which Eq. 11 turns into ±(ε + 2α·Ṫ)·δṪ ≈ ±3–13 pulses/s for
/// JB-KT8 #1 (α = 273): RMS bounded by 30 µg, and the worst rows (turnarounds, where the
/// window's 16-s lag adds ε·Δṫ) by 200 µg.
#[test]
fn compensator_with_exact_table_returns_the_input() {
    let (mean, rms, worst) = exact_table_error(1);
    assert!(mean.abs() < 3e-6, "{mean}");
    assert!(rms < 30e-6, "{rms}");
    assert!(worst < 200e-6, "{worst}");
}

/// The same run logged at 10-s rows. The compensation of a log fills in the firmware's
/// 1-s readings between rows and runs a 10-s row as ten 1-s cycles, so the mean stays
/// within a pulse (measured 0.93 µg). Row by row it is worse than the 1-s log (RMS 51.1,
/// max 258 µg): a 10-s row's reading does not say when within those 10 s the sensor's
/// code changed, so the filled readings' code steps sit up to 5 s from the sensor's own
/// at 0.375 °C/min and Ṫ jitters by more. The RMS and max bounds (60, 300 µg) were set
/// after seeing those figures; with one reading per row at its end (the estimator's 32
/// readings then span 320 s) they were mean −8.6, RMS 96.9, max 504 µg, and all three
/// bounds fail (`cargo test -p qfa-lab --test recovery -- --nocapture`).
#[test]
fn compensator_with_exact_table_returns_the_input_from_ten_second_rows() {
    let (mean, rms, worst) = exact_table_error(10);
    assert!(mean.abs() < 3e-6, "{mean}");
    assert!(rms < 60e-6, "{rms}");
    assert!(worst < 300e-6, "{worst}");
}

/// Mean, RMS and worst (g) of `a − input` over a noiseless run compensated with the exact
/// table, logged at `row_s`-s rows, after the estimator's warm-up.
fn exact_table_error(row_s: u32) -> (f64, f64, f64) {
    let mut truth = Truth::jb_kt8(1).noiseless();
    truth.sensor.offset_c = 0.0;
    truth.bias.b2_g_per_c2 = 0.0; // linear: the grid represents it exactly
    let p = ramps(1.0);
    let run = qfa_sim::simulate_run(&truth, &p, qfa_sim::profile::Position { run: 0, input_g: -1.0 }, row_s, 5);
    let nodes: Vec<f32> = (0..16).map(|i| truth.bias.at(-40.0 + 7.0 * f64::from(i) - T0_C) as f32).collect();
    let axis = qfa_thermal::AxisModel {
        scale: truth.scale,
        bias: qfa_thermal::BiasGrid::single_valued(-40.0, 7.0, &nodes).expect("2 to 16 grid values"),
        rate_limit_c_per_min: 3.0,
        ext: truth.ext,
    };
    let table = qfa_calibrate::fit::table_of(axis).unwrap();
    let c = compensate_run(&table, &run).unwrap();
    // Skip the estimator's warm-up (min_samples = 8 readings and a full 32-sample window).
    let warm_up = 40usize.div_ceil(row_s as usize);
    let err: Vec<f64> = c.accel_g[warm_up..].iter().map(|a| a + 1.0).collect();
    let worst = err.iter().map(|e| e.abs()).fold(0.0, f64::max);
    let rms = (err.iter().map(|e| e * e).sum::<f64>() / err.len() as f64).sqrt();
    let mean = err.iter().sum::<f64>() / err.len() as f64;
    println!(
        "{row_s}-s rows, a − input: mean {:.2} µg, RMS {:.2} µg, max {:.1} µg",
        mean * 1e6,
        rms * 1e6,
        worst * 1e6
    );
    (mean, rms, worst)
}

/// Noisy unit #1 on four short ramp programs: the held-out Table-4 sensitivity of the
/// hysteresis model is at least 4× below the simple model's and below 4 ppm/°C (pure
/// ramps turn around abruptly, the paper's dwell staircase does not: the demo measures
/// the real program), and the simple model is at least 3× below no compensation.
#[test]
fn held_out_hysteresis_beats_simple() {
    let truth = Truth::jb_kt8(1);
    let log = short_log(&truth, &[0.5, 0.8, 1.1, 1.5], 2, 11);
    let cal = calibrate_log(&log, &CalibrateOptions::default()).unwrap();
    let s = cal.report.sensitivity_ppm_per_c;
    println!(
        "held-out ppm/°C: none {:.2}, simple {:.2}, hysteresis {:.2}; bias µg {:?}",
        s.none, s.simple, s.hysteresis, cal.report.bias_residual_ug
    );
    assert!(cal.report.held_out);
    assert_eq!(cal.report.fit_programs, vec!["ramp-0.5".to_string(), "ramp-1.5".to_string()]);
    assert!(s.simple * 3.0 < s.none, "{s:?}");
    assert!(s.hysteresis * 4.0 < s.simple, "{s:?}");
    assert!(s.hysteresis < 4.0, "{s:?}");
    assert!(cal.report.bias_residual_ug.hysteresis < cal.report.bias_residual_ug.simple);
    // What is written is refitted on every program (the held-out ones too), with the
    // branch tie the fit programs chose; the held-out figures above are of the fit on two.
    let all: Vec<String> = ["ramp-0.5", "ramp-0.8", "ramp-1.1", "ramp-1.5"].map(String::from).to_vec();
    assert_eq!(cal.report.table_programs, all);
    assert!(cal.table.pairs > cal.fitted.pairs, "{} vs {}", cal.table.pairs, cal.fitted.pairs);
    assert_eq!(cal.table.branch.mode, cal.fitted.branch.mode);
    assert_ne!(cal.table.hysteresis, cal.fitted.hysteresis);
}

/// A bias model in the table's place is scored as the table is: given the table's own bias
/// grid, `bias_in_place` (the call the report's peers are scored by) reads the table's
/// held-out figure. Before, a bias-only peer was scored on each pair's measured
/// K0, so it was given the pair's own scale factor while the table's figure carried the
/// scale factor's run-to-run error: on the default simulated log the PX4 cubic read
/// 9.58 µg that way against the table's 9.68, and 9.68 in the table's place (on the
/// simulator's earlier run streams).
#[test]
fn a_bias_model_in_the_tables_place_is_scored_as_the_table_is() {
    let truth = Truth::jb_kt8(1);
    let log = short_log(&truth, &[0.5, 0.8, 1.1, 1.5], 2, 11);
    let cal = calibrate_log(&log, &CalibrateOptions::default()).unwrap();
    let paired = PairedLog::new(&log);
    let table = &cal.fitted.hysteresis;
    let grid = &table.axes[0].bias;
    let own = |t: f64, b: Branch| f64::from(grid.k0((t as f32).clamp(grid.t_start_c, grid.t_end_c()), b));
    let got = bias_in_place(&paired, &cal.report.eval_programs, table, &[&own]).unwrap();
    let want = cal.report.bias_residual_ug.hysteresis;
    println!("the table {want:.4} µg; its own grid in its place {:.4} µg", got[0]);
    // The table's compensator evaluates K0 at each 1-s reading, the model at the row's:
    // on 2-s rows the two differ by about a thousandth (1.1e-3 on this draw, under 1e-3 on
    // the simulator's earlier streams; the bound was set after seeing both). The scoring
    // this replaced was 1 % off, which the bound still refuses.
    assert!((got[0] - want).abs() < 3e-3 * want, "{} against {want}", got[0]);
}

/// Nothing held out says why in the log's own terms: a log of two programs with both named
/// as fit programs is not "one program" (it read so before), and a log of one program is.
#[test]
fn nothing_held_out_says_whether_the_log_has_one_program_or_all_were_fitted() {
    use qfa_report::verdict::Measured;
    let log = short_log(&Truth::jb_kt8(1), &[1.0, 1.5], 2, 5);
    let reason = |fit_programs: Vec<String>, log: &Log| {
        let opts = CalibrateOptions { fit_programs: Some(fit_programs), ..CalibrateOptions::default() };
        let cal = calibrate_log(log, &opts).expect("calibrates");
        assert!(!cal.report.held_out, "nothing is held out");
        match cal.report.held_out_table_figures().1 {
            Measured::NotComputed { not_computed } => not_computed,
            Measured::Value(v) => panic!("an in-sample figure given as held out: {v}"),
        }
    };
    let all = reason(log.programs(), &log);
    assert!(all.starts_with("every program of the log fitted"), "{all}");
    let mut one = log.clone();
    one.runs.retain(|r| r.program == "ramp-1");
    let only = reason(vec!["ramp-1".into()], &one);
    assert!(only.starts_with("one program only"), "{only}");
}
