//! The verdict every report opens with: the figure to expect in use (held out, and on
//! what), what the table covers, pass or fail against the limits, what went wrong in
//! words, the files written and what to do with each, and what to record next.
//!
//! One [`Verdict`] is rendered four ways ([`Verdict::console`], [`Verdict::markdown`],
//! [`Verdict::to_page`], and `verdict` in `report.json`) from the same [`Verdict::lines`],
//! so the console, `report.md`, `report.html` and `report.json` cannot tell different
//! stories: a test reads all four back and compares them.
//!
//! Limits come from [`Limits`]: defaults (documented in the lab guide, "Limits") or a TOML
//! file (`--limits limits.toml`). A unit that fails a limit given with `--limits` exits
//! with [`EXIT_LIMIT_FAILED`] after every file is written.

use std::fmt;
use std::path::Path;

use serde::{Deserialize, Serialize};

use crate::html_report::{escape, Page};

mod limits_error;
pub use limits_error::LimitsError;

/// Exit status of a command whose unit fails a limit given with `--limits` (1 is an error,
/// 2 a usage error from the argument parser).
pub const EXIT_LIMIT_FAILED: u8 = 3;

/// Id of the verdict's `<section>` in `report.html` (what a test reads from the DOM).
pub const SECTION_ID: &str = "verdict";

/// How a run came out.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Outcome {
    /// Every limit met.
    Pass,
    /// At least one limit failed (which: [`Verdict::checks`]).
    Fail,
    /// A study (discovery, navigation): no limit applies, the verdict is its answer.
    Study,
}

impl fmt::Display for Outcome {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::Pass => "PASS",
            Self::Fail => "FAIL",
            Self::Study => "RESULT",
        })
    }
}

/// A figure to expect in use: held out, one per axis (or channel).
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Expected {
    /// Axis or channel (`ax`, `pulses`).
    pub axis: String,
    /// What the figure is (`held-out bias RMS`).
    pub what: String,
    /// Its value.
    pub value: f64,
    /// Its unit (`mg`, `µg`, `ppm/°C`).
    pub unit: String,
}

/// The temperatures and rates a table covers (beyond them the firmware clamps and flags).
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
pub struct Covers {
    /// Temperature span of the rows the table was fitted on, °C.
    pub temp_c: [f64; 2],
    /// Fastest heating the rows hold, °C/min (`None`: no heating leg).
    pub heating_c_per_min: Option<f64>,
    /// Fastest cooling the rows hold, °C/min, as a magnitude (`None`: no cooling leg).
    pub cooling_c_per_min: Option<f64>,
}

impl Covers {
    fn text(&self) -> String {
        let leg = |r: Option<f64>| r.map_or_else(|| "none".to_string(), |r| format!("up to {r:.2} °C/min"));
        format!(
            "{:.1}..{:.1} °C; heating {}, cooling {}",
            self.temp_c[0],
            self.temp_c[1],
            leg(self.heating_c_per_min),
            leg(self.cooling_c_per_min)
        )
    }
}

/// A measured figure, or why there is none (in JSON: a number or `{"not_computed": why}`,
/// never NaN or null).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(untagged)]
pub enum Measured {
    /// The figure.
    Value(f64),
    /// Why it could not be formed.
    NotComputed {
        /// The reason.
        not_computed: String,
    },
}

/// One limit checked on one axis.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct Check {
    /// The limit's key in `limits.toml`.
    pub limit: &'static str,
    /// Axis (`all` for a figure of the whole log).
    pub axis: String,
    /// The measured figure.
    pub value: Measured,
    /// The limit.
    pub bound: f64,
    /// `max` (value must not exceed the bound) or `min` (must reach it).
    pub sense: &'static str,
    /// The unit of both.
    pub unit: &'static str,
    /// Whether it is met.
    pub pass: bool,
}

