use super::*;

fn kt8_1() -> ScaleFactor {
    // The test below checks it against the paper's Eq. 15 written out in literals.
    crate::fixtures::JB_KT8_1
}

fn axis(ext: Extensions) -> AxisModel {
    let grid: [f32; 14] = core::array::from_fn(|i| 1e-4 + 2e-7 * i as f32);
    AxisModel {
        scale: kt8_1(),
        bias: BiasGrid::single_valued(-60.0, 10.0, &grid).unwrap(),
        rate_limit_c_per_min: 2.0,
        ext,
    }
}

#[test]
fn eq11_matches_f64() {
    let s = kt8_1();
    for &(t, r) in &[(22.0f32, 0.0f32), (-60.0, -0.9), (70.0, 0.9), (0.0, 0.3)] {
        let (d, rr) = (f64::from(t) - 22.0, f64::from(r));
        let want = 273.0 * rr * rr + 0.1008 * d * d - 0.02409 * rr * d + 88.14 * rr - 32.76 * d + 320_320.0;
        let got = f64::from(s.k1(t, r));
        assert!((got - want).abs() / want < 2e-7, "{t} {r}: {got} vs {want}");
    }
}

#[test]
fn branch_deadband_does_not_chatter() {
    let mut b = Branch::Unknown;
    b = b.next(0.04, 0.05);
    assert_eq!(b, Branch::Unknown);
    b = b.next(0.3, 0.05);
    assert_eq!(b, Branch::Heating);
    for r in [0.04, -0.04, 0.0, -0.05] {
        b = b.next(r, 0.05);
        assert_eq!(b, Branch::Heating);
    }
    assert_eq!(b.next(-0.06, 0.05), Branch::Cooling);
}

#[test]
fn bias_grid_interpolates_and_selects_branch() {
    let mut g = BiasGrid::single_valued(0.0, 10.0, &[0.0, 1.0, 3.0]).unwrap();
    g.cooling_g = heapless::Vec::from_slice(&[1.0, 2.0, 4.0]).unwrap();
    assert_eq!(g.k0(5.0, Branch::Heating), 0.5);
    assert_eq!(g.k0(15.0, Branch::Cooling), 3.0);
    assert_eq!(g.k0(20.0, Branch::Heating), 3.0);
    assert_eq!(g.k0(5.0, Branch::Unknown), 1.0);
    assert_eq!(g.t_end_c(), 20.0);
}

/// `advance` steps every state (and its doubt) as `evaluate` does, bit for bit, and
/// returns the clamped inputs `evaluate` used: over a random walk through the grid's
/// range and beyond, rates past the limit, and a dt of 0 now and then, with every
/// extension on.
#[test]
fn advance_steps_the_states_as_evaluate_does() {
    let m = axis(Extensions {
        sensor_lag: Some(SensorLag { tau_s: 90.0 }),
        bias_branch_hysteresis: Some(BranchHysteresis { half_width_c: 1.5, weight_g: -2e-4 }),
        bias_creep: Some(Creep { gain_g_per_c: 3e-6, tau_ref_s: 1800.0, t_ref_c: 25.0, activation_k: 4000.0 }),
    });
    let (mut by_evaluate, mut by_advance) = (AxisState::default(), AxisState::default());
    let mut x = 0x9e37_79b9_u32;
    let mut next = || {
        x ^= x << 13;
        x ^= x >> 17;
        x ^= x << 5;
        (x >> 8) as f32 / (1u32 << 24) as f32
    };
    let mut t = 20.0f32;
    for k in 0..20_000 {
        t += 4.0 * next() - 2.0;
        let rate = 8.0 * next() - 4.0;
        let dt = if k % 97 == 0 { 0.0 } else { 0.5 + next() };
        let e = m.evaluate_with_deadband(&mut by_evaluate, t, rate, dt, 0.2);
        let a = m.advance(&mut by_advance, t, rate, dt, 0.2);
        assert_eq!(by_evaluate, by_advance, "step {k}");
        assert_eq!((a.temp_clamped, a.rate_clamped), (e.temp_clamped, e.rate_clamped), "step {k}");
        assert!(a.rate_c_per_min.abs() <= m.rate_limit_c_per_min);
    }
}

