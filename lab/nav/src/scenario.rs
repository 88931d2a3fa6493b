//! Flight scenario (a swappable TOML file) and the ideal trajectory it flies.
//!
//! A scenario is a start point, a list of segments (duration and held targets of ground
//! speed, altitude and heading) and a drive-temperature profile. [`Flight`] turns it into
//! a true navigation state every IMU cycle with simple kinematic controllers:
//!
//! * ground speed: rate-limited to ±[`Limits::accel_mps2`];
//! * heading: turn-rate command `k_ψ·error`, limited to ±[`Limits::turn_rate_dps`], with
//!   the turn rate itself slewed at ≤ [`Limits::turn_accel_dps2`] (so the bank angle is
//!   continuous); bank of a coordinated turn, `φ = atan(V·ψ̇/g)`;
//! * altitude (only once above rotation speed): climb-rate command `k_h·error`, limited to
//!   ±[`Limits::climb_mps`], slewed at ≤ [`Limits::climb_accel_mps2`];
//!   pitch = flight-path angle `atan2(v_up, V)` (no wind, no angle of attack);
//! * position from the mechanisation's own trapezoidal rule
//!   ([`super::strapdown::advance_position`]).
//!
//! The built-in default (`default_scenario.toml`) is the paper's §3.2 flight.

use std::f64::consts::PI;
use std::fmt;
use std::path::{Path, PathBuf};

use nalgebra::{UnitQuaternion, Vector3};
use serde::{Deserialize, Serialize};

use super::align::AlignConfig;
use super::earth::{self, Local};
use super::errors::ImuErrors;
use super::strapdown::{advance_position, NavState};
use super::thermal::TempPoint;
use qfa_sim::thermal::ThermalChain;

/// The built-in scenario, TOML.
pub const DEFAULT_TOML: &str = include_str!("default_scenario.toml");

/// Start point.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Start {
    /// Latitude, degrees.
    pub lat_deg: f64,
    /// Longitude, degrees.
    pub lon_deg: f64,
    /// Ellipsoidal height, m.
    pub alt_m: f64,
    /// Initial heading, degrees.
    pub heading_deg: f64,
}

/// One segment: targets held for a duration.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Segment {
    /// Free text.
    #[serde(default)]
    pub label: String,
    /// Duration, s.
    pub duration_s: f64,
    /// Ground-speed target, m/s.
    pub speed_mps: f64,
    /// Altitude target, m.
    pub alt_m: f64,
    /// Heading target, degrees.
    pub heading_deg: f64,
}

/// Controller limits.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Limits {
    /// Longitudinal acceleration bound, m/s².
    pub accel_mps2: f64,
    /// Turn-rate bound, °/s.
    pub turn_rate_dps: f64,
    /// Turn-rate slew bound, °/s².
    pub turn_accel_dps2: f64,
    /// Heading gain k_ψ, 1/s.
    pub heading_gain: f64,
    /// Climb / descent rate bound, m/s.
    pub climb_mps: f64,
    /// Climb-rate slew bound, m/s².
    pub climb_accel_mps2: f64,
    /// Altitude gain k_h, 1/s.
    pub alt_gain: f64,
    /// Speed above which the altitude controller is active (rotation), m/s.
    pub rotate_mps: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self {
            accel_mps2: 1.5,
            turn_rate_dps: 3.0,
            turn_accel_dps2: 1.0,
            heading_gain: 0.1,
            climb_mps: 9.0,
            climb_accel_mps2: 0.3,
            alt_gain: 0.01,
            rotate_mps: 75.0,
        }
    }
}

/// A whole scenario.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// Name.
    pub name: String,
    /// IMU rate, Hz.
    pub imu_rate_hz: f64,
    /// Seed of every random draw (gyro errors, accelerometer noise, DS18B20 noise).
    pub seed: u64,
    /// Start point.
    pub start: Start,
    /// Segments, flown in order.
    #[serde(rename = "segment")]
    pub segments: Vec<Segment>,
    /// Controller limits.
    #[serde(default)]
    pub limits: Limits,
    /// Thermal chain time constants (air → case → element), the lab's defaults if absent.
    #[serde(default)]
    pub thermal: ThermalChain,
    /// Drive-temperature breakpoints.
    pub temperature: Vec<TempPoint>,
    /// Non-thermal IMU errors (`[imu.gyro]`, `[imu.accel]`), documented defaults.
    #[serde(default)]
    pub imu: ImuErrors,
    /// Stationary alignment before take-off (on by default).
    #[serde(default)]
    pub alignment: AlignConfig,
    /// Bounds of the Monte Carlo variations.
    #[serde(default)]
    pub monte_carlo: Variation,
}

