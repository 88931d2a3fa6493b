//! Coefficient table wire format: a 16-byte header and a postcard payload, CRC-32 checked.
//!
//! ```text
//! offset size field
//!      0    4 magic "QFAT"
//!      4    2 format version, little-endian (3; 1 and 2 are refused, see below)
//!      6    1 axis count (1..=3)
//!      7    1 reserved, 0
//!      8    4 payload length, little-endian
//!     12    4 CRC-32/ISO-HDLC of the payload, little-endian
//!     16    n payload: postcard encoding of [`Table`]
//! ```
//!
//! The payload's first field is the [`Input`] the table was fitted for: pulse counts (K1 in
//! pulses/(g·s)) or samples (K1 in LSB/g). Format 1 did not record it, and the two kinds
//! differ in nothing else a decoder could check, so a format-1 table is refused with
//! [`Error::NoInputRecorded`] rather than guessed: re-export it with `qfa-lab`.
//!
//! [`Table::decode`] checks everything before it returns a table (header, CRC, postcard,
//! no trailing bytes, then [`Table::validate`]), so a caller that only swaps in a table it
//! got back from it loads atomically: a table either validates fully or nothing changes.

use core::fmt;

use serde::{Deserialize, Serialize};

use crate::model::{AxisModel, MAX_BIAS_POINTS};

mod source;
pub use source::RustSource;

/// Magic bytes at offset 0.
pub const MAGIC: [u8; 4] = *b"QFAT";
/// Format version written and accepted. Format 3 added each bias grid's fit residual
/// ([`BiasGrid::residual_rms_g`](crate::BiasGrid::residual_rms_g)), which sets when
/// `MODEL_SETTLING` clears; a format-2 table is refused with [`Error::Version`]: re-export it
/// with `qfa-lab` (or decode it with the previous release and add the field).
pub const FORMAT_VERSION: u16 = 3;
/// The format before tables recorded their [`Input`]: refused with [`Error::NoInputRecorded`].
const FORMAT_WITHOUT_INPUT: u16 = 1;
/// Header length in bytes.
pub const HEADER_LEN: usize = 16;
/// Largest encoded table (header + payload) for 3 axes with full grids and every slot.
pub const MAX_TABLE_BYTES: usize = 1024;
/// Most axes a table holds.
pub const MAX_AXES: usize = 3;
/// The unit every [`Input::Samples`] table's K1 is in: 2²⁰ per g, the lab's scale. The
/// compensator brings the part's raw LSB to it with [`Config::sample_lsb_per_g`](crate::Config::sample_lsb_per_g),
/// once per reading, so the fast path takes raw samples as the part gives them.
pub const SAMPLE_UNITS_PER_G: f32 = 1_048_576.0;

/// Physically sane limits a table must respect (beyond finiteness).
pub mod limits {
    /// Temperature range any grid may span, °C (DS18B20: −55..125).
    pub const TEMP_C: (f32, f32) = (-60.0, 130.0);
    /// Largest |K0| anywhere, g: the grid's largest value plus the largest the extension
    /// terms can add (the play weight, the creep gain times the grid's span) must stay
    /// within it.
    pub const BIAS_G: f32 = 0.1;
    /// Largest calibrated |Ṫ|, °C/min.
    pub const RATE_C_PER_MIN: f32 = 20.0;
    /// γ range, pulses/(g·s).
    pub const GAMMA: (f32, f32) = (1.0, 1.0e9);
    /// Largest |K1 − γ|/γ anywhere in the calibrated box: keeps K1 ≥ γ/2 > 0.
    pub const MAX_RELATIVE_DEVIATION: f32 = 0.5;
    /// sensor_lag τ range, s.
    pub const LAG_TAU_S: (f32, f32) = (0.1, 1.0e5);
    /// Play half-width range, °C.
    pub const PLAY_HALF_WIDTH_C: (f32, f32) = (0.01, 50.0);
    /// Largest |play weight|, g.
    pub const PLAY_WEIGHT_G: f32 = 0.01;
    /// Creep τ_ref range, s.
    pub const CREEP_TAU_S: (f32, f32) = (1.0, 1.0e6);
    /// Largest creep activation temperature, K.
    pub const CREEP_ACTIVATION_K: f32 = 20_000.0;
    /// Largest |creep gain|, g/°C.
    pub const CREEP_GAIN_G_PER_C: f32 = 1.0e-3;
    /// Largest |M − I| element of the misalignment matrix.
    pub const MISALIGNMENT: f32 = 0.05;
    /// Largest branch deadband, °C/min.
    pub const DEADBAND_C_PER_MIN: f32 = 10.0;
    /// A bias grid's fit residual (RMS), g: from 0.1 µg (below any accelerometer's bias
    /// stability) to the largest bias.
    pub const RESIDUAL_RMS_G: (f32, f32) = (1e-7, BIAS_G);
    /// Smallest bias-grid step, °C: 1.6 DS18B20 LSB (0.0625 °C). Finer steps resolve nothing
    /// the sensor can tell apart, and at 64 °C a step of 2.6e-7 °C is below one f32 ulp of
    /// the temperature (7.6e-6 °C), so the node index would be noise.
    pub const MIN_GRID_STEP_C: f32 = 0.1;
}

