//! Temperature programs: the paper's Steps 1–6, a flight-like profile, and user files.
//!
//! A program is the chamber-air temperature as a piecewise-linear function of time.
//! The paper's program (§3.1) at rate `r` °C/min: hold 22 °C for 120 min; then to −60,
//! up to +70 and back to 22 °C in 1 °C steps, each step a ramp at `r` followed by a
//! 3-min dwell at the integer temperature. One pass takes 120 + 260·(1/r + 3) min:
//! 1767 min at 0.3, 1420 at 0.5, 1271 at 0.7, 1189 at 0.9 °C/min. The index head runs
//! every program at the four positions 0°, 90°, 180°, 270° = +1, 0, −1, 0 g (Step 5), so
//! the full test at 1-s rows is 4·(1767+1420+1271+1189)·60 ≈ 1.355 M rows.

use std::path::Path;

/// Chamber-air temperature program.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    /// Id written to the log's `program` column.
    pub id: String,
    /// Breakpoints `(time_s, temp_c)`, time strictly increasing, starting at 0.
    pub points: Vec<(f64, f64)>,
}

/// An index-head position: run index and specific force along the input axis.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Position {
    /// Run index in the log.
    pub run: u32,
    /// Input, g.
    pub input_g: f64,
}

/// The paper's four positions 0°, 90°, 180°, 270°: +1, 0, −1, 0 g (Fig. 4).
#[must_use]
pub fn paper_positions() -> Vec<Position> {
    [1.0, 0.0, -1.0, 0.0].iter().enumerate().map(|(i, &g)| Position { run: i as u32, input_g: g }).collect()
}

/// The paper's ramp rates, °C/min (Step 6).
pub const PAPER_RATES: [f64; 4] = [0.3, 0.5, 0.7, 0.9];

/// Program ids of [`Program::covering`].
#[cfg(test)]
pub(crate) const COVERING_IDS: [&str; 4] = ["paper-0.3", "paper-0.9", "ramp-1.0", "ramp-2.0"];

/// Program id of the paper's program at `rate`, e.g. `paper-0.3`.
#[must_use]
pub(crate) fn paper_id(rate: f64) -> String {
    format!("paper-{rate:.1}")
}