impl Check {
    /// A check of `value`: a figure that was not computed fails, with its reason; one that
    /// is not finite was not measured and fails, named as such.
    fn new(
        limit: &'static str,
        axis: &str,
        value: Measured,
        bound: f64,
        sense: &'static str,
        unit: &'static str,
    ) -> Self {
        let (value, pass) = match value {
            Measured::Value(v) if v.is_finite() => {
                (Measured::Value(v), if sense == "max" { v <= bound } else { v >= bound })
            }
            Measured::Value(_) => {
                (Measured::NotComputed { not_computed: "no held-out figure could be formed".into() }, false)
            }
            not @ Measured::NotComputed { .. } => (not, false),
        };
        Self { limit, axis: axis.to_string(), value, bound, sense, unit, pass }
    }

    fn text(&self) -> String {
        let op = if self.sense == "max" { "≤" } else { "≥" };
        let value = match &self.value {
            Measured::Value(v) => format!("{} {}", fmt_value(*v), self.unit),
            Measured::NotComputed { not_computed } => format!("not computed ({not_computed})"),
        };
        format!(
            "{} {}: {value} {op} {} {} ({})",
            self.limit,
            self.axis,
            fmt_value(self.bound),
            self.unit,
            if self.pass { "pass" } else { "FAIL" }
        )
    }
}

fn fmt_value(v: f64) -> String {
    if v.abs() >= 100.0 {
        format!("{v:.0}")
    } else {
        format!("{v:.2}")
    }
}

/// A file the run wrote, and what to do with it.
#[derive(Clone, Debug, PartialEq, Serialize)]
pub struct FileUse {
    /// File name in the output folder (or a sub-folder, `instance0/table.bin`).
    pub file: String,
    /// What to do with it.
    pub action: String,
}

impl FileUse {
    /// `file` with the action the lab's guide gives for its name (the last path
    /// component: `table.bin`, `px4_tc.params`, …).
    #[must_use]
    pub fn of(file: &str) -> Self {
        let name = file.rsplit('/').next().unwrap_or(file);
        Self { file: file.to_string(), action: action_for(name).to_string() }
    }
}

/// What to do with an output file, by name: one sentence each, the same on every page.
#[must_use]
pub fn action_for(name: &str) -> &'static str {
    match name {
        "table.bin" => "flash this: the firmware's table (`Table::decode`), CRC-checked when loaded",
        "table.toml" => "keep: the same table as text, to read, diff and re-encode",
        "table_simple.bin" | "table_simple.toml" => "compare only: the paper's simple model, not for flashing",
        "px4_tc.params" => {
            "PX4: load in QGroundControl (Vehicle Setup → Parameters → Tools → Load from file), then reboot"
        }
        "ardupilot_tcal_1_enable.parm" => {
            "ArduPilot, first: load in Mission Planner (Config → Full Parameter List → Load from file), write, reboot"
        }
        "ardupilot_tcal_2_values.parm" => "ArduPilot, second (after the reboot): load, write, reboot again",
        "report.json" => "keep: every figure for tools and notebooks",
        "report.md" | "report.html" => "read: this report",
        "discovered.toml" | "discovered.bin" => "flash only after reading the held-out gain above",
        n if n.ends_with(".png") => "read: a plot of this report",
        n if n.ends_with(".csv") => "keep: the data behind this report",
        _ => "keep",
    }
}

/// The verdict of one run.
#[derive(Clone, Debug, PartialEq)]
pub struct Verdict {
    /// How it came out.
    pub outcome: Outcome,
    /// One sentence: the answer.
    pub answer: String,
    /// The figures to expect in use.
    pub expect: Vec<Expected>,
    /// What "held-out" means on this page, the one definition.
    pub held_out: String,
    /// What the table covers (`None` for a study without a table).
    pub covers: Option<Covers>,
    /// Where the limits came from (`default limits` or the file).
    pub limits_from: String,
    /// Every limit checked.
    pub checks: Vec<Check>,
    /// What went wrong or looks alarming, in words.
    pub warnings: Vec<String>,
    /// The files written.
    pub files: Vec<FileUse>,
    /// What to record next (coverage advice).
    pub advice: Vec<String>,
}

