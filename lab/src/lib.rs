//! qfa-lab: thermal-test simulator, calibration from four-position cycling logs, and the demo.
//!
//! The lab calls the root crate's own estimator (`RateEstimator<32>`), model
//! (`ScaleFactor`, `BiasGrid`, `Extensions`, `AxisModel::evaluate`), table (`Table`,
//! `encode`) and compensator (`Compensator<1, 32>`), never copies: what the lab fits is
//! what the firmware runs.
//!
//! Entry points for other tools:
//! * simulate: [`simulate::simulate_paper`], [`simulate::simulate`], [`simulate::Accelerometer`];
//! * truth over a temperature history: [`simulate::truth::Truth::model`] → [`simulate::truth::TruthModel::step`],
//!   or [`simulate::truth::TruthModel::over_history`];
//! * calibrate: [`calibrate::calibrate_log`] (in memory) and [`calibrate::calibrate_file`];
//! * firmware view of a run: [`data::pairing::trace_run`]; fitting with extension slots:
//!   [`calibrate::fit::fit`] with [`calibrate::fit::FitOptions::ext`];
//! * compensation: [`compensate::compensate_run`];
//! * static multi-axis logs (a board at one orientation, CSV/TSV):
//!   [`data::open::open`] → [`calibrate::static_cal::calibrate_static`]
//!   (per-axis [`calibrate::fit::fit_static_axis`], peers in [`calibrate::peers`]) → [`compensate::compensate_static`].

pub mod batch;
pub mod calibrate;
pub mod compensate;
pub mod data;
pub mod demo;
pub mod discover;
pub mod html_report;
pub mod lint;
pub mod navigate;
pub mod out_path;
pub mod plot_font;
pub mod plot_legend;
pub mod rng;
pub mod simulate;
pub mod spelling;
pub mod verdict;
