//! qfa-lab: thermal-test simulator, calibration from four-position cycling logs, and the demo.
//!
//! The lab calls the root crate's own estimator (`RateEstimator<32>`), model
//! (`ScaleFactor`, `BiasGrid`, `Extensions`, `AxisModel::evaluate`), table (`Table`,
//! `encode`) and compensator (`Compensator<1, 32>`), never copies: what the lab fits is
//! what the firmware runs.
//!
//! Entry points for other tools:
//! * simulate: [`sim::simulate_paper`], [`sim::simulate`], [`sim::Accelerometer`];
//! * truth over a temperature history: [`truth::Truth::model`] → [`truth::TruthModel::step`],
//!   or [`truth::TruthModel::over_history`];
//! * calibrate: [`calibrate::calibrate_log`] (in memory) and [`calibrate::calibrate_file`];
//! * firmware view of a run: [`pairing::trace_run`]; fitting with extension slots:
//!   [`fit::fit`] with [`fit::FitOptions::ext`];
//! * compensation: [`compensate::compensate_run`];
//! * static multi-axis logs (a board at one orientation, CSV/TSV):
//!   [`log::static_log::read_static`] → [`calibrate::static_cal::calibrate_static`]
//!   (per-axis [`fit::fit_static_axis`], peers in [`peers`]) → [`compensate::compensate_static`].

pub mod calibrate;
pub mod compensate;
pub mod demo;
pub mod discover;
pub mod fit;
pub mod log;
pub mod metrics;
pub mod pairing;
pub mod peers;
pub mod profile;
pub mod report;
pub mod sim;
pub mod thermal;
pub mod truth;
pub mod nav;
pub mod faults;