impl Program {
    /// Duration, s.
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.points.last().map_or(0.0, |p| p.0)
    }

    /// Air temperature at `t_s` (held constant past the ends).
    #[must_use]
    pub fn temp_at(&self, t_s: f64) -> f64 {
        let p = &self.points;
        if p.is_empty() {
            return 22.0;
        }
        if t_s <= p[0].0 {
            return p[0].1;
        }
        let i = p.partition_point(|q| q.0 <= t_s);
        if i >= p.len() {
            return p[p.len() - 1].1;
        }
        let (a, b) = (p[i - 1], p[i]);
        a.1 + (b.1 - a.1) * (t_s - a.0) / (b.0 - a.0)
    }

    /// The paper's Steps 1–4 at `rate` °C/min with `hold_min` at 22 °C and `dwell_min` at
    /// each integer, over `low..high` (the paper: 120, 3, −60, 70).
    #[must_use]
    pub fn staircase(id: &str, rate: f64, hold_min: f64, dwell_min: f64, low: i32, high: i32) -> Self {
        let start = 22;
        let mut pts = vec![(0.0, f64::from(start))];
        let mut t = hold_min * 60.0;
        pts.push((t, f64::from(start)));
        let ramp_s = 60.0 / rate;
        let mut temp = start;
        for target in [low, high, start] {
            let step = if target < temp { -1 } else { 1 };
            while temp != target {
                temp += step;
                t += ramp_s;
                pts.push((t, f64::from(temp)));
                t += dwell_min * 60.0;
                pts.push((t, f64::from(temp)));
            }
        }
        Self { id: id.to_string(), points: pts }
    }

    /// The paper's program (Steps 1–4) at `rate` °C/min.
    #[must_use]
    pub fn paper(rate: f64) -> Self {
        Self::staircase(&paper_id(rate), rate, 120.0, 3.0, -60, 70)
    }

    /// A continuous triangle at `rate` °C/min (no dwells): hold 22 °C for 30 min, then
    /// 22 → −60 → +70 → 22 °C. The case lags the air by τ = 600 s, so after about half an
    /// hour of each ramp the case moves at nearly `rate`: unlike the staircase, whose
    /// dwells keep the case below about half the ramp rate, this reaches the case rates of
    /// a flight (the built-in flight's reach 1.6 °C/min). Id `ramp-{rate:.1}`.
    #[must_use]
    pub(crate) fn triangle(rate: f64) -> Self {
        let mut pts = vec![(0.0, 22.0), (1800.0, 22.0)];
        let mut t = 1800.0;
        let mut temp: f64 = 22.0;
        for target in [-60.0f64, 70.0, 22.0] {
            t += (target - temp).abs() / rate * 60.0;
            temp = target;
            pts.push((t, temp));
        }
        Self { id: format!("ramp-{rate:.1}"), points: pts }
    }

    /// The lab program that covers the built-in flight (`COVERING_IDS`): the paper's
    /// staircase at 0.3 and 0.9 °C/min and continuous 1 and 2 °C/min triangles, in that
    /// order (the held-out rule then fits on `paper-0.3` and `ramp-2.0` and holds out
    /// `paper-0.9` and `ramp-1.0`, both inside the fitted rate range).
    #[must_use]
    pub fn covering() -> Vec<Self> {
        vec![Self::paper(0.3), Self::paper(0.9), Self::triangle(1.0), Self::triangle(2.0)]
    }

    /// A flight-like chamber profile after the paper's §3.2 (about 2.3 h): 30 min start-up
    /// and climb while the INS warms from 20 to 40 °C, 90 min cruise cooling to about
    /// −11 °C at the case, 20 min landing warming to 15 °C. Air leads the case, so the air
    /// goes a little beyond the case targets.
    #[must_use]
    pub fn flight() -> Self {
        let m = 60.0;
        Self {
            id: "flight".to_string(),
            points: vec![
                (0.0, 20.0),
                (5.0 * m, 20.0),
                (30.0 * m, 42.0),
                (45.0 * m, 20.0),
                (110.0 * m, -16.0),
                (120.0 * m, -14.0),
                (128.0 * m, 10.0),
                (140.0 * m, 16.0),
            ],
        }
    }

    /// A user profile: CSV with header `time_s,temp_c`, time increasing from 0.
    ///
    /// # Errors
    /// A message naming the line.
    pub fn from_file(path: &Path, id: &str) -> Result<Self, ProfileError> {
        let text = std::fs::read_to_string(path).map_err(|e| ProfileError::Io(qfa_log::IoFault::new(path, &e)))?;
        let mut pts: Vec<(f64, f64)> = Vec::new();
        for (i, line) in text.lines().enumerate() {
            let l = line.trim();
            if i == 0 {
                if l.replace(' ', "") != "time_s,temp_c" {
                    return Err(ProfileError::Header { got: l.to_string() });
                }
                continue;
            }
            if l.is_empty() || l.starts_with('#') {
                continue;
            }
            let mut it = l.split(',').map(|f| f.trim().parse::<f64>());
            let (Some(Ok(t)), Some(Ok(c)), None) = (it.next(), it.next(), it.next()) else {
                return Err(ProfileError::Row { line: i + 1, got: l.to_string() });
            };
            if !t.is_finite() || !c.is_finite() || !(-60.0..=125.0).contains(&c) {
                return Err(ProfileError::OutOfRange { line: i + 1 });
            }
            if pts.last().is_some_and(|p| t <= p.0) || (pts.is_empty() && t != 0.0) {
                return Err(ProfileError::Time { line: i + 1 });
            }
            pts.push((t, c));
        }
        if pts.len() < 2 {
            return Err(ProfileError::TooFewPoints);
        }
        Ok(Self { id: id.to_string(), points: pts })
    }
}

/// Why a user profile was refused ([`Program::from_file`]).
#[derive(Clone, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum ProfileError {
    /// The file could not be read.
    Io(qfa_log::IoFault),
    /// Line 1 is not `time_s,temp_c`.
    Header {
        /// What line 1 holds.
        got: String,
    },
    /// A line that is not two numbers.
    Row {
        /// Its line number (the header is line 1).
        line: usize,
        /// What it holds.
        got: String,
    },
    /// A value not finite, or a temperature outside −60..125 °C.
    OutOfRange {
        /// Its line number.
        line: usize,
    },
    /// A time that does not start at 0 or does not increase.
    Time {
        /// Its line number.
        line: usize,
    },
    /// Fewer than two points.
    TooFewPoints,
}