/// The scenario's `[monte_carlo]` table: what varies from run to run besides the noise
/// and the IMU error draws ([`super::errors`]).
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default)]
pub struct Variation {
    /// The drive profile and the ground temperature shift by U(−x, +x), °C.
    pub temp_offset_c: f64,
    /// The drive profile's excursion from the ground temperature is scaled by
    /// U(1 − x, 1 + x).
    pub temp_scale: f64,
    /// Unit-to-unit spread: each thermal coefficient of each accelerometer (Eq. 11 μ, β,
    /// ε, η, α and the bias K0, slope and curvature) is multiplied by `1 + x·N(0, 1)`.
    pub unit_spread: f64,
    /// σ of a change of each DS18B20's offset, °C.
    pub sensor_offset_c: f64,
}

impl Default for Variation {
    fn default() -> Self {
        Self { temp_offset_c: 3.0, temp_scale: 0.1, unit_spread: 0.1, sensor_offset_c: 0.1 }
    }
}

/// Why a scenario could not be loaded.
#[derive(Debug)]
#[non_exhaustive]
pub enum ScenarioError {
    /// The file could not be read.
    Read {
        /// The scenario file.
        path: PathBuf,
        /// The system's error.
        source: std::io::Error,
    },
    /// The file's text is not a valid scenario.
    Parse {
        /// The scenario file.
        path: PathBuf,
        /// Why its text was refused ([`Scenario::parse`]'s error).
        source: Box<ScenarioError>,
    },
    /// Text that is not TOML or not a scenario's fields.
    Toml(toml::de::Error),
    /// `imu_rate_hz` not in (0, 10 000] Hz.
    ImuRate,
    /// No segment to fly.
    NoSegments,
    /// A segment of zero or negative duration.
    SegmentDuration,
    /// The alignment's phases out of 0 < `coarse_s` ≤ `duration_s` ≤ 7200 s.
    Alignment,
    /// The `[monte_carlo]` variation bounds out of range.
    MonteCarloBounds,
}

impl fmt::Display for ScenarioError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Read { path, .. } => write!(f, "reading {}", path.display()),
            Self::Parse { path, .. } => write!(f, "parsing {}", path.display()),
            Self::Toml(e) => write!(f, "{e}"),
            Self::ImuRate => f.write_str("imu_rate_hz out of range"),
            Self::NoSegments => f.write_str("scenario has no segments"),
            Self::SegmentDuration => f.write_str("segment duration must be > 0"),
            Self::Alignment => f.write_str("alignment: need 0 < coarse_s ≤ duration_s ≤ 7200 s"),
            Self::MonteCarloBounds => f.write_str("monte_carlo: bounds must be ≥ 0, temp_scale < 1, unit_spread < 0.5"),
        }
    }
}

impl std::error::Error for ScenarioError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Read { source, .. } => Some(source),
            Self::Parse { source, .. } => Some(&**source),
            // Printed as it is (above): its cause, if any, comes next.
            Self::Toml(e) => e.source(),
            _ => None,
        }
    }
}

impl Scenario {
    /// The built-in default.
    ///
    /// # Panics
    /// Never: the default file is checked by a test.
    #[must_use]
    pub fn builtin() -> Self {
        Self::parse(DEFAULT_TOML).expect("built-in scenario parses")
    }

    /// Parse TOML.
    ///
    /// # Errors
    /// TOML or semantic errors.
    pub fn parse(text: &str) -> Result<Self, ScenarioError> {
        let s: Self = toml::from_str(text).map_err(ScenarioError::Toml)?;
        crate::ensure(s.imu_rate_hz > 0.0 && s.imu_rate_hz <= 10_000.0, ScenarioError::ImuRate)?;
        crate::ensure(!s.segments.is_empty(), ScenarioError::NoSegments)?;
        crate::ensure(s.segments.iter().all(|g| g.duration_s > 0.0), ScenarioError::SegmentDuration)?;
        let a = &s.alignment;
        crate::ensure(
            !a.enabled || (a.coarse_s > 0.0 && a.duration_s >= a.coarse_s && a.duration_s <= 7200.0),
            ScenarioError::Alignment,
        )?;
        let v = &s.monte_carlo;
        crate::ensure(
            [v.temp_offset_c, v.temp_scale, v.unit_spread, v.sensor_offset_c]
                .iter()
                .all(|x| x.is_finite() && *x >= 0.0)
                && v.temp_scale < 1.0
                && v.unit_spread < 0.5,
            ScenarioError::MonteCarloBounds,
        )?;
        Ok(s)
    }

