//! The firmware's view of a log's temperatures: the readings it takes, and what its rate
//! estimator makes of them. Calibration's fit, discovery's channels and the compensation of
//! a log all take their readings from here, so they see one T̂, one Ṫ and one branch.
//!
//! - **One rounding.** A reading is `raw = round_ties_even(16·T)`, clamped to `i16`. Ties
//!   matter: a cycling row's temperature can be the mean of two runs' readings, half a code,
//!   and rounding ties away from zero would move every such tie up above 0 °C and down below
//!   it, a step of up to 1/32 °C at 0 °C (a scale-factor curvature of 0.9 ppm at the span's
//!   ends on 12 of 40 clean logs of the second independent generator).
//! - **One reading a second.** The firmware reads its DS18B20 every
//!   [`READING_PERIOD_S`] and its estimator's window is [`RATE_WINDOW`] readings. A log may
//!   keep fewer rows: at 10-s rows the same window would span 320 s and bend every ramp
//!   corner into a temperature error that a rate term then absorbs (a phantom ε of several
//!   ppm on a lag log with no rate term). So when rows are more than [`FILL_FROM_S`] apart
//!   (and within the estimator's gap limit, beyond which the firmware restarts its window
//!   anyway), the readings the firmware would have taken between them are filled in at 1 s,
//!   linear in raw between the two rows' readings, ties to even.
//! - **One instant per row.** A row that counts pulses over the interval ending at its time
//!   ([`RowInstant::IntervalCentre`], a cycling log) is seen at the filled reading at its
//!   interval's centre; a row that is one sample ([`RowInstant::OwnReading`]) at its own
//!   reading.

use qfa_thermal::model::Branch;
use qfa_thermal::rate::{Accepted, Estimate, RateConfig, RateEstimator};

/// Rate-estimator window of every lab table (`Table::rate_window`).
pub const RATE_WINDOW: usize = qfa_thermal::DEFAULT_RATE_WINDOW;

/// The firmware's sensor period, s (`Config::default().sample_period_ms`).
pub const READING_PERIOD_S: f64 = 1.0;

/// Rows further apart than this (s) get the firmware's readings filled in between them.
pub const FILL_FROM_S: f64 = 1.5;

/// Branch deadband the lab writes into its tables, °C/min: the firmware's flicker floor
/// for [`RATE_WINDOW`] at its default 1 s sample period
/// ([`qfa_thermal::rate::flicker_deadband_c_per_min`], 0.182 °C/min), so the fit traces
/// the branch exactly as the compensator will switch it.
#[must_use]
pub fn branch_deadband_c_per_min() -> f32 {
    qfa_thermal::rate::flicker_deadband_c_per_min(RATE_WINDOW, qfa_thermal::Config::default().sample_period_ms)
}

/// Heating, cooling or holding: the lab's one classifier, the comparison of
/// `Branch::next` (past the threshold one way or the other, else the branch held). It
/// answers two questions, each with its threshold:
/// - **which branch the table is read on** ([`Motion::of`]): the firmware's deadband
///   ([`branch_deadband_c_per_min`]); calibration's rows, coverage and the change-point
///   search's corners take it;
/// - **which way the temperature moves** ([`Motion::direction`]): [`DIRECTION_C_PER_MIN`],
///   for discovery's drivers and the words of its localizer and residual file. A unit's
///   hysteresis turns with its temperature, not with the firmware's deadband, which is
///   the flicker floor of a 32-s estimator on 1/16-°C codes: on the second generator's
///   clean draw 33 with a ±4-ppm scale-factor hysteresis, discovery's level by branch read
///   2.2 ppm (z 6.9) by the direction and was not found by the deadband.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Motion {
    /// Ṫ above the deadband.
    Heating,
    /// Ṫ below minus the deadband.
    Cooling,
    /// Within it.
    Holding,
}

impl Motion {
    /// Which way the temperature moves at `rate_c_per_min` (see the type's docs).
    #[must_use]
    pub fn direction(rate_c_per_min: f64) -> Self {
        Self::against(rate_c_per_min, DIRECTION_C_PER_MIN)
    }

    /// The motion of `rate_c_per_min` against the lab's deadband: the table's branch.
    #[must_use]
    pub fn of(rate_c_per_min: f64) -> Self {
        Self::against(rate_c_per_min, f64::from(branch_deadband_c_per_min()))
    }