impl std::fmt::Display for ProfileError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Io(e) => write!(f, "{e}"),
            Self::Header { got } => write!(f, "line 1: header must be `time_s,temp_c`, got `{got}`"),
            Self::Row { line, got } => write!(f, "line {line}: expected `time_s,temp_c`, got `{got}`"),
            Self::OutOfRange { line } => write!(f, "line {line}: value out of range"),
            Self::Time { line } => write!(f, "line {line}: time must start at 0 and increase"),
            Self::TooFewPoints => f.write_str("profile needs at least two points"),
        }
    }
}

impl std::error::Error for ProfileError {}

#[cfg(test)]
mod tests {
    use super::*;

    /// Each way a profile file can be wrong is its own error, with the line it is on.
    #[test]
    fn a_bad_profile_is_refused_with_its_line() {
        let dir = std::env::temp_dir().join(format!("qfa-profile-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let read = |text: &str| {
            let p = dir.join("p.csv");
            std::fs::write(&p, text).unwrap();
            Program::from_file(&p, "p")
        };
        assert_eq!(read("time,temp\n0,20\n").unwrap_err(), ProfileError::Header { got: "time,temp".into() });
        assert_eq!(read("time_s,temp_c\n0,20\n60,x\n").unwrap_err(), ProfileError::Row { line: 3, got: "60,x".into() });
        assert_eq!(read("time_s,temp_c\n0,20\n60,200\n").unwrap_err(), ProfileError::OutOfRange { line: 3 });
        assert_eq!(read("time_s,temp_c\n0,20\n0,21\n").unwrap_err(), ProfileError::Time { line: 3 });
        assert_eq!(read("time_s,temp_c\n0,20\n").unwrap_err(), ProfileError::TooFewPoints);
        assert!(read("time_s,temp_c\n0,20\n60,21\n").is_ok());
        assert!(matches!(Program::from_file(&dir.join("absent.csv"), "p"), Err(ProfileError::Io(_))));
        let _ = std::fs::remove_dir_all(&dir);
    }

    #[test]
    fn triangle_ramps_continuously_at_its_rate() {
        let p = Program::triangle(2.0);
        assert_eq!(p.id, "ramp-2.0");
        // 30 min hold + (82 + 130 + 48) °C at 2 °C/min = 130 min.
        assert!((p.duration_s() - (30.0 + 130.0) * 60.0).abs() < 1e-6);
        // Mid-ramp: 1 °C every 30 s, no dwell.
        let t = 1800.0 + 600.0;
        assert!((p.temp_at(t) - (22.0 - 20.0)).abs() < 1e-9);
        assert!((p.temp_at(t + 30.0) - p.temp_at(t) + 1.0).abs() < 1e-9);
        let ids: Vec<String> = Program::covering().into_iter().map(|p| p.id).collect();
        assert_eq!(ids, COVERING_IDS);
    }

    #[test]
    fn paper_program_duration_matches_hand_count() {
        // 120 min hold + 260 one-degree steps of (1/r + 3) min.
        for &r in &PAPER_RATES {
            let p = Program::paper(r);
            let want = (120.0 + 260.0 * (1.0 / r + 3.0)) * 60.0;
            assert!((p.duration_s() - want).abs() < 1e-6, "{r}: {} vs {want}", p.duration_s());
        }
        let p = Program::paper(0.5);
        assert_eq!(p.temp_at(3600.0), 22.0);
        // First step: 22 → 21 over 120 s, then dwell.
        assert!((p.temp_at(7200.0 + 60.0) - 21.5).abs() < 1e-12);
        assert_eq!(p.temp_at(7200.0 + 200.0), 21.0);
        let lo = p.points.iter().map(|q| q.1).fold(f64::INFINITY, f64::min);
        let hi = p.points.iter().map(|q| q.1).fold(f64::NEG_INFINITY, f64::max);
        assert_eq!((lo, hi), (-60.0, 70.0));
    }
}
