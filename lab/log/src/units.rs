//! Units of a static log: the reader options that state them, how each is spelled to the
//! person who passed it (a `qfa-lab` flag or a Python keyword), the temperature unit, and
//! the one refusal of a unit the data contradict ([`UnitMismatch`]).
//!
//! What the data can say about each unit, checked by [`crate::static_log`]:
//! * acceleration: a board at rest reads |a| = 1 g, so with all three axes the median |a|
//!   must lie in [`REST_G`] in the stated unit, from both sides: m/s² read as mg is 10²
//!   too small, g read as m/s² 9.8× too small, m/s² read as g 9.8× too large. With one or
//!   two axes |a| is only a projection, so only "too large" can be refused;
//! * time: the median row interval (10 µs…60 s) and the fastest temperature change
//!   (`crate::static_log::MAX_SLEW_C_PER_MIN`) from both sides;
//! * temperature: readings outside −60…130 °C in the stated unit refuse it (kelvin read as
//!   °C, °C read as kelvin, a hot Fahrenheit log read as °C), and a column name carrying a
//!   unit (`temp_f`, `temperature_k`) contradicting the option is refused. Celsius and
//!   Fahrenheit readings of a log that stays within about 0…50 °C are both plausible: no
//!   check can tell them apart, so the name or the option decides, and `qfa-lab lint`
//!   says when it was assumed.

use std::fmt;
use std::str::FromStr;

use serde::Serialize;

use crate::spelling::Spelling;

/// Range of the median |a| of a board at rest, g, that a stated unit must give (all three
/// axes present). The closest pair of units differs by 9.8× (g and m/s²), so any bound
/// between 1/3 and 3 separates them; 1.5 was the reader's upper bound before the lower one
/// was added, and the lower one is its mirror (1/1.5). Chosen before the check was run on
/// any log; the real tofupilot log reads 0.92…0.995 g.
pub const REST_G: (f64, f64) = (1.0 / 1.5, 1.5);

/// A reader option: how the person reading a log states columns, units and number format.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub enum ReaderOption {
    /// Column choices.
    Columns,
    /// Unit of the time column.
    TimeUnit,
    /// Unit of the acceleration columns.
    AccelUnit,
    /// Unit of the temperature column.
    TempUnit,
    /// Numbers with a decimal comma.
    DecimalComma,
}

impl ReaderOption {
    /// The option's name: `--accel-unit` or `accel_unit`.
    #[must_use]
    pub fn name(self, sp: Spelling) -> &'static str {
        match (self, sp) {
            (Self::Columns, Spelling::Cli) => "--columns",
            (Self::TimeUnit, Spelling::Cli) => "--time-unit",
            (Self::AccelUnit, Spelling::Cli) => "--accel-unit",
            (Self::TempUnit, Spelling::Cli) => "--temp-unit",
            (Self::DecimalComma, Spelling::Cli) => "--decimal-comma",
            (Self::Columns, Spelling::Python) => "columns",
            (Self::TimeUnit, Spelling::Python) => "time_unit",
            (Self::AccelUnit, Spelling::Python) => "accel_unit",
            (Self::TempUnit, Spelling::Python) => "temp_unit",
            (Self::DecimalComma, Spelling::Python) => "decimal_comma",
            (_, Spelling::Manifest) => self.name(Spelling::Python),
        }
    }

    /// The option with a value, as it is passed: `--accel-unit m/s2`, `accel_unit="m/s2"`,
    /// a manifest's `accel_unit = "m/s2"`; the flag [`Self::DecimalComma`] ignores `value`
    /// (`--decimal-comma`, `decimal_comma=True`, `decimal_comma = true`).
    #[must_use]
    pub fn with(self, sp: Spelling, value: &str) -> String {
        match (self, sp) {
            (Self::DecimalComma, Spelling::Cli) => "--decimal-comma".to_string(),
            (Self::DecimalComma, Spelling::Python) => "decimal_comma=True".to_string(),
            (_, Spelling::Cli) => format!("{} {value}", self.name(sp)),
            (_, Spelling::Python) => format!("{}=\"{value}\"", self.name(sp)),
            (Self::DecimalComma, Spelling::Manifest) => "decimal_comma = true".to_string(),
            (_, Spelling::Manifest) => format!("{} = \"{value}\"", self.name(sp)),
        }
    }

    /// As [`Self::with`], for a value the message refuses: the CLI quotes it after the
    /// flag (``--time-unit `hours` ``), Python writes the keyword as passed
    /// (`time_unit="hours"`).
    #[must_use]
    pub(crate) fn refused(self, sp: Spelling, value: &str) -> String {
        match sp {
            Spelling::Cli => format!("{} `{value}`", self.name(sp)),
            Spelling::Python | Spelling::Manifest => self.with(sp, value),
        }
    }

    /// The values a unit option takes (`s|ms|us|ns`); empty for the others.
    #[must_use]
    pub fn allowed(self) -> &'static str {
        match self {
            Self::TimeUnit => "s|ms|us|ns",
            Self::AccelUnit => "g|mg|m/s2",
            Self::TempUnit => "C|F|K",
            Self::Columns | Self::DecimalComma => "",
        }
    }
}