/// What a table's coefficients convert: the input the fast path is given.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub enum Input {
    /// Pulse counts per IMU cycle from a QFA's current-to-frequency converter
    /// ([`Compensator::cycle`](crate::Compensator::cycle)); K1 and γ in pulses/(g·s).
    #[default]
    PulseCounts,
    /// Raw samples of a digital accelerometer
    /// ([`Compensator::cycle_samples`](crate::Compensator::cycle_samples)); K1 and γ in LSB/g.
    Samples,
}

impl fmt::Display for Input {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::PulseCounts => "pulse counts",
            Self::Samples => "samples",
        })
    }
}

/// Why a table was refused.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
#[non_exhaustive]
pub enum Error {
    /// Fewer bytes than the header and its stated payload.
    Truncated,
    /// Magic is not "QFAT".
    BadMagic,
    /// Format version not supported.
    Version(u16),
    /// Header axis count differs from the payload's or from the compensator's.
    AxisCount {
        /// Axes in the table.
        table: u8,
        /// Axes expected.
        expected: u8,
    },
    /// CRC-32 of the payload does not match the header.
    Crc,
    /// The payload is not a postcard [`Table`].
    Decode,
    /// Bytes after the payload.
    TrailingBytes,
    /// Encoding does not fit the buffer.
    BufferTooSmall,
    /// A number is NaN or infinite; names the field.
    NonFinite(&'static str),
    /// A value is outside its sane range; names the field.
    OutOfRange(&'static str),
    /// The bias grid is malformed (step ≤ 0, fewer than 2 points, unequal branches).
    Grid,
    /// K1 could reach `γ/2` or less inside the calibrated box.
    ScaleFactorNotPositive,
    /// A format-1 table: it does not record whether it converts pulse counts or samples.
    NoInputRecorded,
    /// The table converts another input than the compensator is configured for.
    Input {
        /// Input the table was fitted for.
        table: Input,
        /// Input the compensator's [`Config`](crate::Config) names.
        compensator: Input,
    },
    /// The table's K1 at T0 (γ) is more than a factor of 2 from its nominal scale: the
    /// compensator's [`Config::nominal_k1`](crate::Config::nominal_k1) for pulse counts,
    /// [`SAMPLE_UNITS_PER_G`] for samples. The table is in another unit scale, and applying
    /// it would scale every output by that ratio.
    Scale {
        /// γ of the first axis out of scale, rounded.
        table_k1: u32,
        /// The compensator's nominal K1, rounded.
        nominal_k1: u32,
    },
    /// The table records the part's sensitivity ([`Table::part_lsb_per_g`]) and the
    /// compensator's [`Config::sample_lsb_per_g`](crate::Config::sample_lsb_per_g) differs:
    /// the part is read at another range than it was calibrated at (a ±16 g part given
    /// the ±8 g sensitivity reads 1 g as 0.5 g).
    PartScale {
        /// The part's LSB per g the table was calibrated at, rounded.
        table_lsb_per_g: u32,
        /// The compensator's, rounded.
        config_lsb_per_g: u32,
    },
    /// Table was fitted with another rate-estimator window than this firmware's.
    RateWindow {
        /// Window in the table.
        table: u16,
        /// Window of this firmware.
        firmware: u16,
    },
    /// The table has a misalignment matrix and the compensator has no misalignment stage
    /// (its `MATRIX` is 0): use a `...WithMatrix` type, or a table without one.
    NoMisalignmentStage,
}

impl fmt::Display for Error {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Truncated => f.write_str("table truncated"),
            Self::BadMagic => f.write_str("bad magic (not a QFAT table)"),
            Self::Version(v) => write!(f, "format version {v} not supported"),
            Self::AxisCount { table, expected } => write!(f, "table has {table} axes, expected {expected}"),
            Self::Crc => f.write_str("payload CRC-32 mismatch"),
            Self::Decode => f.write_str("payload is not a valid table encoding"),
            Self::TrailingBytes => f.write_str("trailing bytes after payload"),
            Self::BufferTooSmall => f.write_str("buffer too small for the encoding"),
            Self::NonFinite(w) => write!(f, "non-finite number in {w}"),
            Self::OutOfRange(w) => write!(f, "{w} out of range"),
            Self::Grid => f.write_str("malformed bias grid"),
            Self::ScaleFactorNotPositive => f.write_str("scale factor can fall to γ/2 or below in range"),
            Self::NoInputRecorded => f.write_str(
                "format 1 table does not record whether it converts pulse counts or samples; re-export it with qfa-lab",
            ),
            Self::Input { table, compensator } => {
                write!(f, "table converts {table}, the compensator is configured for {compensator}")
            }
            Self::Scale { table_k1, nominal_k1 } => write!(
                f,
                "table K1 {table_k1} per g is not within a factor of 2 of the nominal {nominal_k1}: another unit \
                 scale (pulse counts: set Config::nominal_k1; samples tables are in 2^20 units per g)"
            ),
            Self::PartScale { table_lsb_per_g, config_lsb_per_g } => write!(
                f,
                "table calibrated at {table_lsb_per_g} LSB/g, the compensator states {config_lsb_per_g} LSB/g: \
                 the part is read at another range (set Config::sample_lsb_per_g to the part's range)"
            ),
            Self::RateWindow { table, firmware } => {
                write!(f, "table fitted with rate window {table}, firmware uses {firmware}")
            }
            Self::NoMisalignmentStage => f.write_str(
                "table has a misalignment matrix, the compensator has no misalignment stage \
                 (use a compensator type WithMatrix, MATRIX = 3)",
            ),
        }
    }
}