    /// Load from a file.
    ///
    /// # Errors
    /// I/O or parse errors, with the path.
    pub fn load(path: &Path) -> Result<Self, ScenarioError> {
        let text = std::fs::read_to_string(path).map_err(|e| ScenarioError::Read { path: path.into(), source: e })?;
        Self::parse(&text).map_err(|e| ScenarioError::Parse { path: path.into(), source: Box::new(e) })
    }

    /// Total duration, s.
    #[must_use]
    pub fn duration_s(&self) -> f64 {
        self.segments.iter().map(|s| s.duration_s).sum()
    }

    /// IMU cycle, s.
    #[must_use]
    pub fn dt(&self) -> f64 {
        1.0 / self.imu_rate_hz
    }

    /// Number of IMU cycles.
    #[must_use]
    pub fn steps(&self) -> u64 {
        (self.duration_s() * self.imu_rate_hz).round() as u64
    }

    /// Ground (alignment) temperature, °C.
    #[must_use]
    pub fn ground_temp_c(&self) -> f64 {
        self.alignment.ground_temp_c.unwrap_or_else(|| self.temperature.first().map_or(20.0, |p| p.temp_c))
    }

    /// Alignment steps before take-off (0 when alignment is off).
    #[must_use]
    pub fn align_steps(&self) -> u64 {
        if self.alignment.enabled {
            (self.alignment.duration_s * self.imu_rate_hz).round() as u64
        } else {
            0
        }
    }

    /// Shift the drive profile and ground temperature by `offset_c` and scale the
    /// excursion from the ground temperature by `scale`.
    #[must_use]
    pub fn with_temperature_variation(mut self, offset_c: f64, scale: f64) -> Self {
        let g = self.ground_temp_c();
        for p in &mut self.temperature {
            p.temp_c = g + offset_c + scale * (p.temp_c - g);
        }
        self.alignment.ground_temp_c = Some(g + offset_c);
        self
    }

    /// Keep only the first `seconds` of flight (for short tests).
    #[must_use]
    pub fn truncated(mut self, seconds: f64) -> Self {
        let mut left = seconds;
        let mut kept = Vec::new();
        for mut s in self.segments {
            if left <= 0.0 {
                break;
            }
            s.duration_s = s.duration_s.min(left);
            left -= s.duration_s;
            kept.push(s);
        }
        self.segments = kept;
        self
    }
}

fn wrap_pi(a: f64) -> f64 {
    (a + PI).rem_euclid(2.0 * PI) - PI
}

fn slew(x: f64, target: f64, max_step: f64) -> f64 {
    x + (target - x).clamp(-max_step, max_step)
}

/// The true trajectory, advanced one IMU cycle at a time.
#[derive(Clone, Debug)]
pub struct Flight {
    segments: Vec<Segment>,
    lim: Limits,
    dt: f64,
    seg: usize,
    seg_end_s: f64,
    /// Time of the current state, s.
    pub t: f64,
    speed: f64,
    heading: f64,
    turn_rate: f64,
    climb: f64,
    airborne: bool,
    /// Current true state.
    pub state: NavState,
}

impl Flight {
    /// At the scenario's start, at rest, level.
    #[must_use]
    pub fn new(sc: &Scenario) -> Self {
        let heading = sc.start.heading_deg.to_radians();
        let mut f = Self {
            segments: sc.segments.clone(),
            lim: sc.limits,
            dt: sc.dt(),
            seg: 0,
            seg_end_s: sc.segments[0].duration_s,
            t: 0.0,
            speed: 0.0,
            heading,
            turn_rate: 0.0,
            climb: 0.0,
            airborne: false,
            state: NavState {
                q: UnitQuaternion::identity(),
                v: Vector3::zeros(),
                lat: sc.start.lat_deg.to_radians(),
                lon: sc.start.lon_deg.to_radians(),
                h: sc.start.alt_m,
            },
        };
        f.state.q = f.attitude();
        f
    }

