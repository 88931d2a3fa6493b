//! The discovery report's records: what `report.json` holds.

use super::*;

/// Start model.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Start {
    /// K1 and K0 linear in ΔT (paper Eq. 3–4).
    Simple,
    /// Eq. 11 scale factor, single-valued smooth bias.
    Paper,
}

impl std::str::FromStr for Start {
    type Err = DiscoverError;
    fn from_str(s: &str) -> Result<Self> {
        match s {
            "simple" => Ok(Start::Simple),
            "paper" => Ok(Start::Paper),
            _ => Err(DiscoverError::UnknownStart(s.to_string())),
        }
    }
}

impl Start {
    /// Name as in the CLI and report.
    #[must_use]
    pub(crate) fn name(self) -> &'static str {
        match self {
            Start::Simple => "simple",
            Start::Paper => "paper",
        }
    }
}

/// A fitted parameter with its 95 % confidence interval.
#[derive(Clone, Debug, Serialize)]
pub struct ParamCi {
    /// Estimate (fit on all data).
    pub value: f64,
    /// 95 % interval.
    pub ci95: [f64; 2],
    /// The estimate sits at a search limit (the limit, not the data, decided it).
    pub at_bound: bool,
    /// How the interval was formed.
    pub method: String,
}

/// An effect added by the workflow.
#[derive(Clone, Debug, Serialize)]
pub struct EffectReport {
    /// Catalog name.
    pub name: String,
    /// `scale_factor`, `bias` or `both`.
    pub channel: String,
    /// Fitted parameters (from the fit on all data).
    pub params: std::collections::BTreeMap<String, f64>,
    /// The same parameters with 95 % intervals and the search-limit flag.
    pub params_ci: std::collections::BTreeMap<String, ParamCi>,
    /// Held-out gain when it was added, with its block-bootstrap uncertainty.
    pub gain: GainStat,
    /// Whether the flashed table (`table.bin`) carries it (`bias_drift` has no root-crate
    /// slot yet: reported, not flashed).
    pub in_table: bool,
    /// Why `table.bin` does not carry it, when it does not.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_in_table: Option<String>,
    /// Significant candidates it did not beat by one standard error (one-SE rule: the
    /// one with fewest parameters was added); empty when the name is clear.
    pub confusable_with: Vec<String>,
    /// Held-out gap of its channel before it was added (for `both`: the channel it
    /// improved more, relative to its held-out RMS).
    pub heldout_gap_before: f64,
    /// The same gap after.
    pub heldout_gap_after: f64,
}

/// Held-out gaps: RMS residuals.
#[derive(Clone, Debug, Serialize, PartialEq)]
#[serde(untagged)]
pub enum Gaps {
    /// Cycling log.
    Cycling {
        /// Scale factor, ppm.
        scale_factor_ppm: f64,
        /// Bias, µg.
        bias_ug: f64,
    },
    /// Single-channel log, value units.
    Single {
        /// RMS of the value residual.
        value_rms: f64,
    },
}

/// A localized disagreement.
#[derive(Clone, Debug, Serialize)]
pub struct Where {
    /// Channel.
    pub channel: String,
    /// Human-readable segment.
    pub segment: String,
    /// Held-out RMS there (ppm, µg or value units).
    pub rms: f64,
}

/// One candidate tried in one round.
#[derive(Clone, Debug, Serialize)]
pub struct CandidateTrial {
    /// Catalog name.
    pub name: String,
    /// Channel.
    pub channel: String,
    /// Held-out gain and its block test, on the residuals whitened by the fitted noise
    /// model.
    pub gain: GainStat,
    /// The same gain on the residuals themselves, and its block test at the uncorrected
    /// level: the improvement must also show in the held-out residual a user sees.
    pub raw_gain: GainStat,
    /// The effect's own weight against its block-bootstrap standard error, on all bins
    /// (tested only after the block test passed; `None` for a lag, which has no weight).
    pub weight: Option<WeightZ>,
    /// Passed the block test, and the weight test where there is one.
    pub significant: bool,
    /// Parameters at a search limit (`name=value`); such a candidate is not added.
    pub at_bound: Vec<String>,
    /// Held-out gaps with it.
    pub gaps: Gaps,
}

/// A candidate's own weight (drift rate, play weight, Eq. 11 term) against its
/// moving-block bootstrap standard error.
#[derive(Clone, Debug, Serialize)]
pub struct WeightZ {
    /// Parameter name.
    pub param: String,
    /// Fitted value on all bins, the other nonlinear parameters as in the first fold.
    pub value: f64,
    /// Moving-block bootstrap standard error.
    pub se: f64,
    /// |value| / se.
    pub z: f64,
}

/// A peer (what users pick today) on the report's own held-out split, bias channel: per
/// fold fitted on the training bins (bin means of the raw temperature reading and of the
/// bias or value) and scored on the held-out bins, as the model's gaps are.
#[derive(Clone, Debug, Serialize)]
pub struct PeerGap {
    /// Peer name.
    pub peer: String,
    /// Held-out RMS of the bias channel (µg for a cycling log, value units for a
    /// single-channel log); absent when the peer could not be fitted (then `error` says why).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heldout_rms: Option<f64>,
    /// Why no figure could be formed.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub error: Option<String>,
}