impl core::error::Error for Error {}

/// Result with a table [`Error`].
pub type Result<T> = core::result::Result<T, Error>;

/// A full coefficient table: one [`AxisModel`] per axis, the rate window it was fitted
/// with, and an optional misalignment / cross-axis matrix (3 axes only).
///
/// Calibration writes a table's wire bytes ([`Table::encode`]); the firmware takes them
/// back with [`Table::decode`], which refuses anything that does not validate fully:
///
/// ```
/// use qfa_thermal::table::{self, MAX_TABLE_BYTES};
/// use qfa_thermal::{AxisModel, BiasGrid, Extensions, Input, ScaleFactor, Table};
///
/// let bias = BiasGrid::single_valued(-40.0, 10.0, &[1e-4; 13]).expect("2 to 16 grid values");
/// let scale = ScaleFactor { t0_c: 22.0, gamma: 320_320.0, mu: -32.76, beta: 0.1008, epsilon: 88.14, eta: -0.02409, alpha: 273.0 }; // JB-KT8 #1, Eq. 15
/// let axis = AxisModel { scale, bias, rate_limit_c_per_min: 2.0, ext: Extensions::default() };
/// let t = Table { input: Input::PulseCounts, rate_window: 32, axes: [axis].into_iter().collect(), misalignment: None, part_lsb_per_g: None };
///
/// let mut buf = [0u8; MAX_TABLE_BYTES];
/// let bytes = t.encode(&mut buf).unwrap();
/// assert_eq!(&bytes[..4], b"QFAT");
/// assert_eq!(u16::from_le_bytes([bytes[4], bytes[5]]), table::FORMAT_VERSION); // 3
/// assert_eq!(Table::decode(bytes), Ok(t));
///
/// let mut corrupt = bytes.to_vec();
/// corrupt[20] ^= 0x01; // one flipped payload bit
/// assert_eq!(Table::decode(&corrupt), Err(table::Error::Crc));
/// ```
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "defmt", derive(defmt::Format))]
pub struct Table {
    /// The input the coefficients convert; sets the unit of every K1 and γ.
    pub input: Input,
    /// Samples in the rate estimator window the table was fitted with.
    pub rate_window: u16,
    /// Per-axis models.
    pub axes: heapless::Vec<AxisModel, MAX_AXES>,
    /// Row-major 3×3 matrix applied to the per-axis velocity increments, or none.
    pub misalignment: Option<[f32; 9]>,
    /// For [`Input::Samples`]: the part's own sensitivity at the range it was calibrated at,
    /// LSB per g (4 096 for a ±8 g 16-bit part), when calibration was told it
    /// (`qfa-lab calibrate --lsb-per-g`). A compensator configured with another
    /// [`Config::sample_lsb_per_g`](crate::Config::sample_lsb_per_g) refuses the table
    /// ([`Error::PartScale`]): the part is set to another range than it was calibrated at,
    /// or the firmware states the wrong one, and every output would be off by their ratio.
    /// `None` for pulse counts, and for a samples table that does not know it.
    pub part_lsb_per_g: Option<f32>,
}

