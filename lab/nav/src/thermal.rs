//! Drive temperature of the IMU bay over a flight: piecewise-linear breakpoints.
//!
//! The lab's thermal chain ([`qfa_sim::thermal::ThermalChain`]: air → case (DS18B20) →
//! element, first-order lags) turns it into the case temperature and rate that the truth
//! model and the DS18B20s see.

use std::fmt;

use serde::{Deserialize, Serialize};

/// One breakpoint of the drive temperature.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct TempPoint {
    /// Time since start, s.
    pub t_s: f64,
    /// Drive temperature, °C.
    pub temp_c: f64,
}

/// Why breakpoints make no drive profile.
#[derive(Debug)]
#[non_exhaustive]
pub enum ProfileError {
    /// No breakpoint at all.
    NoBreakpoints,
    /// Breakpoints whose times do not strictly increase.
    NotIncreasing,
}

impl fmt::Display for ProfileError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::NoBreakpoints => f.write_str("temperature profile has no breakpoints"),
            Self::NotIncreasing => f.write_str("temperature breakpoints not increasing in time"),
        }
    }
}

impl std::error::Error for ProfileError {}

/// Piecewise-linear drive profile, held constant outside its breakpoints: the lab's one
/// temperature program ([`qfa_sim::profile::Program`]) over the flight's breakpoints.
#[derive(Clone, Debug, PartialEq)]
pub struct Profile {
    program: qfa_sim::profile::Program,
}

impl Profile {
    /// From breakpoints sorted by time (at least one).
    ///
    /// # Errors
    /// Empty or unsorted breakpoints.
    pub fn new(points: Vec<TempPoint>) -> Result<Self, ProfileError> {
        crate::ensure(!points.is_empty(), ProfileError::NoBreakpoints)?;
        crate::ensure(points.windows(2).all(|w| w[1].t_s > w[0].t_s), ProfileError::NotIncreasing)?;
        let points = points.iter().map(|p| (p.t_s, p.temp_c)).collect();
        Ok(Self { program: qfa_sim::profile::Program { id: "flight".into(), points } })
    }

    /// Drive temperature at `t_s`, °C.
    #[must_use]
    pub fn at(&self, t_s: f64) -> f64 {
        self.program.temp_at(t_s)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn profile_interpolates_and_holds() {
        let p =
            Profile::new(vec![TempPoint { t_s: 0.0, temp_c: 20.0 }, TempPoint { t_s: 100.0, temp_c: 30.0 }]).unwrap();
        assert_eq!(p.at(-5.0), 20.0);
        assert_eq!(p.at(50.0), 25.0);
        assert_eq!(p.at(500.0), 30.0);
    }
}
