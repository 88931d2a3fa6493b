#![doc = include_str!("../README.md")]
#![cfg_attr(not(test), no_std)]
#![forbid(unsafe_code)]
#![warn(missing_docs)]

pub mod compensator;
pub mod ds18b20;
pub mod ds18b20_driver;
pub mod model;
pub mod onewire;
pub mod rate;
pub mod table;
pub mod time;

pub use compensator::{Applier, Compensator, Config, ConfigError, Output, Published, SampleError, Status, Updater, G0};
pub use model::{AxisModel, BiasGrid, Extensions, ScaleFactor};
pub use table::{Input, Table};