impl Table {
    /// A table of `M` axes (1..=3, checked when it is compiled), in a `const` or `static`:
    /// a table in flash, written by hand or generated, recording no part sensitivity
    /// ([`samples_of_part`](Self::samples_of_part) records one). Nothing is validated here;
    /// [`Compensator::set_table`](crate::Compensator::set_table) validates it before use.
    ///
    /// ```
    /// use qfa_thermal::{AxisModel, BiasGrid, Config, Extensions, Input, ScaleFactor, Table, ThreeAxisSensorPerAxis};
    ///
    /// const AXIS: AxisModel = AxisModel {
    ///     scale: ScaleFactor::simple(22.0, 320_320.0, -32.76),
    ///     bias: BiasGrid::flat(-40.0, 10.0, [1e-4; 13]),
    ///     rate_limit_c_per_min: 2.0,
    ///     ext: Extensions::NONE,
    /// };
    /// static TABLE: Table = Table::new(Input::PulseCounts, 32, [AXIS; 3], None);
    ///
    /// let mut comp = ThreeAxisSensorPerAxis::new(Config::default()).unwrap(); // holds `&'static Table`
    /// comp.set_table(&TABLE).unwrap();
    /// ```
    #[must_use]
    pub const fn new<const M: usize>(
        input: Input,
        rate_window: u16,
        axes: [AxisModel; M],
        misalignment: Option<[f32; 9]>,
    ) -> Self {
        const { assert!(M >= 1 && M <= MAX_AXES, "a table has 1 to 3 axes") }
        Self { input, rate_window, axes: heapless::Vec::from_array(axes), misalignment, part_lsb_per_g: None }
    }

    /// A samples table of `M` axes that records the part's sensitivity at the range it was
    /// calibrated at, LSB per g ([`Table::part_lsb_per_g`]), in a `const` or `static`.
    #[must_use]
    pub const fn samples_of_part<const M: usize>(
        rate_window: u16,
        axes: [AxisModel; M],
        misalignment: Option<[f32; 9]>,
        part_lsb_per_g: f32,
    ) -> Self {
        const { assert!(M >= 1 && M <= MAX_AXES, "a table has 1 to 3 axes") }
        Self {
            input: Input::Samples,
            rate_window,
            axes: heapless::Vec::from_array(axes),
            misalignment,
            part_lsb_per_g: Some(part_lsb_per_g),
        }
    }
}

/// CRC-32/ISO-HDLC remainders of the 16 nibbles (reflected polynomial EDB88320h), built at
/// compile time.
const CRC32_NIBBLES: [u32; 16] = {
    let mut t = [0u32; 16];
    let mut n = 0;
    while n < 16 {
        let mut crc = n as u32;
        let mut bit = 0;
        while bit < 4 {
            crc = if crc & 1 == 1 { (crc >> 1) ^ 0xEDB8_8320 } else { crc >> 1 };
            bit += 1;
        }
        t[n] = crc;
        n += 1;
    }
    t
};

