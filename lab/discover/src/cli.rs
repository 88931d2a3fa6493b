//! The entry points: the workflow with its outputs written ([`discover`],
//! [`discover_with_verdict`]) and the lab demo's hook.

use super::*;
use qfa_log::channels::ChannelsError;
use qfa_log::open::{open, open_bytes, OpenedLog, ReadFlags};
use qfa_report::verdict::Verdict;

/// What a discovery reads: a cycling log (its channels for the catalog, and the log whose
/// ±1 g pairs its table is fitted on, as `calibrate` fits them) or a single-channel log.
#[derive(Debug)]
pub enum Source {
    /// A cycling log and its channels.
    Cycling {
        /// The log.
        log: Box<qfa_log::cycling::Log>,
        /// Its channels.
        channels: Channels,
    },
    /// A single-channel log's channels.
    Single(Channels),
}

impl Source {
    /// The source of an opened log, binned at `bin_s`.
    ///
    /// # Errors
    /// As [`Channels::from_opened`]: a static or autopilot log, a cycling log without pairs.
    pub fn from_opened(opened: OpenedLog, bin_s: f64) -> Result<Self, ChannelsError> {
        let channels = Channels::from_opened(&opened, bin_s)?;
        Ok(match opened {
            OpenedLog::Cycling(log) => Self::Cycling { log: Box::new(log), channels },
            _ => Self::Single(channels),
        })
    }

    /// Read a cycling or single-channel log.
    ///
    /// # Errors
    /// The reader's error, or as [`Source::from_opened`].
    pub fn read(path: &Path, bin_s: f64) -> Result<Self, ChannelsError> {
        Self::from_opened(open(path, &ReadFlags::default()).map_err(ChannelsError::Open)?, bin_s)
    }

    /// Parse log text (see [`Source::read`]).
    ///
    /// # Errors
    /// As [`Source::read`].
    pub fn parse(text: &str, bin_s: f64) -> Result<Self, ChannelsError> {
        Self::from_opened(open_bytes(text.as_bytes(), &ReadFlags::default()).map_err(ChannelsError::Read)?, bin_s)
    }

    /// The channels the catalog reads.
    #[must_use]
    pub fn channels(&self) -> &Channels {
        match self {
            Self::Cycling { channels, .. } | Self::Single(channels) => channels,
        }
    }
}

/// Run the workflow on `input` from `start` and write the outputs to `out_dir`.
///
/// # Errors
/// A cycling log's table could not be fitted, or output files could not be written
/// ([`DiscoverError`]).
pub fn discover(input: &Source, start: Start, out_dir: &Path) -> Result<Report> {
    Ok(discover_with_verdict(input, start, out_dir)?.0)
}

/// The catalog's report on `input` and, for a cycling log, the table both `calibrate` and
/// `discover` write ([`crate::cycling_table`]); a single-channel log's table is the
/// catalog's model (`None` here).
///
/// # Errors
/// A cycling log's table could not be fitted.
pub fn analyze_source(input: &Source, start: Start) -> Result<(Report, Option<qfa_thermal::Table>)> {
    let mut report = analyze(input.channels(), start);
    let table = match input {
        Source::Cycling { log, channels } => Some(crate::cycling_table::adopt(log, channels, &mut report)?),
        Source::Single(_) => None,
    };
    Ok((report, table))
}

/// [`discover`], with the verdict its reports open with (what `qfa-lab discover` prints).
///
/// # Errors
/// As [`discover`].
pub fn discover_with_verdict(input: &Source, start: Start, out_dir: &Path) -> Result<(Report, Verdict)> {
    let (report, table) = analyze_source(input, start)?;
    let (v, _) = output::write(input.channels(), &report, table.as_ref(), out_dir, output::Scope::Own)?;
    Ok((report, v))
}

/// Demo hook (the demo runs one discovery): start `simple` on a unit's cycling log.
/// With the simulator's Eq. 11 truth this should rediscover the paper's structure
/// (`temp_quadratic` and the rate terms). Returns a one-line summary.
///
/// # Errors
/// The log gives no channels, or an output could not be written (the demo fails with it).
pub fn demo_hook(log: &Path, out: &Path) -> Result<String, DiscoverError> {
    let r = discover(&Source::read(log, 60.0)?, Start::Simple, out)?;
    let names = r.effect_labels();
    let gap = |g: &Gaps| match g {
        Gaps::Cycling { scale_factor_ppm, bias_ug } => format!("{scale_factor_ppm:.1} ppm / {bias_ug:.1} µg"),
        Gaps::Single { value_rms } => format!("{value_rms:.3}"),
    };
    Ok(format!(
        "start simple → added [{}]; held-out gap (scale factor / bias) {} → {}; {}",
        if names.is_empty() { "none".to_string() } else { names.join(", ") },
        gap(&r.heldout_gap_before),
        gap(&r.heldout_gap_after),
        out.join("report.md").display()
    ))
}
