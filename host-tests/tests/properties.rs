//! Property tests (proptest) over arbitrary input sequences and tables, and the fuzz
//! harnesses over a fixed corpus (the same functions the cargo-fuzz targets call).

use host_tests::fuzzing;
use proptest::collection::vec;
use proptest::prelude::*;
use qfa_thermal::model::{AxisModel, AxisState, BiasGrid, BranchHysteresis, Creep, Extensions, ScaleFactor, SensorLag};
use qfa_thermal::rate::{RateConfig, RateEstimator};
use qfa_thermal::Table;

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
    let mut rng = qfa_rng::seeded(7);
    let mut n = 0;
    for len in [0usize, 1, 2, 9, 16, 17, 64, 255, 1024] {
        for _ in 0..40 {
            let data: Vec<u8> = (0..len).map(|_| (qfa_rng::uniform(&mut rng) * 256.0) as u8).collect();
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

/// A random axis model for the table property: grids of 2..=16 nodes with steps from
/// `MIN_GRID_STEP_C` (often within 0.05 °C of it) to the whole −60..130 °C range, node
/// values anywhere in ±`BIAS_G` (often exactly at a bound), Eq. 11 coefficients scaled so
/// the triangle bound `validate` checks lands anywhere from 0 to 1.1 times its limit of
/// `MAX_RELATIVE_DEVIATION·γ` (so a good share of the models sit at the edge, and some are
/// refused), rate limits in (0, 20] °C/min, and each extension slot on or off.
fn axis_model() -> impl Strategy<Value = AxisModel> {
    use qfa_thermal::table::limits as l;
    let node = prop_oneof![4 => -l::BIAS_G..=l::BIAS_G, 1 => Just(l::BIAS_G), 1 => Just(-l::BIAS_G)];
    let step = prop_oneof![
        2 => l::MIN_GRID_STEP_C..l::MIN_GRID_STEP_C + 0.05,
        1 => Just(l::MIN_GRID_STEP_C),
        2 => l::MIN_GRID_STEP_C..30.0f32,
    ];
    let grid = (2usize..=16)
        .prop_flat_map(move |n| (step.clone(), 0.0f32..=1.0, vec(node.clone(), n), vec(node.clone(), n), 0.0f32..=10.0))
        .prop_map(|(step, at, heating, cooling, deadband)| {
            let n = heating.len();
            let (lo, hi) = l::TEMP_C;
            let step = step.min((hi - lo) / (n - 1) as f32);
            let span = step * (n - 1) as f32;
            let t_start_c = (lo + at * (hi - lo - span)).clamp(lo, hi);
            BiasGrid {
                t_start_c,
                t_step_c: step,
                deadband_c_per_min: deadband,
                heating_g: heapless::Vec::from_slice(&heating).unwrap(),
                cooling_g: heapless::Vec::from_slice(&cooling).unwrap(),
                residual_rms_g: BiasGrid::DEFAULT_RESIDUAL_RMS_G,
            }
        });
    let lag = prop::option::of((l::LAG_TAU_S.0..=l::LAG_TAU_S.1).prop_map(|tau_s| SensorLag { tau_s }));
    let play = prop::option::of(
        (l::PLAY_HALF_WIDTH_C.0..=l::PLAY_HALF_WIDTH_C.1, -l::PLAY_WEIGHT_G..=l::PLAY_WEIGHT_G)
            .prop_map(|(half_width_c, weight_g)| BranchHysteresis { half_width_c, weight_g }),
    );
    let creep = prop::option::of(
        (
            -l::CREEP_GAIN_G_PER_C..=l::CREEP_GAIN_G_PER_C,
            l::CREEP_TAU_S.0..=l::CREEP_TAU_S.1,
            l::TEMP_C.0..=l::TEMP_C.1,
            0.0f32..=l::CREEP_ACTIVATION_K,
        )
            .prop_map(|(gain_g_per_c, tau_ref_s, t_ref_c, activation_k)| Creep {
                gain_g_per_c,
                tau_ref_s,
                t_ref_c,
                activation_k,
            }),
    );
    let rate_limit = prop_oneof![1 => Just(l::RATE_C_PER_MIN), 4 => 1e-3f32..=l::RATE_C_PER_MIN];
    let terms =
        (any::<[bool; 5]>(), [0.0f32..=1.0, 0.0f32..=1.0, 0.0f32..=1.0, 0.0f32..=1.0, 0.0f32..=1.0], 0.0f32..=1.1);
    (grid, l::TEMP_C.0..=l::TEMP_C.1, 0.0f32..=9.0, terms, rate_limit, (lag, play, creep)).prop_map(
        |(bias, t0_c, log_gamma, (signs, weights, fraction), rate_limit, (lag, play, creep))| {
            let gamma = 10f32.powf(log_gamma);
            let d = (bias.t_start_c - t0_c).abs().max((bias.t_end_c() - t0_c).abs());
            let r = rate_limit;
            // |α|r² + |β|d² + |η|rd + |ε|r + |μ|d = fraction·0.5·γ, shared by the weights.
            let total: f32 = weights.iter().sum::<f32>().max(1e-6);
            let budget = fraction * l::MAX_RELATIVE_DEVIATION * gamma;
            let coef = |i: usize, m: f32| {
                let c = if m > 0.0 { budget * weights[i] / total / m } else { 0.0 };
                if signs[i] {
                    c
                } else {
                    -c
                }
            };
            let scale = ScaleFactor {
                t0_c,
                gamma,
                alpha: coef(0, r * r),
                beta: coef(1, d * d),
                eta: coef(2, r * d),
                epsilon: coef(3, r),
                mu: coef(4, d),
            };
            let ext = Extensions { sensor_lag: lag, bias_branch_hysteresis: play, bias_creep: creep };
            AxisModel { scale, bias, rate_limit_c_per_min: rate_limit, ext }
        },
    )
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 256, max_global_rejects: 4096, ..ProptestConfig::default() })]

    /// Every table that passes `Table::validate` keeps K1 within
    /// `MAX_RELATIVE_DEVIATION·γ` of γ (so K1 > γ/2 > 0) at every temperature and rate,
    /// inside the calibrated box and outside it (clamped), and without extension slots keeps
    /// |K0| within `BIAS_G` and between the grid's smallest and largest node. `BIAS_G` bounds
    /// the grid only (its doc): with the slots on, the documented terms add at most their own
    /// size (the play term `weight·(Te − p)/r` with p within r of Te is at most |weight|, the
    /// creep term `gain·(Te − x)` with x a lag of Te inside the grid at most |gain|·span), so
    /// a validated table can reach |K0| = 0.1 + 0.01 + 1e-3·190 = 0.3 g.
    ///
    /// Seen failing (not committed) with the validation bound loosened to 0.9·γ (K1 1.52 for
    /// γ = 1) and with the interpolation fraction unclamped (K0 past its nodes).
    #[test]
    fn validated_tables_bound_k0_and_k1_everywhere(a in axis_model(), seed in any::<u64>()) {
        use qfa_thermal::table::limits as l;
        let mut t = Table { input: qfa_thermal::Input::PulseCounts, rate_window: 32, axes: heapless::Vec::new(), misalignment: None, part_lsb_per_g: None };
        t.axes.push(a.clone()).unwrap();
        prop_assume!(t.validate().is_ok());
        let g = &a.bias;
        let (t_lo, t_hi) = (g.t_start_c, g.t_end_c());
        let nodes = g.heating_g.iter().chain(g.cooling_g.iter());
        let (k0_min, k0_max) = nodes.fold((f32::INFINITY, f32::NEG_INFINITY), |(lo, hi), &v| (lo.min(v), hi.max(v)));
        // f32 rounding of the slot terms: Te ± r and the lag step land within an ulp of
        // where they should (ulp of |T| ≤ 130 °C: 2⁻¹⁶ °C), so the play fraction can exceed 1
        // by 2 ulp/r and the creep distance the span by 2 ulp (see play_term_can_exceed_its_weight).
        let ulp = 2f64.powi(-16);
        let play = a.ext.bias_branch_hysteresis.map_or(0.0, |h| {
            f64::from(h.weight_g.abs()) * (1.0 + 2.0 * ulp / f64::from(h.half_width_c))
        });
        let creep = a.ext.bias_creep.map_or(0.0, |c| f64::from(c.gain_g_per_c.abs()) * (f64::from(t_hi - t_lo) + 2.0 * ulp));
        // And a few ulps for the grid's interpolation and the two f32 additions.
        let k0_bound = (f64::from(l::BIAS_G) + play + creep) * (1.0 + 4.0 * 2f64.powi(-23));
        let slots = a.ext != Extensions::default();
        // Temperatures: a sweep past both ends of the TEMP_C box, the grid's ends and every
        // node ± a few ulps, and the reference T0.
        let mut temps: Vec<f32> = (0..=600).map(|i| -100.0 + 0.5 * i as f32).collect();
        for i in 0..g.heating_g.len() {
            let x = t_lo + g.t_step_c * i as f32;
            temps.extend([x, f32::from_bits(x.to_bits() + 2), f32::from_bits(x.to_bits().saturating_sub(2)), x + 0.5 * g.t_step_c]);
        }
        temps.extend([t_lo, t_hi, t_lo - 1e-3, t_hi + 1e-3, a.scale.t0_c, -1e6, 1e6]);
        let lim = a.rate_limit_c_per_min;
        let db = g.deadband_c_per_min;
        let rates = [-1e3, -40.0, -lim - 1.0, -lim, -0.5 * lim, -db - 0.01, 0.0, db + 0.01, 0.5 * lim, lim, lim + 1.0, 40.0, 1e3];
        let mut rng = qfa_rng::seeded(seed);
        let mut walk = AxisState::default();
        let mut n = 0u32;
        for &temp in temps.iter().chain(temps.iter().rev()) {
            for &rate in &rates {
                let dt = [0.0f32, 1.0, 60.0, 1e4][(qfa_rng::uniform(&mut rng) * 4.0) as usize];
                // A fresh state and one that walked through every point so far (branches,
                // lag, play and creep states in every configuration the walk reaches).
                let fresh = a.evaluate(&mut AxisState::default(), temp, rate, dt);
                let walked = a.evaluate(&mut walk, temp, rate, dt);
                // The element behind a lag, and the creep state, may be outside the range
                // while the reading is not.
                // The states follow the reading held to what a table may describe (−60…130 °C).
                let read = temp.clamp(-60.0, 130.0);
                let walked_te = if a.ext.sensor_lag.is_some() { walk.element_c } else { read };
                let walked_creep = if a.ext.bias_creep.is_some() { walk.creep_c } else { read };
                for (e, te, creep) in [(fresh, read, read), (walked, walked_te, walked_creep)] {
                    n += 1;
                    prop_assert!(e.k1.is_finite() && e.k0.is_finite(), "{temp} {rate}: {e:?}");
                    let dev = (f64::from(e.k1) - f64::from(a.scale.gamma)).abs();
                    prop_assert!(
                        dev <= f64::from(l::MAX_RELATIVE_DEVIATION) * f64::from(a.scale.gamma),
                        "K1 {} vs γ {} at {temp} °C, {rate} °C/min", e.k1, a.scale.gamma
                    );
                    prop_assert!(e.k1 > 0.0);
                    if slots {
                        prop_assert!(f64::from(e.k0).abs() <= k0_bound, "K0 {} at {temp} °C, {rate} °C/min ({k0_bound})", e.k0);
                    } else {
                        // One f32 ulp of slack: `a + (b − a)·frac` rounds, and can land one ulp past
                        // the node it reaches (grid_interpolation_can_leave_its_nodes_by_one_ulp).
                        let ulp = |x: f32| f64::from(x.abs()) * 2f64.powi(-23);
                        let k0 = f64::from(e.k0);
                        prop_assert!(k0.abs() <= f64::from(l::BIAS_G) + ulp(l::BIAS_G), "K0 {} at {temp} °C, {rate} °C/min", e.k0);
                        prop_assert!(
                            k0 >= f64::from(k0_min) - ulp(k0_min) && k0 <= f64::from(k0_max) + ulp(k0_max),
                            "K0 {} outside the nodes [{k0_min}, {k0_max}] at {temp} °C, {rate} °C/min", e.k0
                        );
                    }
                    let outside = |x: f32| !(t_lo..=t_hi).contains(&x);
                    let held = a.ext.bias_creep.is_some() && (te.clamp(t_lo, t_hi) - creep).abs() > t_hi - t_lo;
                    prop_assert_eq!(e.temp_clamped, outside(temp) || outside(te) || held);
                    prop_assert_eq!(e.rate_clamped, !(-lim..=lim).contains(&rate));
                }
            }
        }
        prop_assert!(n > 10_000);
    }
}

