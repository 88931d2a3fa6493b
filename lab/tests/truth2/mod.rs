//! The second independent truth generator for cycling logs (an oracle).
//!
//! It shares no code with the project: nothing from the lab (`lab/src`), nothing from the
//! firmware (`src/`), nothing from the first independent generator (`tests/truth/`). It is
//! written from the physical definitions of the unit (scale factor K1, bias K0 and the
//! catalog's effects, stated on [`Unit`] and [`CatalogEffect`]), not from the fitter's code,
//! and it writes the four-position test's CSV
//! (`program,run,time_s,input_g,temp_c,pulses,interval_s`) that the lab's reader accepts.
//!
//! How it differs from `tests/truth/` on purpose, so that agreement between the two is not a
//! shared mistake:
//!
//! | | `truth/` | `truth2/` (this module) |
//! |---|---|---|
//! | thermal chain | case τ 300 s (+ optional element lag), one exact first-order step per second | two coupled nodes (air → case τ 400 s, case ↔ element, element weakly coupled to the air), RK4 at 0.25 s |
//! | programs | 1-°C steps with 3-min dwells | continuous linear ramps, holds 30/40/40/30 min, span configurable, heating-only option |
//! | counting | trapezoid per 1 s, rounded | 0.25-s steps, zero-order or first-order hold ([`Counting`]), floor with the remainder carried |
//! | temperature stamp | latest 1-Hz reading at the row's end | start, centre or end of the row ([`Stamp`]) plus a conversion delay |
//! | noise | Gaussian white + Gauss–Markov | white (Gaussian or Student-t, 3 dof), glitches, Gauss–Markov (τ 0 allowed), temperature-dependent, bad runs |
//! | RNG | xorshift64* with Box–Muller | PCG32 (XSH-RR) seeded through SplitMix64, one stream per purpose, Marsaglia's polar method |
//! | unit | fixed coefficients | drawn per seed (±20 %), catalog rate terms, hysteresis, creep, drift, out-of-catalog effects |
//!
//! Streams: the unit's coefficients, each run's white noise, glitches, Gauss–Markov bias, bad
//! run wander and DS18B20 noise each draw from their own PCG32 stream, so switching one
//! option (a stamp, glitches) leaves every other random sequence of the log unchanged.
//!
//! Time base: every run of a program is its own power-on at t = 0 of the program's chamber
//! schedule; the runs follow one another (program by program, `pos0` then `pos2`) on a
//! campaign clock that only the out-of-catalog campaign ageing sees.

#![allow(dead_code)]

mod rng;
mod unit;

pub use rng::*;
pub use unit::*;

/// Reference temperature of ΔT, °C.
pub const T_REF_C: f64 = 22.0;
/// Integration and counting step, s.
pub const DT_S: f64 = 0.25;
/// Chamber air → case time constant, s.
pub const TAU_CASE_S: f64 = 400.0;
/// Ramp rates of the four programs, °C/min.
pub const RATES: [f64; 4] = [0.3, 0.5, 0.7, 0.9];
/// Glitch probability per second and its size, pulses/s.
pub const GLITCH_PER_S: f64 = 1.0 / 5000.0;
/// Default glitch size, pulses/s over one second ([`Draw::glitch_pulses_per_s`]).
pub const GLITCH_PULSES_PER_S: f64 = 200.0;

/// The chamber schedule of one program: (s, °C) knots joined by straight lines, and the
/// times at which each ramp ends.
#[derive(Clone, Debug, PartialEq)]
pub struct Program {
    /// Ramp rate, °C/min.
    pub rate_c_per_min: f64,
    /// (time s, chamber °C) knots.
    pub knots: Vec<(f64, f64)>,
    /// End of each ramp, s.
    pub ramp_ends_s: Vec<f64>,
    /// Length, s.
    pub duration_s: f64,
}

