//! The accelerometer triad's misalignment matrix in flight.
//!
//! The built-in scenario gives the triad a known non-orthogonality `I + K`
//! (`[imu.accel] triad_arcsec`, 20–45″ per term), and every table variant carries
//! `(I + K)⁻¹` as the 3-axis table's misalignment matrix. This flies the §3.2 flight at
//! 20 Hz with the `hysteresis` tables with and without the matrix, beside `simple` and the
//! oracle (both with it), on the same sensor data, and checks that the matrix matters:
//! without it the error against the oracle grows several times the thermal-only error left
//! with it. `cargo test -p qfa-lab --test nav_misalign -- --nocapture` prints the figures.

use nalgebra::Matrix3;
use qfa_nav::accel::{OracleCompensation, TableCompensation};
use qfa_nav::run::{self, Variant};
use qfa_nav::scenario::Scenario;
use qfa_nav::thermal_ceps;

#[test]
fn the_triad_misalignment_matrix_matters() {
    let mut sc = Scenario::builtin();
    sc.imu_rate_hz = 20.0;
    let a = sc.imu.accel;
    // The carried matrix undoes the triad (f32 rounding only), computed independently of
    // the lab's inverse: (I + K)·M = I.
    let m = a.carried_misalignment().expect("the built-in triad is misaligned");
    let mm = Matrix3::from_fn(|r, c| f64::from(m[r * 3 + c]));
    let k = a.triad_arcsec.map(|x| x / 206_264.806);
    let triad = Matrix3::new(1.0, k[0], k[1], k[2], 1.0, k[3], k[4], k[5], 1.0);
    let err = (triad * mm - Matrix3::identity()).abs().max();
    assert!(err < 1e-7, "(I + K)·M − I: {err}");
    assert!(k.iter().map(|x| x.abs()).fold(0.0, f64::max) > 1e-4, "K is not negligible");

    let units = qfa_nav::units();
    let tables = qfa_nav::calibrate_with(&units, sc.seed, 2, false).unwrap();
    let u = &tables.units;
    let h = [&u[0].hysteresis, &u[1].hysteresis, &u[2].hysteresis];
    let s = [&u[0].simple, &u[1].simple, &u[2].simple];
    let variants = vec![
        Variant { name: "oracle".into(), comp: Box::new(OracleCompensation::carrying(a.triad_inverse())) },
        Variant {
            name: "simple".into(),
            comp: Box::new(TableCompensation::with_misalignment(s, Some(m), sc.imu_rate_hz).unwrap()),
        },
        Variant {
            name: "hysteresis".into(),
            comp: Box::new(TableCompensation::with_misalignment(h, Some(m), sc.imu_rate_hz).unwrap()),
        },
        Variant {
            name: "hysteresis, no matrix".into(),
            comp: Box::new(TableCompensation::new(h, sc.imu_rate_hz).unwrap()),
        },
    ];
    let res = run::fly(&sc, &mut qfa_nav::truths_seeded(&units, sc.seed), variants).unwrap();
    let th = thermal_ceps(&res).unwrap();
    let cep = |i: usize| run::Figures::of(&res.t, &res.tracks[i]).cep_nmi_per_h;
    println!(
        "CEP nmile/h: oracle {:.3}, simple {:.3}, hysteresis {:.3}, hysteresis without the matrix {:.3}",
        cep(0),
        cep(1),
        cep(2),
        cep(3)
    );
    println!(
        "against the oracle, nmile/h: simple {:.4}, hysteresis {:.4}, hysteresis without the matrix {:.4}",
        th["simple"], th["hysteresis"], th["hysteresis, no matrix"]
    );
    for (n, al) in res.names.iter().zip(&res.alignment) {
        println!(
            "alignment {n}: roll {:+.1}″ pitch {:+.1}″ heading {:+.3} mrad",
            al.roll_arcsec, al.pitch_arcsec, al.heading_mrad
        );
    }
    assert!(th["hysteresis"] < 0.5 * th["simple"], "with the matrix the hysteresis tables keep their gain");
    assert!(
        th["hysteresis, no matrix"] > 3.0 * th["simple"],
        "without the matrix the triad's 1 g coupling dominates the thermal error"
    );
}