    fn attitude(&self) -> UnitQuaternion<f64> {
        let pitch = if self.speed > 1.0 { self.climb.atan2(self.speed) } else { 0.0 };
        let roll = (self.speed * self.turn_rate / earth::G0).atan();
        UnitQuaternion::from_euler_angles(roll, pitch, self.heading)
    }

    /// Advance one IMU cycle; returns the new true state.
    pub fn step(&mut self) -> NavState {
        let dt = self.dt;
        while self.t + 0.5 * dt >= self.seg_end_s && self.seg + 1 < self.segments.len() {
            self.seg += 1;
            self.seg_end_s += self.segments[self.seg].duration_s;
        }
        let seg = &self.segments[self.seg];
        let lim = self.lim;
        self.speed = slew(self.speed, seg.speed_mps, lim.accel_mps2 * dt).max(0.0);
        let err = wrap_pi(seg.heading_deg.to_radians() - self.heading);
        let r_max = lim.turn_rate_dps.to_radians();
        let r_cmd = if self.speed > lim.rotate_mps { (lim.heading_gain * err).clamp(-r_max, r_max) } else { 0.0 };
        self.turn_rate = slew(self.turn_rate, r_cmd, lim.turn_accel_dps2.to_radians() * dt);
        self.heading = wrap_pi(self.heading + self.turn_rate * dt);
        if self.speed > lim.rotate_mps {
            self.airborne = true;
        }
        let h_prev = self.state.h;
        let climb_prev = self.climb;
        let c_cmd = if self.airborne {
            (lim.alt_gain * (seg.alt_m - h_prev)).clamp(-lim.climb_mps, lim.climb_mps)
        } else {
            0.0
        };
        self.climb = slew(self.climb, c_cmd, lim.climb_accel_mps2 * dt);
        let h = h_prev + 0.5 * (climb_prev + self.climb) * dt;
        let (s, c) = self.heading.sin_cos();
        let v = Vector3::new(self.speed * c, self.speed * s, -self.climb);
        let prev = self.state;
        let loc = Local::at(prev.lat, prev.h, &prev.v);
        let (lat, lon) = advance_position(&prev, h, &v, &loc, dt);
        self.t += dt;
        self.state = NavState { q: self.attitude(), v, lat, lon, h };
        self.state
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn builtin_is_about_2_3_hours() {
        let s = Scenario::builtin();
        let h = s.duration_s() / 3600.0;
        assert!((2.2..2.45).contains(&h), "{h} h");
        assert_eq!(s.steps(), (s.duration_s() * 200.0) as u64);
    }

    /// A bad scenario reaches `navigate`'s caller as its variant, and prints as before:
    /// the file, then why.
    #[test]
    fn a_bad_scenario_is_a_typed_error() {
        let zero_rate = DEFAULT_TOML.replace("imu_rate_hz = 200.0", "imu_rate_hz = 0.0");
        assert!(matches!(Scenario::parse(&zero_rate), Err(ScenarioError::ImuRate)));
        assert!(matches!(Scenario::parse("imu_rate_hz = ["), Err(ScenarioError::Toml(_))));
        let p = std::env::temp_dir().join(format!("qfa_nav_zero_rate_{}.toml", std::process::id()));
        std::fs::write(&p, zero_rate).unwrap();
        let args = crate::NavigateArgs { scenario: Some(p.clone()), ..crate::NavigateArgs::default() };
        let e = crate::navigate(&args).unwrap_err();
        std::fs::remove_file(&p).unwrap();
        assert!(
            matches!(&e, crate::NavError::Scenario(ScenarioError::Parse { path, source })
                if *path == p && matches!(**source, ScenarioError::ImuRate)),
            "{e:?}"
        );
        assert_eq!(crate::chain(&e), format!("parsing {}: imu_rate_hz out of range", p.display()));
        // The file is gone now: reading it fails.
        let e = crate::scenario_of(&args).unwrap_err();
        assert!(matches!(&e, ScenarioError::Read { path, .. } if *path == p), "{e:?}");
        assert!(crate::chain(&e).starts_with(&format!("reading {}: ", p.display())), "{e}");
    }
}