/// Unit of the temperature column; the reader converts it to °C.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize)]
pub enum TempUnit {
    /// Degrees Celsius.
    C,
    /// Degrees Fahrenheit.
    F,
    /// Kelvin.
    K,
}

impl TempUnit {
    /// Every unit.
    pub(crate) const ALL: [TempUnit; 3] = [TempUnit::C, TempUnit::F, TempUnit::K];

    /// The name the option takes.
    #[must_use]
    pub fn name(self) -> &'static str {
        match self {
            Self::C => "C",
            Self::F => "F",
            Self::K => "K",
        }
    }

    /// A reading in this unit, in °C.
    #[must_use]
    pub(crate) fn to_c(self, x: f64) -> f64 {
        match self {
            Self::C => x,
            Self::F => (x - 32.0) / 1.8,
            Self::K => x - 273.15,
        }
    }

    /// The unit a column name ends in (`temp_c`, `temperature_degf`, `temp_k`), if any.
    pub(crate) fn from_suffix(col: &str) -> Option<Self> {
        let c = col.to_ascii_lowercase();
        [("_degc", Self::C), ("_degf", Self::F), ("_c", Self::C), ("_f", Self::F), ("_k", Self::K)]
            .into_iter()
            .find(|(s, _)| c.ends_with(s))
            .map(|(_, u)| u)
    }
}

impl FromStr for TempUnit {
    type Err = UnitParseError;
    fn from_str(s: &str) -> Result<Self, UnitParseError> {
        match s {
            "C" | "c" | "°C" | "degC" => Ok(Self::C),
            "F" | "f" | "°F" | "degF" => Ok(Self::F),
            "K" | "k" => Ok(Self::K),
            _ => Err(UnitParseError { option: ReaderOption::TempUnit, value: s.to_string() }),
        }
    }
}

/// A unit option's value that is none of its units.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct UnitParseError {
    /// The option.
    pub option: ReaderOption,
    /// The value given.
    pub value: String,
}

impl UnitParseError {
    /// The message, with the option spelled for `sp`.
    #[must_use]
    pub fn message(&self, sp: Spelling) -> String {
        format!("{}: expected {}", self.option.refused(sp, &self.value), self.option.allowed())
    }
}

impl fmt::Display for UnitParseError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(Spelling::Cli))
    }
}

impl std::error::Error for UnitParseError {}

/// Where the unit a column was read in came from.
#[derive(Clone, Debug, PartialEq, Eq, Serialize)]
#[non_exhaustive]
pub enum UnitSource {
    /// The reader option.
    Option,
    /// The column's name (`time_ms`, `ax_g`, `temp_f`).
    ColumnName(String),
    /// Neither: the default (°C for temperature, the only unit assumed).
    Assumed,
}

impl UnitSource {
    /// Where the unit came from, in a sentence's words; `option` is the reader option as
    /// the user would type it (`--accel-unit g`).
    #[must_use]
    pub fn describe(&self, option: &str) -> String {
        match self {
            UnitSource::Option => format!("from {option}"),
            UnitSource::ColumnName(c) => format!("from the column name `{c}`"),
            UnitSource::Assumed => "assumed (no option, no unit in the column name)".to_string(),
        }
    }
}