/// CRC-32/ISO-HDLC (the zlib/PNG CRC: initial and final XOR FFFFFFFFh) of `bytes`, a
/// nibble at a time from a 64-byte table. Written out rather than taken from the `crc`
/// crate, whose table-less variant unrolls to 858 B of Cortex-M4 code and whose byte table
/// is 1 KB; a table is checked once per load, so speed does not matter. The standard check
/// value is asserted in the tests.
#[must_use]
pub fn crc32(bytes: &[u8]) -> u32 {
    let mut crc = u32::MAX;
    for &b in bytes {
        crc = (crc >> 4) ^ CRC32_NIBBLES[((crc ^ u32::from(b)) & 0xF) as usize];
        crc = (crc >> 4) ^ CRC32_NIBBLES[((crc ^ u32::from(b >> 4)) & 0xF) as usize];
    }
    !crc
}

// Not inlined: validation runs once per load, and its two dozen call sites would otherwise
// each carry a copy of both checks (about 500 B of Cortex-M4 flash).
#[inline(never)]
fn finite(x: f32, what: &'static str) -> Result<()> {
    if x.is_finite() {
        Ok(())
    } else {
        Err(Error::NonFinite(what))
    }
}

#[inline(never)]
fn within(x: f32, (lo, hi): (f32, f32), what: &'static str) -> Result<()> {
    finite(x, what)?;
    if x >= lo && x <= hi {
        Ok(())
    } else {
        Err(Error::OutOfRange(what))
    }
}

fn validate_axis(a: &AxisModel) -> Result<()> {
    let s = &a.scale;
    for (x, w) in [
        (s.t0_c, "scale.t0_c"),
        (s.gamma, "scale.gamma"),
        (s.mu, "scale.mu"),
        (s.beta, "scale.beta"),
        (s.epsilon, "scale.epsilon"),
        (s.eta, "scale.eta"),
        (s.alpha, "scale.alpha"),
    ] {
        finite(x, w)?;
    }
    within(s.t0_c, limits::TEMP_C, "scale.t0_c")?;
    within(s.gamma, limits::GAMMA, "scale.gamma")?;

    let b = &a.bias;
    finite(b.t_start_c, "bias.t_start_c")?;
    finite(b.t_step_c, "bias.t_step_c")?;
    let n = b.heating_g.len();
    if !(2..=MAX_BIAS_POINTS).contains(&n) || b.cooling_g.len() != n || b.t_step_c <= 0.0 {
        return Err(Error::Grid);
    }
    if b.t_step_c < limits::MIN_GRID_STEP_C {
        return Err(Error::OutOfRange("bias.t_step_c"));
    }
    within(b.t_start_c, limits::TEMP_C, "bias.t_start_c")?;
    within(b.t_end_c(), limits::TEMP_C, "bias grid end")?;
    within(b.deadband_c_per_min, (0.0, limits::DEADBAND_C_PER_MIN), "bias.deadband_c_per_min")?;
    within(b.residual_rms_g, limits::RESIDUAL_RMS_G, "bias.residual_rms_g")?;
    let mut grid_max = 0.0f32;
    for &k0 in b.heating_g.iter().chain(b.cooling_g.iter()) {
        within(k0, (-limits::BIAS_G, limits::BIAS_G), "bias value")?;
        grid_max = libm::fmaxf(grid_max, libm::fabsf(k0));
    }
    within(a.rate_limit_c_per_min, (0.0, limits::RATE_C_PER_MIN), "rate_limit_c_per_min")?;
    if a.rate_limit_c_per_min <= 0.0 {
        return Err(Error::OutOfRange("rate_limit_c_per_min"));
    }

    let d_max = libm::fmaxf(libm::fabsf(b.t_start_c - s.t0_c), libm::fabsf(b.t_end_c() - s.t0_c));
    let dev = s.max_deviation(d_max, a.rate_limit_c_per_min);
    if !(dev.is_finite() && dev < limits::MAX_RELATIVE_DEVIATION * s.gamma) {
        return Err(Error::ScaleFactorNotPositive);
    }

    if let Some(lag) = a.ext.sensor_lag {
        within(lag.tau_s, limits::LAG_TAU_S, "sensor_lag.tau_s")?;
    }
    if let Some(h) = a.ext.bias_branch_hysteresis {
        within(h.half_width_c, limits::PLAY_HALF_WIDTH_C, "bias_branch_hysteresis.half_width_c")?;
        let w = limits::PLAY_WEIGHT_G;
        within(h.weight_g, (-w, w), "bias_branch_hysteresis.weight_g")?;
    }
    if let Some(c) = a.ext.bias_creep {
        let g = limits::CREEP_GAIN_G_PER_C;
        within(c.gain_g_per_c, (-g, g), "bias_creep.gain_g_per_c")?;
        within(c.tau_ref_s, limits::CREEP_TAU_S, "bias_creep.tau_ref_s")?;
        within(c.t_ref_c, limits::TEMP_C, "bias_creep.t_ref_c")?;
        within(c.activation_k, (0.0, limits::CREEP_ACTIVATION_K), "bias_creep.activation_k")?;
    }
    // The whole K0, not the grid alone: the play term reaches its weight, and the creep
    // term its gain times Te − x, both of which stay on the grid's span.
    let play = a.ext.bias_branch_hysteresis.map_or(0.0, |h| libm::fabsf(h.weight_g));
    let creep = a.ext.bias_creep.map_or(0.0, |c| libm::fabsf(c.gain_g_per_c) * (b.t_end_c() - b.t_start_c));
    if grid_max + play + creep > limits::BIAS_G {
        return Err(Error::OutOfRange("bias with its extension terms"));
    }
    Ok(())
}

