//! How a message names an option the person passed: as a `qfa-lab` flag (`--holdout
//! blocks:5`) or as a keyword argument of the Python package (`holdout="blocks:5"`).
//!
//! An error or a note keeps the option it is about as a value
//! ([`crate::units::ReaderOption`] for the log readers, [`CalibrateOption`] for
//! calibration and discovery) and spells it only when its message is formed
//! (`message(Spelling)`; `Display` is the CLI's), so neither front end rewrites the
//! other's text.

/// Who reads a message, and so how it names options.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub enum Spelling {
    /// `qfa-lab`'s flags: `--accel-unit m/s2`.
    #[default]
    Cli,
    /// The Python package's keyword arguments: `accel_unit="m/s2"`.
    Python,
    /// A batch manifest's TOML keys, set for the unit the message is about:
    /// `accel_unit = "m/s2"` (the reader's options; the batch's own are its command's
    /// flags).
    Manifest,
}

/// An option of `qfa-lab calibrate` (and `discover`'s `--holdout`) that a message names.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
#[non_exhaustive]
pub enum CalibrateOption {
    /// The held-out scheme of a static log (`auto`, `after-max`, `blocks:K`, `none`).
    Holdout,
    /// The temperature range of the fields the exported axes share, °C.
    ExportRange,
    /// PX4's `TC_A0_ID`: the device ID of the accelerometer the PX4 file is for.
    Px4DeviceId,
}

impl CalibrateOption {
    /// The option's name: `--export-range` or `export_range`.
    #[must_use]
    pub fn name(self, sp: Spelling) -> &'static str {
        match (self, sp) {
            // A manifest sets reader keys only: these are the batch command's flags.
            (_, Spelling::Manifest) => self.name(Spelling::Cli),
            (Self::Holdout, Spelling::Cli) => "--holdout",
            (Self::ExportRange, Spelling::Cli) => "--export-range",
            (Self::Px4DeviceId, Spelling::Cli) => "--px4-device-id",
            (Self::Holdout, Spelling::Python) => "holdout",
            (Self::ExportRange, Spelling::Python) => "export_range",
            (Self::Px4DeviceId, Spelling::Python) => "px4_device_id",
        }
    }

    /// The option with `value` as the CLI takes it, spelled for `sp`: a scheme is text
    /// (`--holdout blocks:5`, `holdout="blocks:5"`), a device ID a number
    /// (`px4_device_id=7`), a range a pair (`--export-range 20,40`, `export_range=(20, 40)`).
    #[must_use]
    pub fn with(self, sp: Spelling, value: &str) -> String {
        let name = self.name(sp);
        match (self, sp) {
            (_, Spelling::Cli | Spelling::Manifest) => format!("{name} {value}"),
            (Self::Holdout, Spelling::Python) => format!("{name}=\"{value}\""),
            (Self::Px4DeviceId, Spelling::Python) => format!("{name}={value}"),
            (Self::ExportRange, Spelling::Python) => format!("{name}=({})", value.replace(',', ", ")),
        }
    }

    /// As [`Self::with`], for a value the message refuses: the CLI quotes it after the
    /// flag (``--holdout `sideways` ``), Python writes the keyword as passed.
    #[must_use]
    pub fn refused(self, sp: Spelling, value: &str) -> String {
        match sp {
            Spelling::Cli | Spelling::Manifest => format!("{} `{value}`", self.name(sp)),
            Spelling::Python => self.with(sp, value),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn each_option_is_spelled_as_its_caller_passes_it() {
        let cases = [
            (CalibrateOption::Holdout, "blocks:5", "--holdout blocks:5", "holdout=\"blocks:5\""),
            (CalibrateOption::ExportRange, "TMIN,TMAX", "--export-range TMIN,TMAX", "export_range=(TMIN, TMAX)"),
            (CalibrateOption::Px4DeviceId, "ID", "--px4-device-id ID", "px4_device_id=ID"),
        ];
        for (option, value, cli, python) in cases {
            assert_eq!(option.with(Spelling::Cli, value), cli);
            assert_eq!(option.with(Spelling::Python, value), python);
        }
        assert_eq!(CalibrateOption::Holdout.refused(Spelling::Cli, "x"), "--holdout `x`");
        assert_eq!(CalibrateOption::Holdout.refused(Spelling::Python, "x"), "holdout=\"x\"");
        // A manifest sets no calibration option: they are the batch command's flags.
        assert_eq!(CalibrateOption::Holdout.with(Spelling::Manifest, "blocks:5"), "--holdout blocks:5");
    }
}
