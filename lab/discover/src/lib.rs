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
//! 3. **Held-out rule** (`folds`; every figure of merit is held out): a cycling log's
//!    programs dealt by ramp rate into two folds, each fitted on the other; one program or
//!    a single-channel log, 20-min time blocks dealt alternately. Nonlinear parameters are
//!    searched on the training fold only.
//! 4. **Localization** (`localize`): RMS of the held-out residual by heating / cooling
//!    ramps × program rate × temperature band, and holds by time since the last change.
//! 5. **Candidates** (`search`, `optimize`): each catalog effect not yet in the model,
//!    every trial scored by running the root crate's `AxisModel::evaluate`.
//! 6. **Selection** (`stats`, `noise`, `select`): a candidate is added when its held-out
//!    gain passes a block test on residuals whitened by their fitted noise model
//!    (Bonferroni over the catalog's 9 effects, every round), the same gain passes on the
//!    unwhitened residuals, and its weight clears a bootstrap test; a parameter at a
//!    search limit is reported, not added; among the rest the one-SE rule picks the
//!    fewest parameters, and a backward step drops what a later addition made redundant.
//!    The rule in full is docs/lab.md, "Discovery"; its false-discovery rate,
//!    docs/measurements.md, "Lab: discovery" (`tests/discover_fdr.rs`).
//! 7. **Uncertainty** (`uncertainty`): block-bootstrap SEs and 95 % intervals of each
//!    gain and linear weight, profile intervals of the nonlinear parameters, `at_bound`.
//! 8. **Unexplained** (`unexplained`): each channel's final held-out residual against its
//!    noise floor (`noise`), change points, drivers it follows, run levels and pinned
//!    catalog effects, reported with where in time they live, not given a name.
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
//! The catalog's `bias_drift` has no root-crate slot yet, so it is reported but not
//! flashed (`in_table: false`). What the catalog leaves out on purpose (a thermal-gradient
//! term in Ṫ, a second lag stage), and why, is in docs/lab.md, "Discovery".

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