impl Table {
    /// Check every number: finite, grids well formed, K1 > γ/2 over the calibrated box,
    /// and all values within [`limits`].
    ///
    /// # Errors
    /// The first failed check.
    pub fn validate(&self) -> Result<()> {
        if self.axes.is_empty() {
            return Err(Error::AxisCount { table: 0, expected: 1 });
        }
        for a in &self.axes {
            validate_axis(a)?;
        }
        if let Some(m) = self.misalignment {
            if self.axes.len() != 3 {
                return Err(Error::AxisCount { table: self.axes.len() as u8, expected: 3 });
            }
            for (i, &x) in m.iter().enumerate() {
                let ident = if i % 4 == 0 { 1.0 } else { 0.0 };
                within(x - ident, (-limits::MISALIGNMENT, limits::MISALIGNMENT), "misalignment")?;
            }
        }
        if self.rate_window < 3 {
            return Err(Error::OutOfRange("rate_window"));
        }
        if let Some(lsb) = self.part_lsb_per_g {
            // Only a samples table is read in a part's LSB.
            if self.input != Input::Samples {
                return Err(Error::OutOfRange("part_lsb_per_g"));
            }
            within(lsb, limits::GAMMA, "part_lsb_per_g")?;
        }
        Ok(())
    }

    /// Encode into `buf` (header + payload), returning the used bytes. Validates first.
    ///
    /// # Errors
    /// A validation error, or [`Error::BufferTooSmall`].
    pub fn encode<'a>(&self, buf: &'a mut [u8]) -> Result<&'a [u8]> {
        self.validate()?;
        if buf.len() < HEADER_LEN {
            return Err(Error::BufferTooSmall);
        }
        let (head, body) = buf.split_at_mut(HEADER_LEN);
        let payload_len = postcard::to_slice(self, body).map_err(|_| Error::BufferTooSmall)?.len();
        let crc = crc32(&body[..payload_len]);
        head[0..4].copy_from_slice(&MAGIC);
        head[4..6].copy_from_slice(&FORMAT_VERSION.to_le_bytes());
        head[6] = self.axes.len() as u8;
        head[7] = 0;
        head[8..12].copy_from_slice(&(payload_len as u32).to_le_bytes());
        head[12..16].copy_from_slice(&crc.to_le_bytes());
        Ok(&buf[..HEADER_LEN + payload_len])
    }

    /// [`Self::encode`] into a buffer of the largest table's size: the one call host tools
    /// (the lab, its batches, the Python package) encode a table with.
    ///
    /// # Errors
    /// A validation error.
    pub fn to_bytes(&self) -> Result<heapless::Vec<u8, MAX_TABLE_BYTES>> {
        let mut buf = [0u8; MAX_TABLE_BYTES];
        let used = self.encode(&mut buf)?;
        heapless::Vec::from_slice(used).map_err(|_| Error::BufferTooSmall)
    }

    /// Decode and fully validate a table.
    ///
    /// # Errors
    /// The first failed check, header to semantics.
    pub fn decode(bytes: &[u8]) -> Result<Self> {
        let Some((head, body)) = bytes.split_first_chunk::<HEADER_LEN>() else {
            return Err(Error::Truncated);
        };
        if head[0..4] != MAGIC {
            return Err(Error::BadMagic);
        }
        let version = u16::from_le_bytes([head[4], head[5]]);
        if version == FORMAT_WITHOUT_INPUT {
            return Err(Error::NoInputRecorded);
        }
        if version != FORMAT_VERSION {
            return Err(Error::Version(version));
        }
        let axes = head[6];
        if axes == 0 || usize::from(axes) > MAX_AXES || head[7] != 0 {
            return Err(Error::AxisCount { table: axes, expected: MAX_AXES as u8 });
        }
        let len = u32::from_le_bytes([head[8], head[9], head[10], head[11]]) as usize;
        let stored_crc = u32::from_le_bytes([head[12], head[13], head[14], head[15]]);
        if body.len() < len {
            return Err(Error::Truncated);
        }
        if body.len() > len {
            return Err(Error::TrailingBytes);
        }
        if crc32(body) != stored_crc {
            return Err(Error::Crc);
        }
        let (table, rest): (Self, &[u8]) = postcard::take_from_bytes(body).map_err(|_| Error::Decode)?;
        if !rest.is_empty() {
            return Err(Error::TrailingBytes);
        }
        if table.axes.len() != usize::from(axes) {
            return Err(Error::AxisCount { table: table.axes.len() as u8, expected: axes });
        }
        table.validate()?;
        Ok(table)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::model::{BiasGrid, Extensions, ScaleFactor};

    fn small() -> Table {
        let axis = AxisModel {
            scale: ScaleFactor::simple(22.0, 320_000.0, -32.0),
            bias: BiasGrid::single_valued(-60.0, 130.0, &[1e-4, 2e-4]).expect("2 to 16 grid values"),
            rate_limit_c_per_min: 1.0,
            ext: Extensions::default(),
        };
        let mut axes = heapless::Vec::new();
        axes.push(axis).unwrap();
        Table { input: Input::PulseCounts, rate_window: 32, axes, misalignment: None, part_lsb_per_g: None }
    }

    /// `to_bytes` gives `encode`'s bytes, which decode to the same table; an invalid table
    /// is refused with `encode`'s error, not written.
    #[test]
    fn to_bytes_is_encode_and_refuses_what_encode_refuses() {
        let mut buf = [0u8; MAX_TABLE_BYTES];
        let t = small();
        let bytes = t.to_bytes().unwrap();
        assert_eq!(bytes.as_slice(), t.encode(&mut buf).unwrap());
        assert_eq!(Table::decode(&bytes).unwrap(), t);
        let mut bad = small();
        bad.rate_window = 2;
        assert_eq!(bad.to_bytes(), Err(Error::OutOfRange("rate_window")));
    }

    #[test]
    fn exact_bytes_of_a_small_table() {
        let mut buf = [0u8; MAX_TABLE_BYTES];
        let bytes = small().encode(&mut buf).unwrap();
        // Independent spelling of the postcard layout: varint u16, varint len, f32 LE,
        // Option tag bytes, Vec length prefixes.
        let mut want: heapless::Vec<u8, 128> = heapless::Vec::new();
        want.extend_from_slice(&[0, 32, 1]).unwrap(); // pulse counts, rate_window 32, 1 axis
        for f in [22.0f32, 320_000.0, -32.0, 0.0, 0.0, 0.0, 0.0] {
            want.extend_from_slice(&f.to_le_bytes()).unwrap();
        }
        for f in [-60.0f32, 130.0, 0.05] {
            want.extend_from_slice(&f.to_le_bytes()).unwrap();
        }
        for _ in 0..2 {
            want.push(2).unwrap();
            for f in [1e-4f32, 2e-4] {
                want.extend_from_slice(&f.to_le_bytes()).unwrap();
            }
        }
        want.extend_from_slice(&4e-6f32.to_le_bytes()).unwrap(); // the grid's residual (format 3)
        want.extend_from_slice(&1.0f32.to_le_bytes()).unwrap();
        want.extend_from_slice(&[0, 0, 0, 0]).unwrap(); // three slots off, no misalignment
        want.push(0).unwrap(); // no part sensitivity recorded (format 3)
        assert_eq!(&bytes[HEADER_LEN..], &want[..]);
        assert_eq!(&bytes[..8], &[b'Q', b'F', b'A', b'T', 3, 0, 1, 0]);
        assert_eq!(&bytes[8..12], &(want.len() as u32).to_le_bytes());
        assert_eq!(&bytes[12..16], &crc32(&want).to_le_bytes());
        assert_eq!(crc32(b"123456789"), 0xCBF4_3926, "CRC-32/ISO-HDLC check value");
        assert_eq!(Table::decode(bytes).unwrap(), small());
    }

    #[test]
    fn every_header_fault_is_typed() {
        let mut buf = [0u8; MAX_TABLE_BYTES];
        let good: heapless::Vec<u8, MAX_TABLE_BYTES> =
            heapless::Vec::from_slice(small().encode(&mut buf).unwrap()).unwrap();
        let mutate = |f: &dyn Fn(&mut heapless::Vec<u8, MAX_TABLE_BYTES>)| {
            let mut b = good.clone();
            f(&mut b);
            Table::decode(&b)
        };
        assert_eq!(mutate(&|b| b.truncate(10)), Err(Error::Truncated));
        assert_eq!(mutate(&|b| b[0] = b'X'), Err(Error::BadMagic));
        assert_eq!(mutate(&|b| b[4] = 4), Err(Error::Version(4)));
        // Format 2 did not record the grids' residual: refused, not read with a guess.
        assert_eq!(mutate(&|b| b[4] = 2), Err(Error::Version(2)));
        assert_eq!(mutate(&|b| b[4] = 1), Err(Error::NoInputRecorded));
        assert!(matches!(mutate(&|b| b[6] = 4), Err(Error::AxisCount { .. })));
        assert!(matches!(mutate(&|b| b[6] = 2), Err(Error::AxisCount { .. })));
        assert_eq!(mutate(&|b| b[20] ^= 1), Err(Error::Crc));
        assert_eq!(mutate(&|b| b.push(0).unwrap()), Err(Error::TrailingBytes));
        let n = good.len();
        assert_eq!(mutate(&|b| b.truncate(n - 1)), Err(Error::Truncated));
    }

    #[test]
    fn semantic_faults_are_typed() {
        let mut t = small();
        t.axes[0].scale.mu = f32::NAN;
        assert_eq!(t.validate(), Err(Error::NonFinite("scale.mu")));
        let mut t = small();
        t.axes[0].scale.gamma = -1.0;
        assert_eq!(t.validate(), Err(Error::OutOfRange("scale.gamma")));
        let mut t = small();
        t.axes[0].scale.mu = -3000.0; // K1 would fall below γ/2 at 70 °C·... span 108 °C
        assert_eq!(t.validate(), Err(Error::ScaleFactorNotPositive));
        let mut t = small();
        t.axes[0].bias.t_step_c = 0.0;
        assert_eq!(t.validate(), Err(Error::Grid));
        let mut t = small();
        t.axes[0].bias.cooling_g.pop();
        assert_eq!(t.validate(), Err(Error::Grid));
        let mut t = small();
        t.axes[0].bias.heating_g[0] = 0.5;
        assert_eq!(t.validate(), Err(Error::OutOfRange("bias value")));
        let mut t = small();
        t.misalignment = Some([1.0, 0.0, 0.0, 0.0, 1.0, 0.0, 0.0, 0.0, 1.0]);
        assert!(matches!(t.validate(), Err(Error::AxisCount { .. })));
    }
}
