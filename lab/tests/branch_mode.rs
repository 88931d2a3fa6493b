//! The cycling fit's bias-grid branch tie is the data's call (`calibrate::fit::fit`,
//! cross-validation with the one-SE rule): a unit whose truth has a heating/cooling bias
//! split (the root crate's `bias_branch_hysteresis`, a play operator of half-width 2 °C and
//! weight 20 µg: +20 µg heating, −20 µg cooling) must get a two-branch mode and recover the
//! split; a unit whose bias is single-valued (the JB-KT8 presets) must get `Single`. Two
//! seeds each. The same check run on a selector broken to "always Free" (or "always
//! Single") must fail, so the test can fail.
//!
//! Logs: the paper's program shape (30-min hold, 1 °C steps with 3-min dwells) at its two
//! fit rates, 0.3 and 0.9 °C/min, over −30…+50 °C, 2-s rows; the units carry the
//! simulator's full noise (white, 10 µg Gauss–Markov bias instability, DS18B20) and its
//! thermal chain. Not `recovery.rs`'s pure ramps at 0.5 and 1.5 °C/min: there the
//! accelerometer's interior lags the DS18B20 on the case enough that even a single-valued
//! bias splits by branch against the reading, and the cross-validation rightly keeps Free
//! (measured, seed 31, on the lab's earlier random streams: CV MSE Single 33.6 ± 7.8,
//! Offset 36.0 ± 7.8, Free 23.2 ± 4.8 µg²).

use qfa_calibrate::fit::{fit, BranchMode, FitOptions, Fitted};
use qfa_log::cycling::Log;
use qfa_sim::profile::{paper_positions, Program};
use qfa_sim::simulate;
use qfa_sim::truth::Truth;

/// The truth's half-step, g (`Truth::with_effect("bias_branch_hysteresis")`).
const PLAY_WEIGHT_G: f64 = 20e-6;

fn log_of(truth: &Truth, seed: u64) -> Log {
    let programs: Vec<Program> =
        [0.3, 0.9].iter().map(|&r| Program::staircase(&format!("steps-{r}"), r, 30.0, 3.0, -30, 50)).collect();
    simulate(truth, &programs, &paper_positions(), 2, seed, 2, None)
}

/// Half the mean heating − cooling difference over the grid's interior nodes, g.
fn half_split(f: &Fitted) -> f64 {
    let b = &f.hysteresis.axes[0].bias;
    let n = b.heating_g.len();
    let d: Vec<f64> = (1..n - 1).map(|i| f64::from(b.heating_g[i]) - f64::from(b.cooling_g[i])).collect();
    0.5 * d.iter().sum::<f64>() / d.len() as f64
}

/// The check. Hysteretic: a two-branch mode, and the split within 30 % of the truth's
/// (the 4 °C play transition after each turnaround, on 80 °C ramps, and the bias
/// instability pull it down by a few %; 30 % chosen before the first run). Single-valued:
/// `Single`, so both branches are the same curve.
fn check(f: &Fitted, hysteretic: bool) -> Result<(), String> {
    let m = f.branch.mode;
    let h = half_split(f);
    if hysteretic {
        if m == BranchMode::Single {
            return Err(format!("hysteretic unit got Single ({:?})", f.branch.candidates));
        }
        if (h - PLAY_WEIGHT_G).abs() > 0.3 * PLAY_WEIGHT_G {
            return Err(format!("half-split {:.2} µg vs truth 20 µg", h * 1e6));
        }
    } else if m != BranchMode::Single {
        return Err(format!("single-valued unit got {m:?} ({:?})", f.branch.candidates));
    }
    Ok(())
}

fn fitted(hysteretic: bool, seed: u64, forced: Option<BranchMode>) -> Fitted {
    let mut truth = Truth::jb_kt8(1);
    if hysteretic {
        truth = truth.with_effect("bias_branch_hysteresis").unwrap();
    }
    let log = log_of(&truth, seed);
    let mut opts = FitOptions::new(log.programs());
    opts.branch_mode = forced;
    let f = fit(&qfa_log::pairing::PairedLog::new(&log), &opts, None).unwrap();
    let c: Vec<String> = f
        .branch
        .candidates
        .iter()
        .map(|c| format!("{:?} {:.2}±{:.2} µg²", c.mode, c.cv_mse_ug2, c.cv_se_ug2))
        .collect();
    println!(
        "hysteretic {hysteretic}, seed {seed}, forced {forced:?}: {:?}, half-split {:.2} µg; CV {}",
        f.branch.mode,
        half_split(&f) * 1e6,
        c.join(", ")
    );
    f
}

#[test]
fn hysteretic_units_get_two_branches_and_single_valued_units_one() {
    for seed in [31, 32] {
        check(&fitted(true, seed, None), true).unwrap();
        check(&fitted(false, seed, None), false).unwrap();
    }
}

#[test]
fn a_broken_selector_fails_the_check() {
    // Always Free: the single-valued unit gets two noisy branches.
    assert!(check(&fitted(false, 31, Some(BranchMode::Free)), false).is_err());
    // Always Single: the hysteretic unit loses its split.
    assert!(check(&fitted(true, 31, Some(BranchMode::Single)), true).is_err());
}