impl Verdict {
    /// A verdict with the outcome decided by `checks` (no check: [`Outcome::Study`]).
    #[must_use]
    pub fn new(answer: impl Into<String>, held_out: impl Into<String>, checks: Vec<Check>) -> Self {
        let outcome = if checks.is_empty() {
            Outcome::Study
        } else if checks.iter().all(|c| c.pass) {
            Outcome::Pass
        } else {
            Outcome::Fail
        };
        Self {
            outcome,
            answer: answer.into(),
            expect: Vec::new(),
            held_out: held_out.into(),
            covers: None,
            limits_from: String::new(),
            checks,
            warnings: Vec::new(),
            files: Vec::new(),
            advice: Vec::new(),
        }
    }

    /// On a failed verdict, the files that would reach a unit (the table, the autopilot
    /// parameters) say they are held back, so no line of a failed report says "flash this".
    pub fn hold_back_if_failed(&mut self) {
        if self.outcome != Outcome::Fail {
            return;
        }
        for f in &mut self.files {
            let name = f.file.rsplit('/').next().unwrap_or(&f.file);
            if name == "table.bin" || name.ends_with(".params") || name.ends_with(".parm") {
                f.action = "held back: the unit fails a limit above; flash or load it only after deciding why".into();
            }
        }
    }

    /// The limits that failed, one line each (empty on a pass).
    #[must_use]
    pub fn failed(&self) -> Vec<String> {
        self.checks.iter().filter(|c| !c.pass).map(Check::text).collect()
    }

    /// The verdict as `(key, text)` lines, in order: the one text every rendering shows.
    #[must_use]
    pub fn lines(&self) -> Vec<(&'static str, String)> {
        let mut l = Vec::new();
        let against = if self.checks.is_empty() { String::new() } else { format!(" against the {}", self.limits_from) };
        l.push(("verdict", format!("{}{against}: {}", self.outcome, self.answer)));
        // One clause per kind of figure, in the order first given: `what: axis value unit, …`.
        let mut clauses: Vec<(&str, Vec<String>)> = Vec::new();
        for e in &self.expect {
            let fig = format!("{} {} {}", e.axis, fmt_value(e.value), e.unit);
            match clauses.iter_mut().find(|(w, _)| *w == e.what) {
                Some((_, figs)) => figs.push(fig),
                None => clauses.push((&e.what, vec![fig])),
            }
        }
        if !clauses.is_empty() {
            let text: Vec<String> = clauses.iter().map(|(w, f)| format!("{w}: {}", f.join(", "))).collect();
            l.push(("expect in use", text.join("; ")));
        }
        l.push(("held-out", self.held_out.clone()));
        if let Some(c) = &self.covers {
            l.push(("covers", c.text()));
        }
        for c in &self.checks {
            l.push(("limit", c.text()));
        }
        for w in &self.warnings {
            l.push(("warning", w.clone()));
        }
        for f in &self.files {
            l.push(("file", format!("{}: {}", f.file, f.action)));
        }
        for a in &self.advice {
            l.push(("record next", a.clone()));
        }
        l
    }

    /// The console block: `key: text` per line.
    #[must_use]
    pub fn console(&self) -> String {
        self.lines().iter().map(|(k, t)| format!("{k}: {t}\n")).collect()
    }

    /// The `report.md` section: a `## Verdict` heading and one list item per line.
    #[must_use]
    pub fn markdown(&self) -> String {
        let mut s = String::from("## Verdict\n\n");
        for (k, t) in self.lines() {
            s.push_str(&format!("- **{k}:** {t}\n"));
        }
        s.push('\n');
        s
    }

    /// The page's verdict section (`<section id="verdict">`): one list item per line,
    /// a failed limit or a warning set off.
    pub fn to_page(&self, page: &mut Page) {
        let mut h =
            format!("<section id=\"{SECTION_ID}\" class=\"verdict {}\">\n<h2>Verdict</h2>\n<ul>\n", self.outcome);
        for (k, t) in self.lines() {
            let class = match k {
                "verdict" if self.outcome == Outcome::Fail => " class=\"fail\"",
                "verdict" if self.outcome == Outcome::Pass => " class=\"pass\"",
                "limit" if t.ends_with("(FAIL)") => " class=\"fail\"",
                "warning" => " class=\"warn\"",
                _ => "",
            };
            h.push_str(&format!("<li{class}><b>{}:</b> {}</li>\n", escape(k), escape(&t)));
        }
        h.push_str("</ul>\n</section>\n");
        page.raw(&h);
    }
}