/// The program at `rate` °C/min: hold 30 min at 22 °C, ramp to the cold end, hold 40 min,
/// ramp to the hot end, hold 40 min, ramp to 22 °C, hold 30 min; heating-only: hold 40 min
/// at the cold end (where the unit has soaked), ramp to the hot end, hold 40 min.
pub fn program(rate: f64, span_c: (f64, f64), heating_only: bool) -> Program {
    let (lo, hi) = span_c;
    let (start, holds_targets): (f64, Vec<(f64, f64)>) =
        if heating_only { (lo, vec![(hi, 40.0)]) } else { (T_REF_C, vec![(lo, 40.0), (hi, 40.0), (T_REF_C, 30.0)]) };
    let first_hold_min = if heating_only { 40.0 } else { 30.0 };
    let mut t = first_hold_min * 60.0;
    let mut knots = vec![(0.0, start), (t, start)];
    let mut ramp_ends_s = Vec::new();
    let mut temp = start;
    for (target, hold_min) in holds_targets {
        t += (target - temp).abs() / rate * 60.0;
        knots.push((t, target));
        ramp_ends_s.push(t);
        t += hold_min * 60.0;
        knots.push((t, target));
        temp = target;
    }
    Program { rate_c_per_min: rate, knots, ramp_ends_s, duration_s: t }
}

fn air(knots: &[(f64, f64)], t: f64) -> f64 {
    let i = knots.partition_point(|k| k.0 <= t);
    if i == 0 {
        return knots[0].1;
    }
    if i == knots.len() {
        return knots[knots.len() - 1].1;
    }
    let (a, b) = (knots[i - 1], knots[i]);
    a.1 + (b.1 - a.1) * (t - a.0) / (b.0 - a.0)
}

/// The thermal chain's couplings (1/s). Case: dTc/dt = (Ta − Tc)/400 s + c·(Te − Tc);
/// element: dTe/dt = k_ce·(Tc − Te) + k_ae·(Ta − Te). k_ae (weak) and c (the element's
/// small heat capacity loading the case) are fixed fractions; k_ce is chosen so that in a
/// steady ramp at rate R the element lags the case by exactly τ·R (the catalog's
/// sensor_lag τ).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Chain {
    /// Element → case back-coupling c.
    pub c_back: f64,
    /// Case → element k_ce.
    pub k_ce: f64,
    /// Air → element k_ae.
    pub k_ae: f64,
}

impl Chain {
    /// The couplings for a lag τ (s).
    pub fn for_lag(tau_s: f64) -> Self {
        let k_ae = 0.02 / tau_s.max(60.0);
        let c_back = 0.1 / tau_s.max(60.0);
        // Steady ramp R: Ta − Tc = 400·(R + c·L), R = k_ce·L + k_ae·(Ta − Tc + L) with L = τR.
        let k_ce = (1.0 - TAU_CASE_S * k_ae) / tau_s - k_ae * (1.0 + TAU_CASE_S * c_back);
        Self { c_back, k_ce, k_ae }
    }
}

/// The thermal state at every 0.25-s grid point of one program (identical for both runs:
/// the chamber, not the unit's attitude, drives it).
#[derive(Clone, Debug, Default)]
pub struct Thermal {
    /// Case temperature (where the DS18B20 sits), °C.
    pub tc: Vec<f64>,
    /// Element temperature, °C.
    pub te: Vec<f64>,
    /// Case temperature rate, °C/min (the model's derivative, not a difference).
    pub rc: Vec<f64>,
    /// Element temperature rate, °C/min.
    pub re: Vec<f64>,
    /// Creep state x, °C.
    pub x: Vec<f64>,
    /// Play operator output p, °C.
    pub p: Vec<f64>,
}

