//! Discovery workflow: find where the model and a thermal-test log disagree,
//! name the missing physical effect from the catalog, add it in the form the firmware
//! runs (a root-crate extension slot or Eq. 11 term), and show on held-out data that the
//! gap shrank. Says `none` when nothing significant is missing.
//!
//! # Workflow
//! 1. **Channels** ([`qfa_log::channels`]): pair the ±1 g runs of each program by time,
//!    `K1 = (A₊ − A₋)/2`, `K0 = (A₊ + A₋)/(2·K1)`, average into 60-s bins; T and Ṫ come
//!    from the firmware's view of the mean of the two runs' readings
//!    ([`qfa_log::replay`], the one calibration and `compensate` take: the 1-s readings
//!    filled in between rows, a cycling row seen at the middle of its counting interval). A
//!    single-channel log `time_s,temp_c,value` is the bias channel.
//! 2. **Start model** ([`Start`]): `simple` = K1 and K0 linear in ΔT (Eq. 3–4, the bias
//!    on a 16-point grid with equal branches); `paper` = Eq. 11 and a single-valued bias
//!    grid fitted by least squares with a gentle smoothness penalty. On a cycling log
//!    whose model has no ε·Ṫ, every fit also takes a timing offset δ between the
//!    temperature channel and the counts (`fit::TimingOffset`): held while a round's
//!    candidates are scored, reported with its interval.
//! 3. **Held-out rule** (every figure of merit is held out): a cycling log's programs are
//!    sorted by ramp rate and dealt alternately into two folds (0.3/0.7 and 0.5/0.9 °C/min
//!    for the paper's test); each fold is fitted on the other and evaluated on itself,
//!    so each bin's residual comes from a model that never saw its program. With one
//!    program, or a single-channel log, each trace is cut into 20-bin (20-min) time blocks
//!    dealt alternately into the two folds (interleaved blocks: every fold sees heating,
//!    cooling and holds at every temperature). Model states always run through the whole
//!    trace; only the fit skips the held-out bins. Nonlinear parameters are searched on
//!    the training fold only, weighted by each channel's bin-to-bin noise floor.
//! 4. **Localization** (`localize`): RMS of the held-out residual by heating / cooling
//!    ramps × program rate × temperature band, and holds by time since the last change.
//! 5. **Candidates**: each catalog effect not yet in the model. Nonlinear parameters by a
//!    coarse log-grid then golden section (τ, r; 20 steps) or Nelder–Mead (creep τ_ref,
//!    E; T_ref fixed at 22 °C); linear coefficients re-fitted by least squares for every
//!    trial; every trial scored by running the root crate's `AxisModel::evaluate`.
//! 6. **Selection** (`stats`, `noise`): both held-out residuals, before and after the
//!    candidate, are whitened by the noise model fitted to the one after (white plus
//!    Gauss–Markov is ARMA(1, 1); its innovations, clipped at 4 SD). The per-bin gain
//!    (drop of (residual/RMS)², summed over the channels) is summed over blocks of
//!    consecutive bins, four times the whitened residual's 1/e autocorrelation lag long
//!    (≥ 10 bins, ≥ 8 blocks). A candidate is significant when that gain exceeds
//!    t(1 − 0.05/m, blocks − 1) standard errors of the block sums (m = 9, the catalog's
//!    size, in every round: Bonferroni over everything the workflow could add), and
//!    when the same gain on the unwhitened residuals (blocks from their own
//!    autocorrelation) passes the same test at the uncorrected level 0.05: the
//!    improvement must show in the residual a user sees, not only in its fast part. An
//!    effect with a weight of its own (drift rate, play weight, Eq. 11 term) must also
//!    clear its weight test (`WeightZ`: |weight| > z(1 − 0.05/(2m)) moving-block
//!    bootstrap SEs, held-out residuals resampled, nonlinear parameters searched again
//!    per resample). A significant candidate with a parameter at a search limit is
//!    not added (a limit, not the data, decided it); it is reported. Among the rest the
//!    largest gain is best, and by the one-standard-error rule the candidate with fewest
//!    parameters whose gain is within one SE of the best's is added; the others are
//!    listed as `confusable_with` (name not identified). After the last round a
//!    backward step drops any added effect whose removal the block test does not reject
//!    (a simpler effect picked by the one-SE rule, made redundant by a later addition). Repeat until none is
//!    left, then re-optimise the nonlinear parameters jointly (cyclic search). Measured
//!    false-discovery rate on clean simulator logs: docs/measurements.md ("Lab: discovery") and
//!    `tests/discover_fdr.rs`.
//! 7. **Uncertainty**: each added effect's gain carries a block-bootstrap SE and 95 %
//!    interval; nonlinear parameters a profile interval (all-data Σ(residual/RMS)² rising
//!    by 3.84·N/N_eff, N/N_eff from the residual autocorrelation), linear ones a
//!    moving-block bootstrap interval; `at_bound` flags a search limit.
//! 8. **Unexplained** (`unexplained`): each channel's final held-out residual against its
//!    noise floor, the bin-to-bin noise of the model fitted to it (`noise`: white plus
//!    Gauss–Markov, robust to glitches and steps; always reported); a change point inside a
//!    run that the fitted model rejects; drivers it follows significantly (cross-fitted on
//!    time since start, temperature, Ṫ, time since the last reversal and the ramp branch,
//!    same block test, level 0.05 shared over drivers and channels), run means that differ
//!    beyond noise and slow noise, and catalog effects pinned at a search limit are
//!    reported as `unexplained`, with where in time they live, not given a name.
//! 9. **Flashed** ([`Flashed`]): on a cycling log, the table `calibrate` writes for the
//!    same log with the catalog's slots that carry to held-out programs
//!    ([`cycling_table`]: one table for one log, named as its structure); on a
//!    single-channel log, the named model, or the start model when that predicts better
//!    held out. A peer that predicts the bias better is named in the report.
//!
//! 10. **Peers** ([`PeerGap`]): the PX4/tofupilot cubic, ArduPilot TCAL and the paper's
//!     simple model ([`qfa_calibrate::peers`]) on the same folds, bias channel only, so
//!     every report shows what the discovered model is worth against what users pick.
//!
//! A static multi-axis log goes through [`static_axes`]: each axis a single-channel log,
//! on static calibration's split (fit up to the temperature maximum, hold out the rest).
//! There the model is named by static calibration's one search (so what is named is what
//! `table.bin` holds), and the steps above identify its parts, say what it does not hold,
//! what is left, and where.
//!
//! The catalog's `bias_drift` (bias linear in time since the program start: ageing or a
//! long turn-on settling) has no root-crate slot yet, so it is reported but not flashed
//! (`in_table: false`). Left out of the catalog, on purpose: a thermal-gradient
//! term in Ṫ on the bias (on the paper's test Ṫ is the same program signal that
//! `sensor_lag` and, on the scale factor, `rate_hysteresis` already use: ε·Ṫ and a lag's
//! −τ·Ṫ·∂b/∂T cannot be told apart without a second sensor or a gradient that changes
//! sign independently of Ṫ), and a second lag stage (two stages τ₁, τ₂ give a response
//! within a fraction of the noise of one stage with τ₁ + τ₂ on 0.3–0.9 °C/min ramps with
//! 3-min dwells; the out-of-catalog test confirms a two-stage lag is named as one lag
//! with the effective τ).