impl Verdict {
    /// One verdict of several parts (the instances of an autopilot log, the units of a
    /// batch): every part's figures, checks, warnings and advice under its name; it fails
    /// when a part fails. `files` are the files the whole run wrote.
    #[must_use]
    pub fn merge(parts: &[(String, Verdict)], limits_from: &str, files: Vec<FileUse>) -> Self {
        let named = |n: &str, t: &str| format!("{n} {t}");
        let checks: Vec<Check> = parts
            .iter()
            .flat_map(|(n, v)| v.checks.iter().map(move |c| Check { axis: named(n, &c.axis), ..c.clone() }))
            .collect();
        let answer =
            parts.iter().map(|(n, v)| format!("{n} {}: {}", v.outcome, v.answer)).collect::<Vec<_>>().join("; ");
        let held_out = parts.iter().map(|(n, v)| format!("{n}: {}", v.held_out)).collect::<Vec<_>>().join("; ");
        let mut m = Self::new(answer, held_out, checks);
        if parts.iter().any(|(_, v)| v.outcome == Outcome::Fail) {
            m.outcome = Outcome::Fail;
        }
        m.limits_from = limits_from.to_string();
        for (n, v) in parts {
            m.expect.extend(v.expect.iter().map(|e| Expected { axis: named(n, &e.axis), ..e.clone() }));
            m.warnings.extend(v.warnings.iter().map(|w| format!("{n}: {w}")));
            m.advice.extend(v.advice.iter().map(|a| format!("{n}: {a}")));
        }
        m.files = files;
        m
    }
}

/// In `report.json`: the structured fields and the same lines the other renderings show.
impl Serialize for Verdict {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        #[derive(Serialize)]
        struct Json<'a> {
            outcome: Outcome,
            answer: &'a str,
            lines: Vec<String>,
            expect: &'a [Expected],
            held_out: &'a str,
            // A study without a table covers nothing: the key is left out, never null.
            #[serde(skip_serializing_if = "Option::is_none")]
            covers: &'a Option<Covers>,
            // A study checks no limit, so it names no source of limits: the key is left
            // out, never an empty string.
            #[serde(skip_serializing_if = "Option::is_none")]
            limits_from: Option<&'a str>,
            checks: &'a [Check],
            warnings: &'a [String],
            files: &'a [FileUse],
            record_next: &'a [String],
        }
        Json {
            outcome: self.outcome,
            answer: &self.answer,
            lines: self.lines().into_iter().map(|(k, t)| format!("{k}: {t}")).collect(),
            expect: &self.expect,
            held_out: &self.held_out,
            covers: &self.covers,
            limits_from: (!self.checks.is_empty()).then_some(self.limits_from.as_str()),
            checks: &self.checks,
            warnings: &self.warnings,
            files: &self.files,
            record_next: &self.advice,
        }
        .serialize(s)
    }
}

/// A report's JSON with the verdict as its first key: `{"verdict": …, "report": …}`.
///
/// # Errors
/// The report does not serialize.
pub fn json_with_verdict<T: Serialize>(verdict: &Verdict, report: &T) -> serde_json::Result<String> {
    #[derive(Serialize)]
    struct Both<'a, T> {
        verdict: &'a Verdict,
        #[serde(flatten)]
        report: &'a T,
    }
    serde_json::to_string_pretty(&Both { verdict, report })
}