#[test]
fn out_of_range_is_clamped_and_flagged() {
    let m = axis(Extensions::default());
    let mut s = AxisState::default();
    let e = m.evaluate(&mut s, 80.0, 5.0, 1.0);
    assert!(e.temp_clamped && e.rate_clamped);
    let mut s2 = AxisState::default();
    let at_edge = m.evaluate(&mut s2, 70.0, 2.0, 1.0);
    assert_eq!(e.k1, at_edge.k1);
    assert_eq!(e.k0, at_edge.k0);
}

#[test]
fn sensor_lag_follows_first_order_step_response() {
    let m = axis(Extensions { sensor_lag: Some(SensorLag { tau_s: 60.0 }), ..Default::default() });
    let mut s = AxisState::default();
    m.evaluate(&mut s, 20.0, 0.0, 1.0);
    for _ in 0..60 {
        m.evaluate(&mut s, 30.0, 0.0, 1.0);
    }
    // After one τ: 1 − e⁻¹ of the step.
    let want = 20.0 + 10.0 * (1.0 - (-1.0f64).exp());
    assert!((f64::from(s.element_c) - want).abs() < 1e-3, "{}", s.element_c);
}

#[test]
fn play_operator_persists_through_hold_and_switches_over_2r() {
    let h = BranchHysteresis { half_width_c: 2.0, weight_g: 1e-4 };
    let m = axis(Extensions { bias_branch_hysteresis: Some(h), ..Default::default() });
    let base = axis(Extensions::default());
    let mut s = AxisState::default();
    let mut sb = AxisState::default();
    let mut t = 0.0f32;
    let mut extra = 0.0f32;
    for _ in 0..100 {
        t += 0.1;
        extra = m.evaluate(&mut s, t, 0.0, 1.0).k0 - base.evaluate(&mut sb, t, 0.0, 1.0).k0;
    }
    assert!((extra - 1e-4).abs() < 1e-9, "heating saturates at +w: {extra}");
    for _ in 0..50 {
        extra = m.evaluate(&mut s, t, 0.0, 1.0).k0 - base.evaluate(&mut sb, t, 0.0, 1.0).k0;
    }
    assert!((extra - 1e-4).abs() < 1e-9, "hold keeps it");
    for _ in 0..20 {
        t -= 0.1;
        extra = m.evaluate(&mut s, t, 0.0, 1.0).k0 - base.evaluate(&mut sb, t, 0.0, 1.0).k0;
    }
    assert!(extra.abs() < 1e-8, "halfway after 2 °C of 4: {extra}");
}

#[test]
fn creep_tau_is_arrhenius() {
    let c = Creep { gain_g_per_c: 1e-6, tau_ref_s: 3600.0, t_ref_c: 25.0, activation_k: 5000.0 };
    assert!((c.tau_s(25.0) - 3600.0).abs() < 1e-2);
    let want = 3600.0 * (5000.0 * (1.0 / 358.15 - 1.0 / 298.15f64)).exp();
    assert!((f64::from(c.tau_s(85.0)) - want).abs() / want < 1e-5);
    assert!(c.tau_s(85.0) < c.tau_s(-55.0));
}

/// After power-up a lag state is flagged until its error bound has shrunk by e^(−t/τ)
/// below ¼ LSB. The bound at the start is what the history could have made of it: the
/// state is an average of past temperatures of the unit, held to the −60…130 °C any table
/// may describe, so no further from T than that range's farther end (110 °C from 20 °C):
/// t = τ·ln(110·64) = 8.86 τ, checked here against that formula to the second. While the
/// states were held to the grid it was the grid's farther end (80 °C on −60…70 °C, 8.54 τ);
/// before that, the grid's whole span (130 °C, 9.03 τ).
#[test]
fn a_lag_started_without_its_history_settles_when_its_bound_says() {
    let m = axis(Extensions { sensor_lag: Some(SensorLag { tau_s: 600.0 }), ..Default::default() });
    let bound_c = (130.0 - 20.0f64).max(20.0 - -60.0);
    assert_eq!(bound_c, 110.0);
    let want_s = 600.0 * (bound_c * 64.0).ln();
    let mut s = AxisState::default();
    let mut settled_at = None;
    for k in 0..20_000u32 {
        let e = m.evaluate(&mut s, 20.0, 0.0, if k == 0 { 0.0 } else { 1.0 });
        if !e.settling && settled_at.is_none() {
            settled_at = Some(f64::from(k));
        }
        assert_eq!(e.settling, settled_at.is_none(), "the flag never comes back at rest");
    }
    let got = settled_at.expect("settles");
    assert!((got - want_s).abs() <= 2.0, "settled after {got} s, the bound says {want_s:.0} s");
}