/// The play term of `bias_branch_hysteresis` is `weight·(Te − p)/r` with p kept within r of
/// Te, so it should never exceed |weight| (model docs: "+weight after sustained heating").
/// In f32, Te − r and Te + r round to the ulp of Te (7.6e-6 °C at 90 °C), so with the
/// smallest half-width the table allows (0.01 °C) the fraction reaches 1.0002 and K0
/// overshot by 2e-6 g (0.02 % of the weight) until the fraction was clamped to ±1 in
/// `AxisModel::evaluate_with_deadband`. Found by `validated_tables_bound_k0_and_k1_everywhere`.
#[test]
fn play_term_can_exceed_its_weight() {
    let h = BranchHysteresis { half_width_c: 0.01, weight_g: 0.009_255_718 };
    let a = AxisModel {
        scale: ScaleFactor::simple(22.0, 320_000.0, 0.0),
        bias: BiasGrid::single_valued(0.0, 10.0, &[0.0; 14]).expect("2 to 16 grid values"),
        rate_limit_c_per_min: 20.0,
        ext: Extensions { bias_branch_hysteresis: Some(h), ..Extensions::default() },
    };
    let mut s = AxisState::default();
    let mut worst = 0.0f32;
    for i in 0..=2_000 {
        // Heating from 80 to 100 °C: after the first 2r the play term sits at +weight.
        let e = a.evaluate(&mut s, 80.0 + 0.01 * i as f32, 1.0, 1.0);
        worst = worst.max(e.k0);
    }
    assert!(worst <= h.weight_g, "play term {worst} g above its weight {} g", h.weight_g);
}

