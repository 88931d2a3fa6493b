//! The flight simulation: one pass, every variant in lock-step on the same sensor data.
//!
//! First, when the scenario asks for it, the stationary alignment ([`super::align`]) on
//! the same sensors. Then per IMU cycle: the true trajectory advances ([`Flight`]), the
//! ideal increments come from the mechanisation's exact inverse, the gyros and the
//! accelerometer axes get their non-thermal errors ([`super::errors`]), each
//! accelerometer axis's truth model turns its ideal Δv into pulses, a DS18B20 reading
//! of the case arrives every second, and each variant compensates the same pulses and
//! drives its own mechanisation. Errors are sampled once a second.

use std::fmt;

use nalgebra::Vector3;
use serde::{Deserialize, Serialize};

use super::accel::{AccelCompensation, AccelTruth};
use super::align::{AlignErrors, Aligner, FilterNoise};
use super::earth::{self, NMI_M};
use super::errors::ImuDraw;
use super::scenario::{Flight, Scenario};
use super::strapdown::{inverse, AltRef, Increments, NavState, Strapdown};
use super::thermal::{Profile, ProfileError};
use qfa_calibrate::metrics::rms;
use qfa_sim::thermal::{ChainState, Temps};
use qfa_sim::truth::SensorTruth;

pub use super::errors::GyroErrors;

/// One variant in the run.
pub struct Variant {
    /// Name in the report.
    pub name: String,
    /// Its compensation.
    pub comp: Box<dyn AccelCompensation>,
}

/// Error time series of one variant, sampled every second.
#[derive(Clone, Debug, Default)]
pub struct Track {
    /// North velocity error, m/s.
    pub vn: Vec<f64>,
    /// East velocity error, m/s.
    pub ve: Vec<f64>,
    /// North position error, m.
    pub dn: Vec<f64>,
    /// East position error, m.
    pub de: Vec<f64>,
}

/// Result of a flight.
#[derive(Clone, Debug, Default)]
pub struct FlightResult {
    /// Sample times, s.
    pub t: Vec<f64>,
    /// Bay air, case and element temperature, °C.
    pub temps: Vec<[f64; 3]>,
    /// Variant names, in order.
    pub names: Vec<String>,
    /// One track per variant.
    pub tracks: Vec<Track>,
    /// Gyro biases drawn, °/h.
    pub gyro_bias_dph: [f64; 3],
    /// Alignment errors per variant (empty when alignment is off).
    pub alignment: Vec<AlignErrors>,
    /// Status flags each variant's compensation raised over the flight's IMU cycles
    /// (alignment excluded), per variant; `None`: no status word (the oracle).
    pub flags: Vec<Option<super::accel::FlagCounts>>,
}

/// Navigation figures of one variant.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Figures {
    /// CEP rate, nmile/h: least-squares slope through the origin of the radial position
    /// error r(t) over the whole flight, `Σ t·r / Σ t²` (one trajectory; see the module doc).
    pub cep_nmi_per_h: f64,
    /// RMS East velocity error over the flight, m/s.
    pub rms_ve_mps: f64,
    /// RMS North velocity error over the flight, m/s.
    pub rms_vn_mps: f64,
    /// Radial position error at the end divided by the flight time, nmile/h.
    pub end_radial_nmi_per_h: f64,
    /// Largest radial position error, m.
    pub max_radial_m: f64,
    /// 0.5887·(σ_N + σ_E) of the N/E position errors over the flight (PSINS `cep.m`
    /// form), divided by the flight time, nmile/h.
    pub cep_psins_nmi_per_h: f64,
}

impl Figures {
    /// Figures of a track sampled at times `t` (s).
    #[must_use]
    pub fn of(t: &[f64], tr: &Track) -> Self {
        let r: Vec<f64> = tr.dn.iter().zip(&tr.de).map(|(n, e)| n.hypot(*e)).collect();
        let stt: f64 = t.iter().map(|x| x * x).sum();
        let str_: f64 = t.iter().zip(&r).map(|(a, b)| a * b).sum();
        let slope = if stt > 0.0 { str_ / stt } else { 0.0 };
        let hours = t.last().copied().unwrap_or(0.0) / 3600.0;
        let end = r.last().copied().unwrap_or(0.0);
        let per_h = |m: f64| if hours > 0.0 { m / NMI_M / hours } else { 0.0 };
        Self {
            cep_nmi_per_h: slope * 3600.0 / NMI_M,
            rms_ve_mps: rms(&tr.ve),
            rms_vn_mps: rms(&tr.vn),
            end_radial_nmi_per_h: per_h(end),
            max_radial_m: r.iter().copied().fold(0.0, f64::max),
            cep_psins_nmi_per_h: per_h(0.5887 * (rms(&tr.dn) + rms(&tr.de))),
        }
    }
}

