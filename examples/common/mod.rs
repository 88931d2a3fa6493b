//! Code the QEMU examples share, each with `mod common;` (the demo needs none of it).
// Each example uses the part it needs: the size measurements the quiet HardFault exit, the
// programs that run the console and the exits that print.
#![allow(dead_code)]

#[cfg(target_os = "none")]
pub mod rt;