/// Pass/fail limits (`limits.toml`; every key optional, a missing key keeps its default).
/// The defaults are starting points, not a standard: a production engineer sets their own.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[serde(default, deny_unknown_fields)]
pub struct Limits {
    /// Static (MEMS) logs: each axis's held-out bias RMS over rows must not exceed this,
    /// mg. Default 5.0 (the real IMU log's worst axis is 2.01 with our model, 5.94 with
    /// the PX4 cubic).
    pub held_out_bias_mg: f64,
    /// Cycling (QFA) logs: the held-out bias residual RMS must not exceed this, µg.
    /// Default 50 (simulated JB-KT8 units: about 9).
    pub held_out_bias_ug: f64,
    /// Cycling logs: the held-out Table-4 scale-factor sensitivity must not exceed this,
    /// ppm/°C. Default 1.0 (simulated JB-KT8 units: 0.28–0.34 over three draws; the paper's: 2.48–5.19).
    pub held_out_sensitivity_ppm_per_c: f64,
    /// Every log: the temperature span the table is fitted over must reach this, °C.
    /// Default 30.
    pub min_span_c: f64,
}

impl Default for Limits {
    fn default() -> Self {
        Self { held_out_bias_mg: 5.0, held_out_bias_ug: 50.0, held_out_sensitivity_ppm_per_c: 1.0, min_span_c: 30.0 }
    }
}

/// The text of a limits file.
fn read_limits(path: &Path) -> Result<String, LimitsError> {
    std::fs::read_to_string(path).map_err(|e| LimitsError::Read {
        file: path.to_path_buf(),
        kind: e.kind(),
        os_code: e.raw_os_error(),
    })
}

impl Limits {
    /// The limits in `path`, checked.
    ///
    /// # Errors
    /// The file cannot be read, is not the documented TOML, or holds a value outside its
    /// unit's range.
    pub fn from_file(path: &Path) -> Result<Self, LimitsError> {
        Self::from_toml(&read_limits(path)?).map_err(|e| match e {
            LimitsError::Parse { file: None, error } => LimitsError::Parse { file: Some(path.to_path_buf()), error },
            other => other,
        })
    }

    /// Limits from TOML text, checked.
    ///
    /// # Errors
    /// See [`Limits::from_file`].
    pub fn from_toml(text: &str) -> Result<Self, LimitsError> {
        let l: Self = toml::from_str(text).map_err(|error| LimitsError::Parse { file: None, error })?;
        l.check()?;
        Ok(l)
    }