/// The simulated IMU: gyros with their drawn errors, the three accelerometer truth models
/// behind their non-thermal errors, and the three case DS18B20s.
struct Imu<'a> {
    truths: &'a mut [Box<dyn AccelTruth>; 3],
    sensors: [SensorTruth; 3],
    draw: ImuDraw,
    rng: qfa_rng::LabRng,
}

/// One cycle of IMU output.
struct Sensed {
    dtheta: Vector3<f64>,
    pulses: [i32; 3],
    coeffs: [(f64, f64); 3],
}

impl Imu<'_> {
    fn sense(&mut self, ideal: &Increments, th: &Temps, dt: f64) -> Sensed {
        let dtheta = self.draw.gyro(&ideal.dtheta, dt, &mut self.rng);
        let dv = self.draw.accel(&ideal.dv, dt);
        let mut pulses = [0i32; 3];
        let mut coeffs = [(0.0, 0.0); 3];
        for i in 0..3 {
            pulses[i] = self.truths[i].corrupt(th, dv[i], dt);
            coeffs[i] = self.truths[i].coefficients();
        }
        Sensed { dtheta, pulses, coeffs }
    }

    fn ds18b20(&mut self, case_c: f64) -> [i16; 3] {
        let s = self.sensors;
        [0, 1, 2].map(|i| s[i].raw(&mut self.rng, case_c))
    }

    /// Each case's DS18B20 conversion completes once a second (the first at t = 1 s):
    /// on those IMU cycles, read the three sensors and feed every variant.
    fn read_temperatures(&mut self, clock: u64, per_second: u64, case_c: f64, variants: &mut [Variant]) {
        if clock.is_multiple_of(per_second) {
            let raw = self.ds18b20(case_c);
            let t_ms = (clock / per_second * 1000) as u32;
            for v in variants {
                v.comp.on_temperatures(t_ms, raw);
            }
        }
    }
}

/// Why a scenario could not be flown.
#[derive(Debug)]
#[non_exhaustive]
pub enum RunError {
    /// An IMU period that is not a whole number of µs (the compensator's ticks).
    Period,
    /// An IMU rate that is not a whole number of Hz (one DS18B20 reading a second).
    Rate,
    /// The scenario's drive temperature profile.
    Profile(ProfileError),
    /// An alignment that ends before its coarse phase gave an attitude.
    Alignment,
}

impl fmt::Display for RunError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Period => f.write_str("IMU period must be a whole number of µs"),
            Self::Rate => f.write_str("IMU rate must be a whole number of Hz"),
            Self::Profile(e) => write!(f, "{e}"),
            Self::Alignment => f.write_str("alignment shorter than its coarse phase"),
        }
    }
}

impl std::error::Error for RunError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // Printed as it is (above): its cause comes next.
            Self::Profile(e) => e.source(),
            Self::Period | Self::Rate | Self::Alignment => None,
        }
    }
}

impl From<ProfileError> for RunError {
    fn from(e: ProfileError) -> Self {
        Self::Profile(e)
    }
}