/// What `table.bin` holds.
#[derive(Clone, Debug, Serialize)]
pub struct Flashed {
    /// `named model` or `start model`: whichever predicts better held out (Σ over
    /// channels of (held-out RMS / noise floor)²).
    pub model: String,
    /// Its held-out gaps; absent when none can be formed (`not_computed` says why).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub heldout: Option<Gaps>,
    /// Why it has no held-out figure, when it has none.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub not_computed: Option<String>,
    /// A peer whose bias figure on the same folds beats it (a cycling table needs a
    /// scale-factor model, which the peers have not, so it is not flashed: said instead).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub peer_better: Option<PeerBetter>,
}

/// A peer that predicts the bias better than the flashed model, held out.
#[derive(Clone, Debug, Serialize)]
pub struct PeerBetter {
    /// Peer name.
    pub peer: String,
    /// Its held-out RMS of the bias (µg, or the log's value unit).
    pub heldout_rms: f64,
}

/// The timing offset a discovery fitted (see `super::fit::TimingOffset`).
#[derive(Clone, Copy, Debug, Serialize, PartialEq)]
pub struct TimingOffsetReport {
    /// δ, s: the counts at time t follow the temperature stamped t + δ.
    pub seconds: f64,
    /// 95 % interval (the fit's SE widened by the residual's variance inflation N/N_eff).
    pub ci95: [f64; 2],
    /// The largest |δ| a fit may take (1.5 rows, at least 2 s), s.
    pub limit_s: f64,
    /// δ sits at the limit: the delay is longer than a timestamp convention.
    pub at_limit: bool,
    /// A scale-factor level by ramp branch is left unexplained (`unexplained[].branch_level`):
    /// δ took that level's share on the ramps, so it is not the log's timing alone (a
    /// 9.9-ppm hysteresis moved it from +11.1 to −1.3 s).
    pub shares_a_branch_level: bool,
}

/// The discovery report; `report.json` is its serialization.
#[derive(Clone, Debug, Serialize)]
pub struct Report {
    /// Start model.
    pub start: Start,
    /// Effects added, in order.
    pub effects: Vec<EffectReport>,
    /// Held-out gaps of the start model.
    pub heldout_gap_before: Gaps,
    /// Held-out gaps of the final model.
    pub heldout_gap_after: Gaps,
    /// Where the start model disagrees most (held out).
    #[serde(rename = "where")]
    pub where_: Vec<Where>,
    /// Structure left in the final held-out residual that no catalog effect explains.
    pub unexplained: Vec<Unexplained>,
    /// Each channel's final held-out residual against its noise floor (the test that
    /// reports structure left even when no driver explains it).
    pub residual_vs_floor: Vec<FloorRatio>,
    /// The timing offset between the temperature channel and the counts, fitted with every
    /// model as a nuisance (cycling logs only; see `super::fit::TimingOffset`).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub timing_offset: Option<TimingOffsetReport>,
    /// Each series' fitted noise model and its tests (`super::noise`): the channels in the
    /// order of `residual_vs_floor`, then, on a cycling log, each position's reading;
    /// `series` names each.
    pub noise: Vec<super::noise::NoiseTest>,
    /// Noise floors of the final held-out residual (the bin-to-bin noise of each
    /// channel's noise model, √(W + Q(1 − φ))).
    pub noise_floor: Gaps,
    /// Peers on the same held-out split, bias channel (cycling logs: the bias channel
    /// only; the peers have no scale-factor model).
    pub peers: Vec<PeerGap>,
    /// The selection rule, in words.
    pub selection_rule: String,
    /// Every candidate of every round (for the Markdown report).
    #[serde(skip)]
    pub rounds: Vec<Vec<CandidateTrial>>,
    /// Where the final model disagrees most.
    #[serde(skip)]
    pub where_after: Vec<Where>,
    /// The model flashed (`table.bin`): the named model, or the start model when that
    /// predicts better held out.
    #[serde(skip)]
    pub model: Option<AxisModel>,
    /// Which model is flashed, its held-out figure, and a peer that predicts the bias
    /// better, if any.
    pub flashed: Flashed,
    /// A cycling log's table: `calibrate`'s, with the catalog's slots that carry to
    /// held-out programs ([`crate::cycling_table`]); `None` for a single-channel log, whose
    /// table is the catalog's model.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub table: Option<crate::cycling_table::CyclingTable>,
    /// The extension slots of the catalog's named model (fitted on every bin).
    #[serde(skip)]
    pub named_ext: qfa_thermal::Extensions,
    /// Held-out residuals before and after.
    #[serde(skip)]
    pub residuals: (Residuals, Residuals),
    /// The held-out rule applied.
    #[serde(skip)]
    pub heldout_rule: String,
}

impl Report {
    /// Added effects as `name (channel)`: `temp_quadratic` can be added once per channel,
    /// and a summary must say which.
    #[must_use]
    pub fn effect_labels(&self) -> Vec<String> {
        self.effects
            .iter()
            .map(|e| {
                if e.confusable_with.is_empty() {
                    format!("{} ({})", e.name, e.channel)
                } else {
                    format!("{} ({}; not identified: as good as {})", e.name, e.channel, e.confusable_with.join(", "))
                }
            })
            .collect()
    }
}

impl EffectReport {
    /// Each parameter as `name = value [low, high]`, followed by `limit_mark` when it sits at
    /// a search limit.
    #[must_use]
    pub(crate) fn params_text(&self, limit_mark: &str) -> Vec<String> {
        self.params_ci
            .iter()
            .map(|(k, c)| {
                format!(
                    "{k} = {:.4e} [{:.3e}, {:.3e}]{}",
                    c.value,
                    c.ci95[0],
                    c.ci95[1],
                    if c.at_bound { limit_mark } else { "" }
                )
            })
            .collect()
    }
}
