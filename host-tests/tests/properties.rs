//! Property tests (proptest) over arbitrary input sequences, and the fuzz harnesses over a
//! fixed corpus (the same functions the cargo-fuzz targets call).

use host_tests::fuzzing;
use proptest::prelude::*;
use qfa_thermal::rate::{RateConfig, RateEstimator};

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]

    #[test]
    fn compensator_stream_holds_its_properties(data in proptest::collection::vec(any::<u8>(), 0..600)) {
        fuzzing::compensator_stream(&data);
    }

    #[test]
    fn scratchpad_decoding_never_lies(sp in any::<[u8; 9]>()) {
        fuzzing::scratchpad(&sp);
    }

    #[test]
    fn table_decoding_never_panics(data in proptest::collection::vec(any::<u8>(), 0..400)) {
        fuzzing::table(&data);
    }

    #[test]
    fn mutated_tables_are_refused_or_valid(i in 0usize..4096, bit in 0u8..8) {
        let mut t = fuzzing::stream_table();
        let n = t.len();
        t[i % n] ^= 1 << bit;
        fuzzing::table(&t);
        // One flipped bit is always caught (CRC-32 detects every single-bit error).
        prop_assert!(qfa_thermal::Table::decode(&t).is_err());
    }

    /// Shifting every timestamp by the same offset (including across the u32 wrap) changes
    /// nothing: the estimator only sees time differences.
    #[test]
    fn rate_estimator_is_invariant_to_time_origin(
        offset in any::<u32>(),
        steps in proptest::collection::vec((1u32..5000, -40i16..40), 1..200),
    ) {
        let mut a = RateEstimator::<32>::new(RateConfig::default());
        let mut b = RateEstimator::<32>::new(RateConfig::default());
        let (mut t, mut y) = (0u32, 300i16);
        for (dt, dy) in steps {
            t = t.wrapping_add(dt);
            y = y.saturating_add(dy);
            let ra = a.push(t, y);
            let rb = b.push(t.wrapping_add(offset), y);
            prop_assert_eq!(ra, rb);
            prop_assert_eq!(a.estimate(), b.estimate());
            prop_assert!(a.estimate().is_none_or(|e| e.rate_c_per_min.is_finite()));
        }
    }
}

/// Fixed corpus for CI: seeds from the fuzz corpus folder plus deterministic pseudo-random
/// inputs, each through all three harnesses.
#[test]
fn fuzz_harnesses_over_fixed_corpus() {
    let mut rng = host_tests::scenarios::Lcg::new(7);
    let mut n = 0;
    for len in [0usize, 1, 2, 9, 16, 17, 64, 255, 1024] {
        for _ in 0..40 {
            let data: Vec<u8> = (0..len).map(|_| (rng.uniform() * 256.0) as u8).collect();
            fuzzing::scratchpad(&data);
            fuzzing::table(&data);
            fuzzing::compensator_stream(&data);
            n += 1;
        }
    }
    let good = fuzzing::stream_table();
    fuzzing::table(&good);
    assert!(qfa_thermal::Table::decode(&good).is_ok());
    println!("{n} corpus inputs through 3 harnesses");
    assert_eq!(n, 360);
}

/// Every file under `host-tests/fuzz-corpus/<target>/` through the harness of that
/// cargo-fuzz target: the seed inputs, and any crash a libFuzzer run found, kept as a
/// regression (see fuzz/README.md).
#[test]
fn fuzz_seed_files() {
    let root = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("fuzz-corpus");
    type Harness = fn(&[u8]);
    let harnesses: [(&str, Harness); 3] = [
        ("scratchpad", fuzzing::scratchpad),
        ("table", fuzzing::table),
        ("compensator_stream", fuzzing::compensator_stream),
    ];
    let mut n = 0;
    for (target, harness) in harnesses {
        let dir = root.join(target);
        let mut files: Vec<_> = std::fs::read_dir(&dir)
            .unwrap_or_else(|e| panic!("{}: {e}", dir.display()))
            .map(|e| e.unwrap().path())
            .collect();
        files.sort();
        assert!(!files.is_empty(), "no seed files in {}", dir.display());
        for f in files {
            let data = std::fs::read(&f).unwrap();
            harness(&data);
            n += 1;
        }
    }
    println!("{n} seed files through their harnesses");
}
