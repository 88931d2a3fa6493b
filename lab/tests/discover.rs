//! Discovery workflow (issue 4) on synthetic data made by the root crate's AxisModel with
//! hidden slots on: each catalog effect is named, its parameter recovered within 25 %,
//! and the held-out gap of its channel shrinks ≥ 3× or to within 1.5× the noise floor.

use qfa_lab::discover::synth::{cycling_channels, kt8_1_scale, truth, SynthConfig};
use qfa_lab::discover::{analyze, Gaps, Report, Start};
use qfa_thermal::model::{BranchHysteresis, Creep, Extensions, ScaleFactor, SensorLag};

fn simple_scale() -> ScaleFactor {
    ScaleFactor::simple(22.0, 320_320.0, -32.76)
}

fn run(cfg: &SynthConfig, scale: ScaleFactor, bias: [f32; 3], ext: Extensions, start: Start) -> Report {
    let m = truth(scale, bias, ext);
    let ch = cycling_channels(cfg, &m, 60.0);
    let t = std::time::Instant::now();
    let r = analyze(&ch, start);
    eprintln!(
        "{:.1} s: effects {:?}\n  before {:?}\n  after {:?}\n  floor {:?}",
        t.elapsed().as_secs_f64(),
        r.effects.iter().map(|e| (&e.name, &e.channel, &e.params, e.heldout_gap_before, e.heldout_gap_after)).collect::<Vec<_>>(),
        r.heldout_gap_before,
        r.heldout_gap_after,
        r.noise_floor
    );
    for (i, round) in r.rounds.iter().enumerate() {
        for c in round {
            eprintln!("  round {i} {:24} gain {:10.1} pen {:5.1} {}", c.name, c.gain, c.penalty, c.significant);
        }
    }
    r
}

fn names(r: &Report) -> Vec<&str> {
    r.effects.iter().map(|e| e.name.as_str()).collect()
}

fn channel_gaps(r: &Report, channel: &str) -> (f64, f64, f64) {
    let pick = |g: &Gaps| match (g, channel) {
        (Gaps::Cycling { scale_factor_ppm, .. }, "scale_factor") => *scale_factor_ppm,
        (Gaps::Cycling { bias_ug, .. }, _) => *bias_ug,
        (Gaps::Single { value_rms }, _) => *value_rms,
    };
    (pick(&r.heldout_gap_before), pick(&r.heldout_gap_after), pick(&r.noise_floor))
}

fn assert_shrinks(r: &Report, channel: &str) {
    let (b, a, floor) = channel_gaps(r, channel);
    assert!(b >= 3.0 * a || a <= 1.5 * floor, "{channel}: gap {b} -> {a}, floor {floor}");
}

fn param(r: &Report, name: &str, p: &str) -> f64 {
    r.effects.iter().find(|e| e.name == name).and_then(|e| e.params.get(p).copied()).unwrap_or(f64::NAN)
}

fn within(got: f64, want: f64, tol: f64) {
    assert!((got - want).abs() <= tol * want.abs(), "{got} vs {want}");
}

fn quick(seed: u64) -> SynthConfig {
    SynthConfig { seed, ..SynthConfig::default() }
}

#[test]
fn discover_sensor_lag() {
    for (seed, tau) in [(1u64, 600.0f32), (2, 300.0)] {
        let ext = Extensions { sensor_lag: Some(SensorLag { tau_s: tau }), ..Default::default() };
        let r = run(&quick(seed), simple_scale(), [1e-4, 3e-6, 0.0], ext, Start::Simple);
        assert_eq!(names(&r), ["sensor_lag"]);
        within(param(&r, "sensor_lag", "tau_s"), f64::from(tau), 0.25);
        assert_shrinks(&r, "scale_factor");
        assert_shrinks(&r, "bias");
    }
}