/// Integrates the chain with RK4 at 0.25 s over `prog` for `u`.
pub fn thermal(prog: &Program, u: &Unit) -> Thermal {
    let n = (prog.duration_s / DT_S).round() as usize;
    let chain = u.lag_tau_s.map(Chain::for_lag);
    let knots = &prog.knots;
    // State [Tc, Te, x]; without a lag Te is Tc.
    let rhs = |t: f64, s: [f64; 3]| -> [f64; 3] {
        let ta = air(knots, t);
        let (tc, te_state, x) = (s[0], s[1], s[2]);
        let (dtc, te, dte) = match chain {
            Some(ch) => {
                let dtc = (ta - tc) / TAU_CASE_S + ch.c_back * (te_state - tc);
                (dtc, te_state, ch.k_ce * (tc - te_state) + ch.k_ae * (ta - te_state))
            }
            None => {
                let dtc = (ta - tc) / TAU_CASE_S;
                (dtc, tc, dtc)
            }
        };
        let dx = match u.creep_tau_s(te) {
            Some(tau) => (te - x) / tau,
            None => 0.0,
        };
        [dtc, dte, dx]
    };
    let t0 = knots[0].1;
    let mut s = [t0, t0, t0];
    let mut th = Thermal::default();
    let mut p = t0;
    for k in 0..=n {
        let t = k as f64 * DT_S;
        if chain.is_none() {
            s[1] = s[0];
        }
        let f = rhs(t, s);
        if let Some((h, _)) = u.play {
            p = p.clamp(s[1] - h, s[1] + h);
        }
        th.tc.push(s[0]);
        th.te.push(s[1]);
        th.rc.push(60.0 * f[0]);
        th.re.push(60.0 * f[1]);
        th.x.push(s[2]);
        th.p.push(p);
        if k == n {
            break;
        }
        let add = |a: [f64; 3], b: [f64; 3], w: f64| [a[0] + w * b[0], a[1] + w * b[1], a[2] + w * b[2]];
        let k1 = f;
        let k2 = rhs(t + 0.5 * DT_S, add(s, k1, 0.5 * DT_S));
        let k3 = rhs(t + 0.5 * DT_S, add(s, k2, 0.5 * DT_S));
        let k4 = rhs(t + DT_S, add(s, k3, DT_S));
        for i in 0..3 {
            s[i] += DT_S / 6.0 * (k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]);
        }
    }
    th
}

fn interp(v: &[f64], t: f64) -> f64 {
    let x = (t / DT_S).clamp(0.0, (v.len() - 1) as f64);
    let i = (x.floor() as usize).min(v.len() - 2);
    let f = x - i as f64;
    v[i] + f * (v[i + 1] - v[i])
}

// ---------------------------------------------------------------------------------------
// The log.
// ---------------------------------------------------------------------------------------

/// The truth behind one row, at the centre of its counting interval.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct RowTruth {
    /// Program index (in [`RATES`] order).
    pub program: usize,
    /// 0 = pos0, 1 = pos2.
    pub run: usize,
    /// The row's `time_s` (end of its interval), s.
    pub time_s: f64,
    /// Element temperature at the centre, °C.
    pub te_c: f64,
    /// Case temperature at the centre, °C.
    pub tc_c: f64,
    /// Case rate at the centre, °C/min.
    pub rate_c_per_min: f64,
    /// K1 at the centre, all terms, pulses/(g·s).
    pub k1: f64,
    /// K0 at the centre, all deterministic terms (no noise, no Gauss–Markov, no wander), g.
    pub k0_g: f64,
}

/// What [`cycling_traced`] returns besides the CSV.
#[derive(Clone, Debug)]
pub struct Trace {
    /// The unit.
    pub unit: Unit,
    /// The programs, in log order.
    pub programs: Vec<Program>,
    /// One entry per CSV row, in log order.
    pub rows: Vec<RowTruth>,
    /// Seconds that carried a glitch.
    pub glitch_seconds: usize,
    /// Seconds counted in the whole log.
    pub counted_seconds: usize,
}

/// The CSV text of the draw's cycling log.
pub fn cycling(d: &Draw) -> String {
    cycling_traced(d).0
}

