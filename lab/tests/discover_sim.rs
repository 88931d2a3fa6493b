//! Discovery on the lab simulator's own logs (not the discovery module's synthetic data):
//! the paper's full four-rate, four-position test at 10-s rows, one catalog effect hidden
//! in the truth, start model `paper`.
//!
//! The noise floor that matters here is the simulator's bias instability (Gauss–Markov,
//! 10 µg over 1800 s): low-frequency, so the bin-to-bin floor in the report misses it.
//! The honest floor is the held-out residual of the same log simulated with nothing
//! hidden (same unit, same seed): each hidden effect must be named, its parameters
//! recovered within 25 %, and its channel's held-out gap shrunk ≥ 3× or to within 1.5×
//! of that baseline. Units, seeds and parameters differ from the truth presets.

use qfa_discover::{analyze, Channels, Gaps, Report, Start};
use qfa_log::cycling::write_log_to;
use qfa_sim::simulate_paper;
use qfa_sim::truth::Truth;
use qfa_thermal::model::{BranchHysteresis, Creep, SensorLag};

fn run(truth: &Truth, seed: u64) -> Report {
    let log = simulate_paper(truth, 10, seed, 1, None);
    let mut csv = Vec::new();
    write_log_to(&mut csv, &log).expect("in-memory CSV");
    let ch = Channels::parse(std::str::from_utf8(&csv).expect("utf-8"), 60.0).expect("parse");
    analyze(&ch, Start::Paper)
}

fn gaps(g: &Gaps) -> (f64, f64) {
    match g {
        Gaps::Cycling { scale_factor_ppm, bias_ug } => (*scale_factor_ppm, *bias_ug),
        Gaps::Single { .. } => panic!("cycling log expected"),
    }
}

fn within(got: f64, want: f64, rel: f64) -> bool {
    (got - want).abs() <= rel * want.abs()
}

/// Check one hidden-effect report against its no-effect baseline.
fn check(name: &str, r: &Report, base: &Report, params: &[(&str, f64)], sf: bool, bias: bool) {
    let names: Vec<&str> = r.effects.iter().map(|e| e.name.as_str()).collect();
    println!(
        "{name}: added {names:?}; gaps {:?} → {:?}; baseline {:?}",
        gaps(&r.heldout_gap_before),
        gaps(&r.heldout_gap_after),
        gaps(&base.heldout_gap_after)
    );
    for (i, round) in r.rounds.iter().enumerate() {
        for c in round {
            println!(
                "  round {i} {:24} gain {:9.1} se {:7.1} t {:6.2} crit {:5.2} {} {:?}",
                c.name, c.gain.gain, c.gain.se, c.gain.t, c.gain.critical, c.significant, c.at_bound
            );
        }
    }
    println!("  unexplained {:?}", r.unexplained);
    assert_eq!(names, [name], "exactly the hidden effect is named");
    let e = &r.effects[0];
    for &(p, want) in params {
        let got = e.params[p];
        println!("  {p}: {got:.6e} vs truth {want:.6e} ({:+.1} %)", 100.0 * (got / want - 1.0));
        assert!(within(got, want, 0.25), "{name}.{p} = {got} vs {want}");
    }
    let (sf0, b0) = gaps(&r.heldout_gap_before);
    let (sf1, b1) = gaps(&r.heldout_gap_after);
    let (sfn, bn) = gaps(&base.heldout_gap_after);
    if sf {
        assert!(sf1 <= (sf0 / 3.0).max(1.5 * sfn), "scale factor gap {sf0} → {sf1}, baseline {sfn}");
    }
    if bias {
        assert!(b1 <= (b0 / 3.0).max(1.5 * bn), "bias gap {b0} → {b1}, baseline {bn}");
    }
}

#[test]
fn discovery_names_each_effect_hidden_in_the_lab_simulator() {
    let unit1 = Truth::jb_kt8(1);
    let unit2 = Truth::jb_kt8(2);
    let unit3 = Truth::jb_kt8(3);
    let mut lag = unit2.clone();
    lag.ext.sensor_lag = Some(SensorLag { tau_s: 240.0 });
    let mut play = unit3.clone();
    play.ext.bias_branch_hysteresis = Some(BranchHysteresis { half_width_c: 1.5, weight_g: -15e-6 });
    let mut creep = unit1.clone();
    creep.ext.bias_creep = Some(Creep { gain_g_per_c: 3e-6, tau_ref_s: 3000.0, t_ref_c: 22.0, activation_k: 4000.0 });

    let cases = [(&unit1, 21), (&creep, 21), (&unit2, 22), (&lag, 22), (&unit3, 23), (&play, 23)];
    let reports: Vec<Report> = std::thread::scope(|s| {
        let handles: Vec<_> = cases.iter().map(|&(t, seed)| s.spawn(move || run(t, seed))).collect();
        handles.into_iter().map(|h| h.join().expect("discovery run")).collect()
    });

    let none: Vec<&str> = reports[0].effects.iter().map(|e| e.name.as_str()).collect();
    println!("nothing hidden (JB-KT8 #1): added {none:?}, gaps {:?}", gaps(&reports[0].heldout_gap_after));
    assert!(none.is_empty(), "nothing hidden must give none, got {none:?}");

    check("bias_creep", &reports[1], &reports[0], &[("gain_ug_per_c", 3.0), ("tau_ref_s", 3000.0)], false, true);
    check("sensor_lag", &reports[3], &reports[2], &[("tau_s", 240.0)], true, true);
    check(
        "bias_branch_hysteresis",
        &reports[5],
        &reports[4],
        &[("half_width_c", 1.5), ("weight_ug", -15.0)],
        false,
        true,
    );
}