/// Run the scenario with the given accelerometer truths (x, y, z) and variants.
///
/// The non-thermal IMU errors are drawn from `sc.imu` on `sc.seed`'s IMU stream
/// ([`super::seeds::imu_errors`]). With
/// `sc.alignment.enabled` (the default) every variant first aligns on the ground on its
/// own compensated output ([`super::align`]) and starts from its aligned attitude, zero
/// velocity and the true position; otherwise every variant starts at the true state.
/// Every variant sees the same gyro increments, pulses and temperature readings.
pub fn fly(
    sc: &Scenario,
    truths: &mut [Box<dyn AccelTruth>; 3],
    mut variants: Vec<Variant>,
) -> Result<FlightResult, RunError> {
    let sensors: [SensorTruth; 3] = [0, 1, 2].map(|i| {
        truths[i].sensor().unwrap_or(SensorTruth { offset_c: 0.0, noise_c: 0.01, period_s: 1.0, first_s: 1.0 })
    });
    let (dt, dt_ticks, per_second) = imu_timing(sc)?;
    let steps = sc.steps();
    let profile = Profile::new(sc.temperature.clone())?;
    let align_steps = sc.align_steps();
    let ground_c = sc.ground_temp_c();
    let chain =
        sc.thermal.start(if align_steps > 0 { ground_c } else { profile.at(0.0) }, dt, sc.thermal.element_tau_s);
    let mut rng = qfa_rng::seeded(super::seeds::imu_errors(sc.seed));
    let draw = ImuDraw::draw(&sc.imu, &mut rng);
    let imu = Imu { truths, sensors, draw, rng };
    let mut flight = Flight::new(sc);
    let start = flight.state;
    let mut res = FlightResult {
        names: variants.iter().map(|v| v.name.clone()).collect(),
        tracks: vec![Track::default(); variants.len()],
        gyro_bias_dph: imu.draw.gyro_bias_dph(),
        ..FlightResult::default()
    };
    // Global cycle count: the DS18B20 timestamps run on through alignment and flight.
    let mut sim = Sim { imu, chain, clock: 0, prev_ideal: Increments::default(), dt, dt_ticks, per_second };
    let mut starts = vec![start; variants.len()];
    if align_steps > 0 {
        align_on_ground(&mut sim, sc, (start, ground_c, align_steps), &mut variants, &mut starts, &mut res.alignment)?;
    }
    let mut navs: Vec<Strapdown> = starts.into_iter().map(Strapdown::new).collect();
    // The flags are counted over the flight only: the alignment's first cycles are flagged
    // RATE_NOT_READY by construction (the estimator's window is filling).
    let flags_at_takeoff: Vec<_> = variants.iter().map(|v| v.comp.flags()).collect();
    for k in 1..=steps {
        let (truth, th) = fly_cycle(&mut sim, &mut flight, &profile, &mut variants, &mut navs);
        if k % per_second == 0 {
            sample_errors(&mut res, flight.t, &th, &truth, &navs);
        }
    }
    res.flags = variants
        .iter()
        .zip(&flags_at_takeoff)
        .map(|(v, f0)| v.comp.flags().map(|f| f0.as_ref().map_or(f, |f0| f.since(f0))))
        .collect();
    Ok(res)
}

/// The IMU period (s, and in the compensator's µs ticks) and the cycles per second,
/// refused unless both are whole numbers.
fn imu_timing(sc: &Scenario) -> Result<(f64, u32, u64), RunError> {
    let dt = sc.dt();
    let dt_ticks = (dt * 1e6).round() as u32;
    crate::ensure((f64::from(dt_ticks) * 1e-6 - dt).abs() < 1e-12, RunError::Period)?;
    let per_second = sc.imu_rate_hz.round() as u64;
    crate::ensure((sc.imu_rate_hz - per_second as f64).abs() < 1e-9, RunError::Rate)?;
    Ok((dt, dt_ticks, per_second))
}

/// What runs on from one IMU cycle to the next, through alignment and flight: the IMU,
/// the thermal chain, the global cycle count, the previous ideal increments, the timing.
struct Sim<'a> {
    imu: Imu<'a>,
    chain: ChainState,
    clock: u64,
    prev_ideal: Increments,
    dt: f64,
    dt_ticks: u32,
    per_second: u64,
}