    /// Both sides of every key: positive and finite, and below a bound that only a unit
    /// mistake reaches.
    ///
    /// # Errors
    /// [`LimitsError::OutOfRange`] for the first key outside its range.
    pub fn check(&self) -> Result<(), LimitsError> {
        let keys: [(&'static str, f64, f64, f64, &'static str, &'static str); 4] = [
            ("held_out_bias_mg", self.held_out_bias_mg, 1e-3, 100.0, "mg", "a limit in µg belongs in held_out_bias_ug"),
            (
                "held_out_bias_ug",
                self.held_out_bias_ug,
                0.01,
                10_000.0,
                "µg",
                "a limit in mg belongs in held_out_bias_mg",
            ),
            (
                "held_out_sensitivity_ppm_per_c",
                self.held_out_sensitivity_ppm_per_c,
                1e-3,
                1_000.0,
                "ppm/°C",
                "ppm/°C: 1 ppm/°C is 1e-6 of the scale factor per degree",
            ),
            ("min_span_c", self.min_span_c, 0.0, 200.0, "°C", "a span in °C (in K it is the same number)"),
        ];
        for (key, value, lo, hi, unit, hint) in keys {
            if !(value.is_finite() && (lo..=hi).contains(&value)) {
                return Err(LimitsError::OutOfRange { key, value, lo, hi, unit, hint });
            }
        }
        Ok(())
    }

    /// The static-log checks: each axis's held-out bias RMS (rows), and the span.
    #[must_use]
    pub fn static_checks(&self, held_out_mg: &[(String, Measured)], span_c: f64) -> Vec<Check> {
        let mut c: Vec<Check> = held_out_mg
            .iter()
            .map(|(axis, v)| Check::new("held_out_bias_mg", axis, v.clone(), self.held_out_bias_mg, "max", "mg"))
            .collect();
        c.push(Check::new("min_span_c", "all", Measured::Value(span_c), self.min_span_c, "min", "°C"));
        c
    }

    /// The cycling-log checks: held-out sensitivity and bias residual, and the span.
    #[must_use]
    pub fn cycling_checks(
        &self,
        axis: &str,
        sensitivity_ppm_per_c: Measured,
        bias_ug: Measured,
        span_c: f64,
    ) -> Vec<Check> {
        vec![
            Check::new(
                "held_out_sensitivity_ppm_per_c",
                axis,
                sensitivity_ppm_per_c,
                self.held_out_sensitivity_ppm_per_c,
                "max",
                "ppm/°C",
            ),
            Check::new("held_out_bias_ug", axis, bias_ug, self.held_out_bias_ug, "max", "µg"),
            Check::new("min_span_c", "all", Measured::Value(span_c), self.min_span_c, "min", "°C"),
        ]
    }
}

/// The keys a static (MEMS) log is checked against.
pub const STATIC_KEYS: [&str; 2] = ["held_out_bias_mg", "min_span_c"];
/// The keys a cycling (QFA) log is checked against.
pub const CYCLING_KEYS: [&str; 3] = ["held_out_sensitivity_ppm_per_c", "held_out_bias_ug", "min_span_c"];

/// Where a run's limits came from, and whether a failure changes the exit status.
#[derive(Clone, Debug, Default, PartialEq)]
pub struct LimitsChoice {
    /// The limits.
    pub limits: Limits,
    /// The file they came from (`None`: the defaults, which are reported but never change
    /// the exit status).
    pub file: Option<std::path::PathBuf>,
    /// The keys the file sets (every other key keeps its default).
    pub keys_set: Vec<String>,
}

impl LimitsChoice {
    /// From `--limits` (or the defaults without it).
    ///
    /// # Errors
    /// See [`Limits::from_file`].
    pub fn from_arg(file: Option<&Path>) -> Result<Self, LimitsError> {
        let Some(p) = file else { return Ok(Self::default()) };
        let text = read_limits(p)?;
        let parse = |error| LimitsError::Parse { file: Some(p.to_path_buf()), error };
        // The keys set come from the text as a table: `Limits` fills the missing ones.
        let table: toml::Table = toml::from_str(&text).map_err(parse)?;
        let limits = Limits::from_toml(&text).map_err(|e| match e {
            LimitsError::Parse { file: None, error } => parse(error),
            other => other,
        })?;
        Ok(Self { limits, file: Some(p.to_path_buf()), keys_set: table.keys().cloned().collect() })
    }

    /// A file that sets none of the keys a log of this kind is checked against would leave
    /// only defaults in force under the file's name: refused.
    ///
    /// # Errors
    /// [`LimitsError::NoneApply`].
    pub fn check_applies(&self, kind: &'static str, keys: &[&'static str]) -> Result<(), LimitsError> {
        match &self.file {
            Some(p) if !keys.iter().any(|k| self.keys_set.iter().any(|s| s == k)) => Err(LimitsError::NoneApply {
                file: p.display().to_string(),
                kind,
                set: self.keys_set.clone(),
                checked: keys.to_vec(),
            }),
            _ => Ok(()),
        }
    }

    /// How the verdict names them.
    #[must_use]
    pub fn source(&self) -> String {
        match &self.file {
            None => "default limits (the lab guide's \"Limits\"; --limits FILE sets yours)".to_string(),
            Some(p) => format!("limits in {}", p.display()),
        }
    }

    /// How the verdict names the limits behind `checks`: the file's keys, and which of the
    /// checked keys kept their defaults.
    #[must_use]
    pub fn source_for(&self, checks: &[Check]) -> String {
        if self.file.is_none() {
            return self.source();
        }
        let mut defaults: Vec<&str> =
            checks.iter().map(|c| c.limit).filter(|k| !self.keys_set.iter().any(|s| s == k)).collect();
        defaults.dedup();
        if defaults.is_empty() {
            self.source()
        } else {
            format!("{} (defaults for {})", self.source(), defaults.join(", "))
        }
    }

    /// Whether `verdict` must end the command with [`EXIT_LIMIT_FAILED`].
    #[must_use]
    pub fn enforced_failure(&self, verdict: &Verdict) -> bool {
        self.file.is_some() && verdict.outcome == Outcome::Fail
    }
}

#[cfg(test)]
mod tests;
