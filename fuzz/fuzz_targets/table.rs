//! Table decoding: never panics; whatever decodes validates and re-encodes to the same bytes.
//!
//! The harness is `host_tests::fuzzing::table`, which `cargo test` also runs over the
//! fixed corpus (host-tests/tests/properties.rs).
#![no_main]

use libfuzzer_sys::fuzz_target;

fuzz_target!(|data: &[u8]| host_tests::fuzzing::table(data));