/// The stationary alignment at `start` with the bay at `ground_c` over `align_steps`
/// cycles: each variant aligns on its own compensated output; its attitude goes into
/// its entry of `starts` and its errors into `alignment`.
fn align_on_ground(
    sim: &mut Sim<'_>,
    sc: &Scenario,
    (start, ground_c, align_steps): (NavState, f64, u64),
    variants: &mut [Variant],
    starts: &mut [NavState],
    alignment: &mut Vec<AlignErrors>,
) -> Result<(), RunError> {
    let g = sc.imu.gyro;
    let noise = FilterNoise {
        arw_rad_rs: g.arw_dprh.to_radians() / 60.0,
        // The lab units' white noise, 10 µg/√Hz.
        accel_white_mps2_rhz: 10e-6 * earth::G0,
        gyro_bias_rad_s: g.bias_dph.hypot(g.bias_instability_dph).to_radians() / 3600.0,
    };
    let mut aligners: Vec<Aligner> =
        variants.iter().map(|_| Aligner::new(&sc.alignment, start, sim.dt, sim.per_second, noise)).collect();
    for _ in 0..align_steps {
        sim.clock += 1;
        let ideal = inverse(&start, &start, &sim.prev_ideal, sim.dt);
        sim.prev_ideal = ideal;
        let th = sim.chain.step(ground_c);
        let s = sim.imu.sense(&ideal, &th, sim.dt);
        sim.imu.read_temperatures(sim.clock, sim.per_second, th.case_c, variants);
        for (v, a) in variants.iter_mut().zip(&mut aligners) {
            let dv = v.comp.compensate(s.pulses, sim.dt_ticks, &s.coeffs);
            a.step(&Increments { dtheta: s.dtheta, dv });
        }
    }
    for (st, a) in starts.iter_mut().zip(&aligners) {
        let q = a.attitude().ok_or(RunError::Alignment)?;
        st.q = q;
        alignment.push(AlignErrors::of(&q, &start.q));
    }
    Ok(())
}

/// One flight cycle: the trajectory advances, the IMU senses it at the drive profile's
/// temperature, and each variant compensates and drives its mechanisation. Returns the
/// true state and the temperatures of the cycle.
fn fly_cycle(
    sim: &mut Sim<'_>,
    flight: &mut Flight,
    profile: &Profile,
    variants: &mut [Variant],
    navs: &mut [Strapdown],
) -> (NavState, Temps) {
    sim.clock += 1;
    let prev = flight.state;
    let truth = flight.step();
    let ideal = inverse(&prev, &truth, &sim.prev_ideal, sim.dt);
    sim.prev_ideal = ideal;
    let th = sim.chain.step(profile.at(flight.t));
    let s = sim.imu.sense(&ideal, &th, sim.dt);
    sim.imu.read_temperatures(sim.clock, sim.per_second, th.case_c, variants);
    let alt = AltRef { h: truth.h, vd: truth.v.z };
    for (v, nav) in variants.iter_mut().zip(navs) {
        let dv = v.comp.compensate(s.pulses, sim.dt_ticks, &s.coeffs);
        nav.step(&Increments { dtheta: s.dtheta, dv }, sim.dt, alt);
    }
    (truth, th)
}

/// Sample, at flight time `t`, the temperatures and each variant's velocity and position
/// errors against the true state.
fn sample_errors(res: &mut FlightResult, t: f64, th: &Temps, truth: &NavState, navs: &[Strapdown]) {
    res.t.push(t);
    res.temps.push([th.air_c, th.case_c, th.element_c]);
    let (rm, rn) = earth::radii(truth.lat);
    for (tr, nav) in res.tracks.iter_mut().zip(navs) {
        let s = &nav.state;
        tr.vn.push(s.v.x - truth.v.x);
        tr.ve.push(s.v.y - truth.v.y);
        tr.dn.push((s.lat - truth.lat) * (rm + truth.h));
        tr.de.push((s.lon - truth.lon) * (rn + truth.h) * truth.lat.cos());
    }
}

/// Closure check with perfect sensors: the ideal increments (f64, no quantization) drive
/// the mechanisation over the whole scenario. Returns the largest horizontal position
/// error (m) and the largest horizontal velocity error (m/s) seen.
#[must_use]
pub fn closure(sc: &Scenario) -> (f64, f64) {
    let dt = sc.dt();
    let mut flight = Flight::new(sc);
    let mut nav = Strapdown::new(flight.state);
    let mut prev_ideal = Increments::default();
    let (mut max_p, mut max_v) = (0.0f64, 0.0f64);
    for _ in 0..sc.steps() {
        let prev = flight.state;
        let truth = flight.step();
        let ideal = inverse(&prev, &truth, &prev_ideal, dt);
        prev_ideal = ideal;
        nav.step(&ideal, dt, AltRef { h: truth.h, vd: truth.v.z });
        let (rm, rn) = earth::radii(truth.lat);
        let s = &nav.state;
        let dn = (s.lat - truth.lat) * (rm + truth.h);
        let de = (s.lon - truth.lon) * (rn + truth.h) * truth.lat.cos();
        max_p = max_p.max(dn.hypot(de));
        max_v = max_v.max((s.v.x - truth.v.x).hypot(s.v.y - truth.v.y));
    }
    (max_p, max_v)
}