/// The real chamber log's z axis, as `qfa-lab calibrate` fits it: a grid over −18…74 °C, a
/// 30-s lag, a 600-s creep of 0.26 mg/°C, a rate limit of 11.1 °C/min, and a fit residual
/// of 2 mg. Powered up at 52 °C, the creep state may be as far as the farther end of the
/// −60…130 °C the states are held to (112 °C), 29.6 mg of bias; it is settled once that has
/// shrunk below a quarter of the residual, 0.5 mg: ln(59.3) = 4.08 τ, 41 min (36 min while
/// the states were held to the grid, whose farther end was 70 °C away). With the threshold at
/// 1 µg, as before the table recorded its residual, it took over 100 min: the whole 70-min
/// log was flagged.
#[test]
fn a_creep_settles_to_a_quarter_of_the_tables_residual() {
    let settle_min = |residual_rms_g: f32| {
        let mut bias = BiasGrid::single_valued(-18.0, 92.0 / 15.0, &[0.0; 16]).unwrap();
        bias.residual_rms_g = residual_rms_g;
        let m = AxisModel {
            scale: ScaleFactor::simple(22.0, 1_048_576.0, 0.0),
            bias,
            rate_limit_c_per_min: 11.148_451,
            ext: Extensions {
                sensor_lag: Some(SensorLag { tau_s: 30.0 }),
                bias_creep: Some(Creep {
                    gain_g_per_c: 2.645_932e-4,
                    tau_ref_s: 600.0,
                    t_ref_c: 22.0,
                    activation_k: 0.0,
                }),
                ..Extensions::NONE
            },
        };
        let mut s = AxisState::default();
        (0..20_000u32)
            .find(|&k| !m.evaluate(&mut s, 52.0, 0.0, if k == 0 { 0.0 } else { 1.0 }).settling)
            .map(|k| f64::from(k) / 60.0)
    };
    let want_min = 600.0 * (2.645_932e-4 * 112.0 / 0.5e-3f64).ln() / 60.0;
    let got = settle_min(2e-3).expect("settles");
    // The lag's own doubt feeds the creep's for its first minutes: a little later.
    assert!(got >= want_min && got < want_min + 2.0, "settled after {got:.1} min, the bound says {want_min:.1}");
    let strict = settle_min(BiasGrid::DEFAULT_RESIDUAL_RMS_G).expect("settles");
    assert!(strict > 95.0, "{strict:.1} min");
}

/// A play's term lies within its weight of zero whatever its state (`evaluate` holds the
/// fraction to ±1), so two states' terms differ by at most twice the weight, and the
/// play's position by at most twice its half-width plus the element's own doubt. After
/// power-up with a lag the play's doubt was floored at the lag's doubt times the play's
/// slope (80 °C × 60 µg/°C = 4.8 mg for a 30-µg play) and then shrank only as the play
/// moved: on a ±25-°C daily swing it stayed over its 1-µg threshold for hours, so
/// `MODEL_SETTLING` was set on every cycle of a 2.5-h soak. Now it is settled once the lag
/// has settled (τ·ln(80·64) = 342 s for τ 40 s) and the play has moved twice its
/// half-width: on a swing of 0.44 °C/min at its fastest, under 8 minutes.
#[test]
fn a_play_started_without_its_history_settles_once_it_has_moved_twice_its_half_width() {
    let m = axis(Extensions {
        sensor_lag: Some(SensorLag { tau_s: 40.0 }),
        bias_branch_hysteresis: Some(BranchHysteresis { half_width_c: 0.5, weight_g: 3e-5 }),
        ..Default::default()
    });
    let mut s = AxisState::default();
    let two_pi = 2.0 * core::f64::consts::PI;
    let settled_at = (0..9_000u32).find(|&k| {
        let t = f64::from(k);
        let temp = 20.0 + 25.0 * (two_pi * t / 21_600.0).sin();
        let rate = 25.0 * two_pi / 21_600.0 * 60.0 * (two_pi * t / 21_600.0).cos();
        !m.evaluate(&mut s, temp as f32, rate as f32, if k == 0 { 0.0 } else { 1.0 }).settling
    });
    let got = settled_at.expect("settles within the 2.5 h");
    assert!(got < 8 * 60, "settled after {got} s");
}