/// `BiasGrid::interpolate` promises that K0 "never leaves the two nodes it lies between,
/// whatever rounding does to x", so a validated grid bounds |K0| by `BIAS_G`. At the top
/// node `a + (b − a)·1` rounds: with nodes −0.048831895 and 0.1 g it gives 0.10000001 g,
/// one ulp above the node and above `BIAS_G` (7e-9 g), until the interpolated value was
/// held to `[min(a, b), max(a, b)]`. Found by
/// `validated_tables_bound_k0_and_k1_everywhere` (its minimal case, kept here).
#[test]
fn grid_interpolation_can_leave_its_nodes_by_one_ulp() {
    let mut bias = BiasGrid::single_valued(-17.964_062, 0.1, &[0.0, 0.0]).expect("2 to 16 grid values");
    bias.cooling_g = heapless::Vec::from_slice(&[-0.048_831_895, 0.1]).unwrap();
    bias.deadband_c_per_min = 0.0;
    let a = AxisModel {
        scale: ScaleFactor::simple(0.0, 1.0, 0.0),
        bias,
        rate_limit_c_per_min: 20.0,
        ext: Extensions::default(),
    };
    let mut t = Table {
        input: qfa_thermal::Input::PulseCounts,
        rate_window: 32,
        axes: heapless::Vec::new(),
        misalignment: None,
        part_lsb_per_g: None,
    };
    t.axes.push(a.clone()).unwrap();
    t.validate().unwrap();
    // Above the grid, cooling: the top node of the cooling branch, 0.1 g.
    let e = a.evaluate(&mut AxisState::default(), -17.5, -1_000.0, 1.0);
    assert!(e.k0 <= qfa_thermal::table::limits::BIAS_G, "K0 {} above BIAS_G", e.k0);
}