/// A stated unit the data contradict: the one message style of every unit mistake. It
/// reads "wrong unit? read with `<option> <unit>` `<evidence>`; `<expectation>`: pass
/// `<option> <unit that fits>` (`<its figure>`)", or "check `<option>`" when no unit fits.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct UnitMismatch {
    /// The option whose unit is wrong.
    pub option: ReaderOption,
    /// The unit the log was read in.
    pub stated: &'static str,
    /// Where that unit came from.
    pub source: UnitSource,
    /// What the data show in that unit (`the median |a| over … is 0.0096 g`).
    pub evidence: String,
    /// What they must show (`a board at rest reads 0.67..1.5 g`).
    pub expected: String,
    /// Units that fit, each with what the data show in it (`1.000 g`).
    pub fits: Vec<(&'static str, String)>,
}

impl UnitMismatch {
    /// The message, with the option spelled for `sp`.
    #[must_use]
    pub(crate) fn message(&self, sp: Spelling) -> String {
        let read = match &self.source {
            UnitSource::ColumnName(c) => format!("read in {} (from the column name `{c}`)", self.stated),
            UnitSource::Option => format!("read with {}", self.option.with(sp, self.stated)),
            UnitSource::Assumed => format!("read in {} (assumed: no unit given)", self.stated),
        };
        let mut s = format!("wrong unit? {read} {}; {}: ", self.evidence, self.expected);
        if self.fits.is_empty() {
            s.push_str(&format!("check {}", self.option.name(sp)));
        } else {
            let f: Vec<String> =
                self.fits.iter().map(|(u, fig)| format!("pass {} ({fig})", self.option.with(sp, u))).collect();
            s.push_str(&f.join(" or "));
        }
        s
    }
}

impl fmt::Display for UnitMismatch {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(Spelling::Cli))
    }
}

/// How each unit of a static log was decided and what the data show in it (the figures
/// the checks compared): what `qfa-lab lint` prints as the units' evidence.
#[derive(Clone, Debug, Default, PartialEq, Serialize)]
pub struct UnitEvidence {
    /// `(option, unit, source, what the data show)` for time, acceleration, temperature.
    pub units: Vec<(ReaderOption, &'static str, UnitSource, String)>,
    /// The median |a| over the axes at rest, g.
    pub median_abs_g: f64,
    /// Whether every axis is present, so a unit too small could be refused too.
    pub all_axes: bool,
    /// Temperature range read, °C.
    pub temp_range_c: (f64, f64),
    /// Other temperature units in which the log is also plausible (the check could not
    /// tell them apart), with the range they give, °C.
    pub temp_also_plausible: Vec<(&'static str, (f64, f64))>,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn options_are_spelled_for_each_caller() {
        let m = UnitMismatch {
            option: ReaderOption::AccelUnit,
            stated: "mg",
            source: UnitSource::Option,
            evidence: "the median |a| is 0.0096 g".into(),
            expected: "a board at rest reads 0.67..1.50 g".into(),
            fits: vec![("m/s2", "0.980 g".into())],
        };
        assert_eq!(
            m.message(Spelling::Cli),
            "wrong unit? read with --accel-unit mg the median |a| is 0.0096 g; a board at rest reads 0.67..1.50 g: \
             pass --accel-unit m/s2 (0.980 g)"
        );
        let py = m.message(Spelling::Python);
        assert!(py.contains("accel_unit=\"m/s2\"") && !py.contains("--"), "{py}");
        let manifest = m.message(Spelling::Manifest);
        assert!(manifest.ends_with("pass accel_unit = \"m/s2\" (0.980 g)") && !manifest.contains("--"), "{manifest}");
        assert_eq!(ReaderOption::DecimalComma.with(Spelling::Manifest, ""), "decimal_comma = true");
        let bad = UnitParseError { option: ReaderOption::TimeUnit, value: "hours".into() };
        assert_eq!(bad.to_string(), "--time-unit `hours`: expected s|ms|us|ns");
        assert_eq!(bad.message(Spelling::Python), "time_unit=\"hours\": expected s|ms|us|ns");
        assert_eq!(TempUnit::from_suffix("temp_F"), Some(TempUnit::F));
        assert_eq!(TempUnit::from_suffix("imu.temperature"), None);
        assert!((TempUnit::F.to_c(212.0) - 100.0).abs() < 1e-12);
    }
}