    /// The motion of `rate_c_per_min` against a table's own `deadband` (°C/min).
    #[must_use]
    pub fn against(rate_c_per_min: f64, deadband: f64) -> Self {
        if rate_c_per_min > deadband {
            Self::Heating
        } else if rate_c_per_min < -deadband {
            Self::Cooling
        } else {
            Self::Holding
        }
    }

    /// +1 heating, −1 cooling, 0 holding.
    #[must_use]
    pub fn sign(self) -> i8 {
        match self {
            Self::Heating => 1,
            Self::Cooling => -1,
            Self::Holding => 0,
        }
    }
}

/// A temperature moving faster than this, °C/min, is heating or cooling (see [`Motion`]):
/// a ramp against a dwell in the temperature's own motion.
pub const DIRECTION_C_PER_MIN: f64 = 0.05;

/// The estimator configuration of every replay: the firmware's default.
#[must_use]
pub fn rate_config() -> RateConfig {
    RateConfig::default()
}

/// A reading as the DS18B20 reports it, 1/16 °C: ties to even, clamped to `i16`.
#[must_use]
pub fn raw_reading(temp_c: f64) -> i16 {
    (temp_c * 16.0).round_ties_even().clamp(-32768.0, 32767.0) as i16
}

/// A row time as the firmware's millisecond clock (wrapping, as on target).
#[must_use]
pub fn clock_ms(time_s: f64) -> u32 {
    (time_s * 1000.0).round() as i64 as u32
}

/// Which reading of a row stands for the row.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowInstant {
    /// The row is one sample at its time (a static or single-channel log).
    OwnReading,
    /// The row counts over the interval that ends at its time (a cycling log's pulses): the
    /// filled reading at the interval's centre stands for it, its own when none was filled.
    IntervalCentre,
}

/// One reading the firmware takes.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Reading {
    /// The firmware's clock, ms.
    pub clock_ms: u32,
    /// DS18B20 raw, 1/16 °C.
    pub raw: i16,
    /// The row's own reading (else one filled in before it).
    pub own: bool,
    /// The state after this reading is the row's view.
    pub stands_for_row: bool,
}

/// The readings of a log's rows, one row at a time.
#[derive(Clone, Debug, Default)]
pub struct Readings {
    /// The previous row with a reading: its time (s) and raw reading.
    prev: Option<(f64, i16)>,
}

impl Readings {
    /// Before the first row.
    #[must_use]
    pub fn new() -> Self {
        Self::default()
    }

    /// The readings of the row at `time_s` with reading `temp_c` (none: the row has no
    /// reading), in time order, into `out` (cleared first): the filled ones, then its own.
    pub fn row(&mut self, time_s: f64, temp_c: Option<f64>, instant: RowInstant, out: &mut Vec<Reading>) {
        out.clear();
        let Some(temp) = temp_c else { return };
        let raw = raw_reading(temp);
        let mut centre_marked = false;
        if let Some((tp, rp)) = self.prev {
            let gap = time_s - tp;
            if gap > FILL_FROM_S && gap * 1000.0 <= f64::from(rate_config().max_gap_ms) {
                let mid = (gap / 2.0).round().max(1.0);
                let mut k = 1.0;
                while k < gap - 0.5 {
                    let x = f64::from(rp) + (f64::from(raw) - f64::from(rp)) * k / gap;
                    let centre = instant == RowInstant::IntervalCentre && k == mid;
                    centre_marked |= centre;
                    out.push(Reading {
                        clock_ms: clock_ms(tp + k * READING_PERIOD_S),
                        raw: x.round_ties_even() as i16,
                        own: false,
                        stands_for_row: centre,
                    });
                    k += 1.0;
                }
            }
        }
        out.push(Reading { clock_ms: clock_ms(time_s), raw, own: true, stands_for_row: !centre_marked });
        self.prev = Some((time_s, raw));
    }
}

/// What the firmware's estimator made of one reading it accepted.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Seen {
    /// The reading.
    pub reading: Reading,
    /// The estimator's T̂ (°C) and Ṫ (°C/min) after it.
    pub estimate: Estimate,
    /// Seconds since the previous accepted reading (0 for the first), as the firmware's
    /// slow path passes them to `AxisModel::evaluate`.
    pub dt_s: f32,
    /// The firmware's bias branch after it: `Branch::next` with the view's deadband on
    /// every reading.
    pub branch: Branch,
}

