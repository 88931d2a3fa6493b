//! qfa-lab: the lab's command line and its demo. The work is done by the lab's crates:
//! `qfa_log` (readers and writers), `qfa_sim` (the simulator), `qfa_calibrate`
//! (calibration, discovery, batches, compensation, lint), `qfa_nav` (the navigation study)
//! and `qfa_report` (pages and verdicts).
//!
//! The lab calls the root crate's own estimator (`RateEstimator<32>`), model
//! (`ScaleFactor`, `BiasGrid`, `Extensions`, `AxisModel::evaluate`), table (`Table`,
//! `encode`) and compensator (`Compensator<1, 32>`), never copies: what the lab fits is
//! what the firmware runs.
//!
//! Entry points for other tools:
//! * simulate: [`qfa_sim::simulate_paper`], [`qfa_sim::simulate`], [`qfa_sim::Accelerometer`];
//! * truth over a temperature history: [`qfa_sim::truth::Truth::model`] → [`qfa_sim::truth::TruthModel::step`],
//!   or [`qfa_sim::truth::TruthModel::over_history`];
//! * calibrate: [`qfa_calibrate::calibrate_log`] (in memory) and [`qfa_calibrate::calibrate_file`];
//! * firmware view of a run: [`qfa_log::pairing::trace_run`]; fitting with extension slots:
//!   [`qfa_calibrate::fit::fit`] with [`qfa_calibrate::fit::FitOptions::ext`];
//! * compensation: [`qfa_calibrate::compensate::compensate_run`];
//! * static multi-axis logs (a board at one orientation, CSV/TSV):
//!   [`qfa_log::open::open`] → [`qfa_calibrate::static_cal::calibrate_static`]
//!   (per-axis [`qfa_calibrate::fit::fit_static_axis`], peers in [`qfa_calibrate::peers`]) → [`qfa_calibrate::compensate::compensate_static`].

pub mod demo;
pub mod out_path;
