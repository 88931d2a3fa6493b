//! Scratchpad decoding: an accepted reading has a valid CRC, masked low bits, a valid config byte and is not the power-on pattern.
//!
//! The harness is `host_tests::fuzzing::scratchpad`, which `cargo test` also runs over the
//! fixed corpus (host-tests/tests/properties.rs).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| host_tests::fuzzing::scratchpad(data));
