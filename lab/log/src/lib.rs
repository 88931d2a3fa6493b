//! qfa-log, the lab's data layer: every log kind the lab reads or writes, and the channels the fitters
//! see. Data flows one way: a log ([`cycling`] or [`static_log`]) → its channels
//! ([`pairing`] for the ±1 g runs of a cycling log, [`channels`] for discovery's binned
//! series) → a fit (in qfa-calibrate) → a table → compensation and evaluation.

pub mod autopilot;
pub mod channels;
pub mod cycling;
pub(crate) mod dataflash;
pub mod io_fault;
pub(crate) mod lines;
pub mod open;
pub mod pairing;
pub mod replay;
pub mod robust;
pub(crate) mod single;
pub mod spelling;
pub mod static_log;
pub(crate) mod ulog;
pub mod units;

pub use io_fault::IoFault;