pub(crate) mod cli;
pub mod cycling_table;
pub(crate) mod error;
pub mod fit;
mod folds;
mod heldout;
mod localize;
pub(crate) mod noise;
mod optimize;
pub(crate) mod output;
pub(crate) mod page;
mod params;
pub(crate) mod report;
mod search;
pub(crate) mod select;
pub mod static_axes;
pub(crate) mod stats;
pub(crate) mod structure;
mod uncertainty;
pub(crate) mod unexplained;
pub(crate) mod verdict;

use std::path::Path;

use qfa_thermal::model::AxisModel;
use serde::Serialize;

pub use cli::{analyze_source, demo_hook, discover, discover_with_verdict, Source};
pub use error::DiscoverError;
use fit::{Fitted, Residuals, Setup};
use folds::*;
use heldout::*;
pub(crate) use localize::localize;
use optimize::{golden, nelder_mead2};
use params::*;
pub use qfa_log::channels::Channels;
pub(crate) use qfa_log::channels::{BiasUnit, LogKind};
pub(crate) use report::{CandidateTrial, ParamCi, WeightZ};
pub use report::{EffectReport, Flashed, Gaps, PeerBetter, PeerGap, Report, Start, TimingOffsetReport, Where};
use search::*;
pub use select::analyze;
pub(crate) use select::{start_model, ALPHA};
pub(crate) use stats::GainStat;
pub(crate) use structure::Effect;
use structure::{Nonlinear, Structure};
use uncertainty::*;
pub(crate) use unexplained::{FloorRatio, Unexplained};

use qfa_calibrate::metrics::rms_of_finite as rms;

/// What discovery's fallible steps return: a [`DiscoverError`] unless they name another.
type Result<T, E = DiscoverError> = std::result::Result<T, E>;

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn at_bound_flags_each_search_limit_and_nothing_inside() {
        // Limits from the search grids (30..3840 s, 0.15..20 °C, 1..1e6 s, E ≤ 20 000 K).
        let lag = |t: f32| at_bound(Effect::SensorLag, &Nonlinear { lag_tau_s: Some(t), ..Default::default() });
        assert_eq!(lag(3840.0), ["tau_s=3840"]);
        assert_eq!(lag(30.2), ["tau_s=30"]);
        assert!(lag(500.0).is_empty() && lag(3500.0).is_empty());
        let play =
            |r: f32| at_bound(Effect::BiasBranchHysteresis, &Nonlinear { play_r_c: Some(r), ..Default::default() });
        assert_eq!(play(20.0), ["half_width_c=20.00"]);
        assert_eq!(play(0.15), ["half_width_c=0.15"]);
        assert!(play(2.0).is_empty());
        let creep =
            |t: f32, e: f32| at_bound(Effect::BiasCreep, &Nonlinear { creep: Some((t, e)), ..Default::default() });
        assert_eq!(creep(1e6, 20_000.0), ["tau_ref_s=1000000", "activation_k=20000"]);
        // E = 0 is physical (no thermal activation), not a search limit.
        assert!(creep(3000.0, 0.0).is_empty());
    }
}