/// The firmware's rate estimator fed a log's readings: the one place the lab constructs it.
#[derive(Clone, Debug)]
pub struct FirmwareView {
    readings: Readings,
    est: RateEstimator<RATE_WINDOW>,
    last_ms: Option<u32>,
    branch: Branch,
    deadband: f32,
    buf: Vec<Reading>,
}

impl Default for FirmwareView {
    fn default() -> Self {
        Self::new()
    }
}

/// How a row fared.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum RowSeen {
    /// The row has no reading.
    NoReading,
    /// Its own reading was refused (time not after the previous reading's, as on target).
    Refused,
    /// Its own reading was accepted.
    Accepted,
}

impl FirmwareView {
    /// A fresh power-up, with the lab's branch deadband.
    #[must_use]
    pub fn new() -> Self {
        Self::with_deadband(branch_deadband_c_per_min())
    }

    /// A fresh power-up whose branch switches past `deadband` (°C/min): a table's own.
    #[must_use]
    pub fn with_deadband(deadband: f32) -> Self {
        Self {
            readings: Readings::new(),
            est: RateEstimator::new(rate_config()),
            last_ms: None,
            branch: Branch::Unknown,
            deadband,
            buf: Vec::with_capacity(32),
        }
    }

    /// Feed the row's readings (see [`Readings::row`]), calling `each` on every one the
    /// estimator accepted, in time order.
    pub fn row(
        &mut self,
        time_s: f64,
        temp_c: Option<f64>,
        instant: RowInstant,
        mut each: impl FnMut(&Seen),
    ) -> RowSeen {
        let mut buf = std::mem::take(&mut self.buf);
        self.readings.row(time_s, temp_c, instant, &mut buf);
        let mut seen = if buf.is_empty() { RowSeen::NoReading } else { RowSeen::Refused };
        for &reading in &buf {
            let accepted: Result<Accepted, _> = self.est.push(reading.clock_ms, reading.raw);
            if accepted.is_err() {
                continue;
            }
            if reading.own {
                seen = RowSeen::Accepted;
            }
            let dt_s = self.last_ms.map_or(0.0, |p| reading.clock_ms.wrapping_sub(p) as f32 * 1e-3);
            self.last_ms = Some(reading.clock_ms);
            let estimate = self.est.estimate().expect("a reading was just accepted");
            // The firmware's deadband: the table's, at least the window's floor as filled now.
            let deadband = self.deadband.max(self.est.flicker_floor(self.deadband));
            self.branch = self.branch.next(estimate.rate_c_per_min, deadband);
            each(&Seen { reading, estimate, dt_s, branch: self.branch });
        }
        self.buf = buf;
        seen
    }
}

/// The firmware's state after one reading it accepted, as a row keeps it.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct ReadingState {
    /// The firmware's clock at the reading, ms.
    pub clock_ms: u32,
    /// The reading, 1/16 °C.
    pub raw: i16,
    /// The estimator's T̂ (°C) and Ṫ (°C/min) after it.
    pub estimate: Estimate,
    /// The bias branch after it.
    pub branch: Branch,
}

/// What the firmware made of one row's readings.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowView {
    /// How the row's own reading fared.
    pub seen: RowSeen,
    /// The state after the reading that stands for the row ([`RowInstant`]), when the
    /// estimator accepted it.
    pub standing: Option<ReadingState>,
    /// The state after the row's own reading, when the estimator accepted it.
    pub own: Option<ReadingState>,
    /// The branch after the row's last accepted reading (none when it accepted none).
    pub branch_after: Option<Branch>,
}

/// The firmware's view of a whole log, row by row: its readings replayed through the
/// estimator and the branch once, so that every model a fit or a search tries is evaluated
/// over the same rows without replaying them (the replay was a third of a static
/// discovery's time). It keeps the rows it was made from, so a view under another
/// deadband ([`FirmwareRows::for_deadband`]) is the replay of those same rows.
#[derive(Clone, Debug)]
pub struct FirmwareRows {
    source: Vec<(f64, Option<f64>)>,
    instant: RowInstant,
    deadband: f32,
    rows: Vec<RowView>,
}