/// The CSV text and the truth behind it.
pub fn cycling_traced(d: &Draw) -> (String, Trace) {
    let u = unit(d);
    let (lo, hi) = d.span_c;
    let sub = ((d.row_s / DT_S).round() as usize).max(1);
    let row = sub as f64 * DT_S;
    let sf_hyst_ppm: f64 =
        d.other.iter().map(|o| if let OutOfCatalog::SfHysteresis { ppm } = o { *ppm } else { 0.0 }).sum();
    let campaign_g_per_h: f64 =
        d.other.iter().map(|o| if let OutOfCatalog::CampaignAgeing { g_per_h } = o { *g_per_h } else { 0.0 }).sum();
    let temp_noise = d.other.contains(&OutOfCatalog::TempDependentNoise);
    let white_step = d.white_ug_per_10s * 1e-6 * (10.0 / DT_S).sqrt();
    let (gm_sd, gm_tau) = d.bias_instability;
    let gm_phi = if gm_tau > 0.0 { (-DT_S / gm_tau).exp() } else { 0.0 };
    let wander_phi = (-DT_S / 3600.0f64).exp();
    let prefix = if d.heating_only { "heat" } else { "ramp" };

    let mut out = String::from("program,run,time_s,input_g,temp_c,pulses,interval_s\n");
    let mut trace =
        Trace { unit: u.clone(), programs: Vec::new(), rows: Vec::new(), glitch_seconds: 0, counted_seconds: 0 };
    let mut campaign_s = 0.0;
    for (pi, &rate) in RATES.iter().enumerate() {
        let prog = program(rate, d.span_c, d.heating_only);
        let th = thermal(&prog, &u);
        let n = th.tc.len() - 1;
        let rows = n / sub;
        // Scale factor at every grid point, with the direction of the last ramp.
        let mut dir = 0.0f64;
        let k1: Vec<f64> = (0..=n)
            .map(|k| {
                if th.re[k].abs() > 0.05 {
                    dir = th.re[k].signum();
                }
                u.k1(th.te[k], th.rc[k]) + dir * sf_hyst_ppm * 1e-6 * u.k10
            })
            .collect();
        // Bias terms common to both runs.
        let k0_thermal: Vec<f64> = (0..=n)
            .map(|k| {
                let mut b = u.k0_static(th.te[k]);
                if let Some((h, w)) = u.play {
                    b += w * (th.te[k] - th.p[k]) / h;
                }
                if let Some((g, _, _)) = u.creep {
                    b += g * (th.te[k] - th.x[k]);
                }
                b
            })
            .collect();
        for (ri, (run, g)) in [("pos0", 1.0f64), ("pos2", -1.0f64)].into_iter().enumerate() {
            let mut white = run_stream(d.seed, S_WHITE, pi, ri);
            let mut glitch = run_stream(d.seed, S_GLITCH, pi, ri);
            let mut gmr = run_stream(d.seed, S_GM, pi, ri);
            let mut wanr = run_stream(d.seed, S_WANDER, pi, ri);
            let mut sensor = run_stream(d.seed, S_SENSOR, pi, ri);
            let bad = d.other.contains(&OutOfCatalog::BadRun { program_index: pi, run_index: ri });
            let step_at: Vec<(f64, f64)> = d
                .other
                .iter()
                .filter_map(|o| match *o {
                    OutOfCatalog::BiasStep { program_index, run_index, at_fraction, size_g }
                        if program_index == pi && run_index == ri =>
                    {
                        Some((at_fraction * prog.duration_s, size_g))
                    }
                    _ => None,
                })
                .collect();
            // Deterministic bias of this run at grid point k.
            let k0_at = |k: usize| -> f64 {
                let t = k as f64 * DT_S;
                let mut b = k0_thermal[k] + u.drift_g_per_h * t / 3600.0 + campaign_g_per_h * (campaign_s + t) / 3600.0;
                for &(ts, size) in &step_at {
                    if t >= ts {
                        b += size;
                    }
                }
                b
            };
            let mut gm = gm_sd * gmr.normal();
            let mut wander = if bad { 10e-6 * wanr.normal() } else { 0.0 };
            let rate_of = |k: usize, gm: f64, wander: f64| k1[k] * (g + k0_at(k) + gm + wander);
            let mut prev_rate = rate_of(0, gm, wander);
            let (mut acc, mut row_i) = (0.0f64, 0usize);
            let mut spike = 0.0f64;
            for k in 0..rows * sub {
                if k % 4 == 0 {
                    // A new second: a glitch for the next four steps, or none.
                    spike = 0.0;
                    if d.glitches && glitch.uniform() < GLITCH_PER_S {
                        spike = glitch.sign() * d.glitch_pulses_per_s;
                        trace.glitch_seconds += 1;
                    }
                    trace.counted_seconds += 1;
                }
                // Noise over the step.
                let mut sd = white_step;
                if temp_noise {
                    sd *= 1.0 + 2.0 * ((th.te[k] - lo) / (hi - lo)).clamp(0.0, 1.0);
                }
                if bad {
                    sd *= 5.0;
                }
                let z = if sd > 0.0 {
                    if d.heavy_tails {
                        white.student3()
                    } else {
                        white.normal()
                    }
                } else {
                    0.0
                };
                let gm_next =
                    if gm_sd > 0.0 { gm_phi * gm + gm_sd * (1.0 - gm_phi * gm_phi).sqrt() * gmr.normal() } else { 0.0 };
                let wander_next = if bad {
                    wander_phi * wander + 10e-6 * (1.0 - wander_phi * wander_phi).sqrt() * wanr.normal()
                } else {
                    0.0
                };
                let next_rate = rate_of(k + 1, gm_next, wander_next);
                let signal = match d.counting {
                    Counting::ZeroOrderHold => prev_rate * DT_S,
                    Counting::FirstOrderHold => 0.5 * (prev_rate + next_rate) * DT_S,
                };
                acc += signal + k1[k] * sd * z * DT_S + spike * DT_S;
                prev_rate = next_rate;
                gm = gm_next;
                wander = wander_next;
                if (k + 1) % sub == 0 {
                    row_i += 1;
                    let t_end = row_i as f64 * row;
                    let pulses = acc.floor();
                    acc -= pulses;
                    let t_stamp = match d.stamp {
                        Stamp::Start => t_end - row,
                        Stamp::Centre => t_end - 0.5 * row,
                        Stamp::End => t_end,
                    };
                    let seen = interp(&th.tc, (t_stamp - d.conversion_delay_s).max(0.0));
                    let noise = if d.sensor_noise_c > 0.0 { d.sensor_noise_c * sensor.normal() } else { 0.0 };
                    let reading = ((seen + noise) * 16.0).round() / 16.0;
                    out.push_str(&format!(
                        "{prefix}-{rate:.1},{run},{t_end:.2},{g},{reading:.4},{pulses:.0},{row:.2}\n"
                    ));
                    let t_mid = t_end - 0.5 * row;
                    let x = t_mid / DT_S;
                    let kf = (x.floor() as usize).min(n - 1);
                    let frac = x - kf as f64;
                    let k0_mid = k0_at(kf) + frac * (k0_at(kf + 1) - k0_at(kf));
                    trace.rows.push(RowTruth {
                        program: pi,
                        run: ri,
                        time_s: t_end,
                        te_c: interp(&th.te, t_mid),
                        tc_c: interp(&th.tc, t_mid),
                        rate_c_per_min: interp(&th.rc, t_mid),
                        k1: interp(&k1, t_mid),
                        k0_g: k0_mid,
                    });
                }
            }
            campaign_s += prog.duration_s;
        }
        trace.programs.push(prog);
    }
    (out, trace)
}
