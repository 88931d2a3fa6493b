//! The compensator driven by a byte stream of mixed events: no panic, finite outputs,
//! rejected readings and tables change nothing, staleness flagged.
//!
//! The harness is `host_tests::fuzzing::compensator_stream`, which `cargo test` also runs over the
//! fixed corpus (host-tests/tests/properties.rs).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| host_tests::fuzzing::compensator_stream(data));