impl FirmwareRows {
    /// Replay rows `(time_s, reading °C or none)` from a fresh power-up, each seen at
    /// `instant`, the branch switching past `deadband` (°C/min).
    #[must_use]
    pub fn new(rows: impl IntoIterator<Item = (f64, Option<f64>)>, instant: RowInstant, deadband: f32) -> Self {
        let source: Vec<(f64, Option<f64>)> = rows.into_iter().collect();
        let mut view = FirmwareView::with_deadband(deadband);
        let rows = source
            .iter()
            .map(|&(time_s, temp_c)| {
                let (mut standing, mut own, mut branch_after) = (None, None, None);
                let seen = view.row(time_s, temp_c, instant, |s| {
                    let state = ReadingState {
                        clock_ms: s.reading.clock_ms,
                        raw: s.reading.raw,
                        estimate: s.estimate,
                        branch: s.branch,
                    };
                    if s.reading.stands_for_row {
                        standing = Some(state);
                    }
                    if s.reading.own {
                        own = Some(state);
                    }
                    branch_after = Some(s.branch);
                });
                RowView { seen, standing, own, branch_after }
            })
            .collect();
        Self { source, instant, deadband, rows }
    }

    /// The rows' views, in order.
    #[must_use]
    pub fn rows(&self) -> &[RowView] {
        &self.rows
    }

    /// The branch deadband of this view, °C/min.
    #[must_use]
    pub fn deadband(&self) -> f32 {
        self.deadband
    }

