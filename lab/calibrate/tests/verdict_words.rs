//! What the verdicts say in words: the cycling verdict's comparison with the bias-only
//! peers, both scored in the table's place (within the figures' resolution no warning,
//! beyond it one that says which peer), and what a static log's held-out leg looks like.

use qfa_calibrate::report::PeerBias;
use qfa_calibrate::verdict::{leg_shape, worse_than_a_peer};

#[test]
fn a_peer_within_the_figures_resolution_is_not_a_warning_beyond_it_is() {
    let p = PeerBias { cubic: 9.679, ardupilot: 10.04 };
    assert_eq!(worse_than_a_peer(9.684, p, true), None);
    assert_eq!(worse_than_a_peer(9.0, p, true), None);
    let w = worse_than_a_peer(9.80, p, true).expect("1.2 % worse");
    assert!(w.starts_with("the bias residual (9.80 µg) is worse held out than a bias-only peer"), "{w}");
    assert!(worse_than_a_peer(10.2, PeerBias { cubic: 11.0, ardupilot: 10.0 }, true).is_some());
    // A log of one program scores both in-sample, and the warning says so.
    let w = worse_than_a_peer(9.80, p, false).expect("1.2 % worse");
    assert!(w.starts_with("the bias residual (9.80 µg) is worse in-sample than a bias-only peer"), "{w}");
}

/// A held-out leg of an hour at 1-s rows, its residual `shape(t)` plus white noise of 0.1 mg
/// (a fixed pseudo-random sequence), at a steady temperature or on a ramp.
fn leg(shape: impl Fn(f64) -> f64, ramp: bool) -> Option<String> {
    let t: Vec<f64> = (0..3600).map(f64::from).collect();
    let mut z = 0x2545_F491_4F6C_DD1Du64;
    let noise = |_| {
        z ^= z << 13;
        z ^= z >> 7;
        z ^= z << 17;
        0.1 * ((z >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 12f64.sqrt()
    };
    let r: Vec<f64> = t.iter().map(|&x| shape(x)).zip(t.iter().map(noise)).map(|(a, b)| a + b).collect();
    let temp: Vec<f64> = t.iter().map(|&x| if ramp { 70.0 - x / 60.0 } else { 25.0 + (x * 0.01).sin() }).collect();
    leg_shape(&t, &r, &temp)
}

#[test]
fn a_later_legs_offset_is_called_a_shift_a_drift_or_a_settling_as_it_is() {
    let shift = leg(|_| 2.0, false).unwrap();
    assert!(shift.starts_with("over the later leg it looks like a shift:"), "{shift}");
    let drift = leg(|t| 1.0 + 1e-3 * t, false).unwrap();
    assert!(drift.starts_with("over the later leg it looks like a drift:"), "{drift}");
    let settling = leg(|t| 2.0 - 1.5 * (-t / 480.0).exp(), false).unwrap();
    assert!(settling.starts_with("over the later leg it looks like a settling:"), "{settling}");
    assert!(settling.contains("(τ 8 min)"), "{settling}");
    // On a ramp, time is temperature too: said.
    for text in [&shift, &drift, &settling] {
        assert!(!text.contains("move together"), "{text}");
    }
    let on_ramp = leg(|t| 1.0 + 1e-3 * t, true).unwrap();
    assert!(on_ramp.contains("time and temperature move together there (r = -1.00)"), "{on_ramp}");
    assert!(on_ramp.contains("record a hold at one temperature after the run"), "{on_ramp}");
}