    /// This view when its deadband is `deadband` (bit for bit), else the same rows replayed
    /// under `deadband`: the branch is the only part of the view the deadband changes.
    #[must_use]
    pub fn for_deadband(&self, deadband: f32) -> std::borrow::Cow<'_, Self> {
        if deadband.to_bits() == self.deadband.to_bits() {
            std::borrow::Cow::Borrowed(self)
        } else {
            std::borrow::Cow::Owned(Self::new(self.source.iter().copied(), self.instant, deadband))
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The replay's reading period is the firmware's default sensor period.
    #[test]
    fn the_reading_period_is_the_firmwares() {
        assert_eq!(READING_PERIOD_S * 1000.0, f64::from(qfa_thermal::Config::default().sample_period_ms));
    }

    /// Ties go to even codes on both sides of 0 °C: ±1/32 °C reads 0, ±3/32 °C reads ±2/16.
    #[test]
    fn half_codes_round_to_even_codes() {
        assert_eq!(raw_reading(1.0 / 32.0), 0);
        assert_eq!(raw_reading(-1.0 / 32.0), 0);
        assert_eq!(raw_reading(3.0 / 32.0), 2);
        assert_eq!(raw_reading(-3.0 / 32.0), -2);
        assert_eq!(raw_reading(1e6), i16::MAX);
    }

    /// 10-s rows get nine readings between them at 1 s, and a cycling row is seen at its
    /// interval's centre (5 s before its time); 1-s rows get none.
    #[test]
    fn ten_second_rows_are_filled_at_one_second() {
        let mut r = Readings::new();
        let mut out = Vec::new();
        r.row(0.0, Some(20.0), RowInstant::IntervalCentre, &mut out);
        assert_eq!(out.len(), 1);
        assert!(out[0].stands_for_row);
        r.row(10.0, Some(21.0), RowInstant::IntervalCentre, &mut out);
        assert_eq!(out.iter().map(|x| x.clock_ms).collect::<Vec<_>>(), (1..=10).map(|k| k * 1000).collect::<Vec<_>>());
        assert_eq!(out.iter().filter(|x| x.stands_for_row).map(|x| x.clock_ms).collect::<Vec<_>>(), vec![5000]);
        assert_eq!(out[4].raw, 328); // 320 + 16·5/10
        r.row(20.0, Some(22.0), RowInstant::OwnReading, &mut out);
        assert_eq!(out.iter().filter(|x| x.stands_for_row).map(|x| x.clock_ms).collect::<Vec<_>>(), vec![20_000]);
        r.row(21.0, Some(22.0), RowInstant::IntervalCentre, &mut out);
        assert_eq!(out.len(), 1);
        // Beyond the estimator's gap limit nothing is filled: the firmware restarts there.
        r.row(60.0, Some(22.0), RowInstant::IntervalCentre, &mut out);
        assert_eq!(out.len(), 1);
    }

    /// Hold 20 °C for 10 min, ramp at 1 °C/min to 40 °C, hold 10 min: the chamber's own
    /// temperature at `t` s.
    fn ramp(t: f64) -> f64 {
        20.0 + ((t - 600.0) / 60.0).clamp(0.0, 20.0)
    }

    /// The oracle: the firmware's own estimator fed a reading of the chamber every second,
    /// as on target; its (T̂, Ṫ) at each whole second.
    fn firmware_every_second(end_s: u32) -> Vec<(f32, f32)> {
        let mut est = RateEstimator::<RATE_WINDOW>::new(RateConfig::default());
        (0..=end_s)
            .map(|t| {
                let raw = (ramp(f64::from(t)) * 16.0).round() as i16;
                est.push(t * 1000, raw).expect("times increase");
                let e = est.estimate().expect("a reading was pushed");
                (e.temp_c, e.rate_c_per_min)
            })
            .collect()
    }

    /// A log that keeps one row in ten of that test: each row, as calibration sees it (the
    /// run's trace) and as discovery sees it (its channels), carries the Ṫ the firmware had
    /// at that instant, within 0.1 °C/min at every row, ramp corners included (measured
    /// 0.049: the filled readings differ from the chamber's by a code near the corners, and
    /// one code in one reading moves a 32-reading slope by up to 0.021 °C/min). Without the
    /// 1-s readings between rows the estimator's 32 readings span 320 s and Ṫ lags by up
    /// to 0.97 °C/min, nearly the whole ramp rate, after each corner.
    #[test]
    fn a_ten_second_row_log_is_seen_with_the_rate_the_firmware_had() {
        let oracle = firmware_every_second(3000);
        let rows: Vec<(f64, Option<f64>)> =
            (0..=300).map(|k| (f64::from(k) * 10.0, Some(ramp(f64::from(k) * 10.0)))).collect();
        let view = FirmwareRows::new(rows.iter().copied(), RowInstant::OwnReading, 0.182);
        let calibration = crate::pairing::trace_view(&view, &qfa_thermal::Extensions::NONE, 0.182);
        let discovery = crate::channels::Trace::new(
            "ramp".into(),
            &rows.iter().map(|&(t, c)| (t, c.unwrap() as f32)).collect::<Vec<_>>(),
            None,
            &vec![0.0; rows.len()],
            60.0,
        );
        let mut worst = 0.0f64;
        for (k, &(t, _)) in rows.iter().enumerate() {
            let (_, rate) = oracle[t as usize];
            let cal = calibration.rate_c_per_min[k];
            assert_eq!(cal, f64::from(discovery.est_rate[k]), "row {k}: calibration and discovery disagree");
            worst = worst.max((cal - f64::from(rate)).abs());
        }
        assert!(worst < 0.1, "Ṫ off the firmware's by up to {worst} °C/min");
    }

    /// A cycling row counts pulses over its interval: calibration's trace of a run and the
    /// compensation of that run see it at the interval's centre: the firmware's T̂ there
    /// within 0.02 °C (a third of a code; 0.73 °C off without the 1-s readings, at the end
    /// of each row).
    #[test]
    fn a_cycling_row_is_seen_at_its_intervals_centre() {
        let oracle = firmware_every_second(3000);
        let samples = (1..=300)
            .map(|k| {
                let t = f64::from(k) * 10.0;
                crate::cycling::Sample { time_s: t, temp_c: Some(ramp(t)), pulses: 0, interval_s: 10.0 }
            })
            .collect();
        let run = crate::cycling::Run { program: "p".into(), run: "0".into(), input_g: 1.0, samples };
        let tr = crate::pairing::trace_run(&run, &qfa_thermal::Extensions::NONE, 0.182);
        let mut worst = 0.0f64;
        for (k, s) in run.samples.iter().enumerate().skip(40) {
            let (temp, _) = oracle[(s.time_s - 5.0) as usize];
            worst = worst.max((tr.temp_c[k] - f64::from(temp)).abs());
        }
        assert!(worst < 0.02, "T̂ off the firmware's at the interval centre by {worst} °C");
    }
}
