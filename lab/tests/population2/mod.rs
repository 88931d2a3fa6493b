//! A second generator of static (MEMS) production batches, an oracle for the batch tests.
//!
//! It shares no code with the lab's own population simulator (`qfa_sim::population`) nor
//! with the firmware: it is written from the physical description below, and it writes the
//! two inputs a production line has (one chamber log holding every unit, or one log per
//! unit named by a manifest) for the lab's readers to take as any logger's files.
//!
//! How it differs from the lab's simulator on purpose, so that agreement between the two is
//! not a shared mistake:
//!
//! | | lab simulator | this generator |
//! |---|---|---|
//! | bias curve | a cubic in T − 25 °C | an S-curve (`tanh`) plus a bow that flattens at the ends: no polynomial |
//! | hysteresis | a step between branches when the rate passes a deadband | a play (backlash) operator of ±1.5 °C on the die's temperature: the output crosses between branches over 3 °C after a turn |
//! | thermal chain | air → case, 1 step a second; die lag optional | air → case → die, exact exponential sub-steps of 0.1 s; every die lags (0–240 s) |
//! | program | 25 → −20 → 70 → 40 °C at 2 °C/min | 30 → −25 → 65 → 35 °C at 1.8 °C/min |
//! | noise | Gaussian | Student-t of 3 degrees of freedom, and rare single-sample spikes of 4–12 mg |
//! | population | one family | two production lots, whose slope, knee and level differ |
//! | defects | shock on every axis at 60 %, sensor drift, 3× split | shock on one axis at 45–70 %, sensor drift, 3× split, 4× noise |
//! | sensor | 1/16 °C steps | 0.01 °C steps |
//! | RNG | Xoshiro256++, ziggurat normals | XorShift128 (`rand_xorshift`), `rand_distr`'s Student-t |
//! | units logged | g | a chamber log in g; a manifest whose second lot logs mg, comma-separated, under other column names |

#![allow(dead_code)]

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

use rand::{RngExt, SeedableRng};
use rand_distr::{Distribution, StudentT};
use rand_xorshift::XorShiftRng;

/// Row interval, s.
pub const ROW_S: f64 = 1.0;
/// Thermal sub-steps per row.
const SUBSTEPS: usize = 10;
/// The chamber program: 30 °C held, then (target °C, hold at the target s) legs at
/// [`RAMP_C_PER_MIN`].
pub const START_C: f64 = 30.0;
/// First hold, s.
pub const FIRST_HOLD_S: f64 = 600.0;
/// Legs: (target °C, hold s).
pub const LEGS: [(f64, f64); 3] = [(-25.0, 900.0), (65.0, 900.0), (35.0, 900.0)];
/// Ramp rate, °C/min.
pub const RAMP_C_PER_MIN: f64 = 1.8;
/// The play operator's half-width on the die's temperature, °C.
pub const PLAY_HALF_WIDTH_C: f64 = 1.5;
/// The longest die lag drawn, s.
pub const MAX_DIE_LAG_S: f64 = 240.0;
/// A spike's chance per sample and axis.
pub const SPIKE_PER_SAMPLE: f64 = 1.0 / 2500.0;

/// A deliberately bad unit.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Defect {
    /// One axis's bias steps by 3–6 mg (either sign) at 45–70 % of the run: a shock.
    Damaged,
    /// The temperature sensor drifts 2 °C an hour.
    DriftingSensor,
    /// The play's heating/cooling split three times the unit's drawn one on every axis.
    Hysteresis3x,
    /// Four times the unit's drawn noise on every axis.
    Noisy,
}

impl Defect {
    /// Every defect, in the order they are placed.
    pub const ALL: [Self; 4] = [Self::Damaged, Self::DriftingSensor, Self::Hysteresis3x, Self::Noisy];
}

/// Rows a unit's own log keeps (manifest only).
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Truncation {
    /// From the end of the cold hold to the start of the hot hold.
    HeatingOnly,
    /// The first half of the rows.
    FirstHalf,
}

/// One axis: bias `b(T) = level + slope·width·tanh((T − knee)/width) + bow·d²/(1 + (d/40)²)`
/// with `d = T − 25 °C`, `T` the die's temperature, plus the play's `±split/2`.
#[derive(Clone, Copy, Debug)]
pub struct Axis {
    /// g (gravity's share included).
    pub level_g: f64,
    /// Slope at the knee, g/°C.
    pub slope_g_per_c: f64,
    /// °C.
    pub knee_c: f64,
    /// °C.
    pub width_c: f64,
    /// g/°C² near 25 °C.
    pub bow_g_per_c2: f64,
    /// Heating minus cooling once the play is taken up, g.
    pub split_g: f64,
}

impl Axis {
    /// The bias without the play, g.
    #[must_use]
    pub fn curve(&self, t_c: f64) -> f64 {
        let d = t_c - 25.0;
        self.level_g
            + self.slope_g_per_c * self.width_c * ((t_c - self.knee_c) / self.width_c).tanh()
            + self.bow_g_per_c2 * d * d / (1.0 + (d / 40.0).powi(2))
    }

    /// The bias at a steady die temperature `t_c` on a branch whose play is taken up, g.
    #[must_use]
    pub fn at(&self, t_c: f64, heating: bool) -> f64 {
        self.curve(t_c) + if heating { 0.5 } else { -0.5 } * self.split_g
    }
}

/// One unit's truth.
#[derive(Clone, Debug)]
pub struct Unit {
    /// Serial: `A0001`… for the first lot, `B0001`… for the second.
    pub serial: String,
    /// 0 or 1.
    pub lot: usize,
    /// Its defect.
    pub defect: Option<Defect>,
    /// Its own log's truncation (manifest only).
    pub truncation: Option<Truncation>,
    /// Air → case, s.
    pub case_tau_s: f64,
    /// Case → die, s (the output follows the die; the sensor reads the case).
    pub die_tau_s: f64,
    /// °C.
    pub sensor_offset_c: f64,
    /// °C per hour.
    pub sensor_drift_c_per_h: f64,
    /// Standard deviation of the Student-t noise, g.
    pub noise_g: f64,
    /// The shock: axis, time s, size g.
    pub shock: Option<(usize, f64, f64)>,
    /// `ax`, `ay`, `az`.
    pub axes: [Axis; 3],
}

/// What to draw.
#[derive(Clone, Copy, Debug)]
pub struct Spec {
    /// Units.
    pub units: usize,
    /// Seed.
    pub seed: u64,
    /// One of each [`Defect`] per started 50 units.
    pub bad: bool,
    /// Good units with truncated logs (manifest only), alternating heating-only and first half.
    pub truncated: usize,
}

/// The nominal axes of each lot: the second lot's slope and knee differ, as a process
/// change would move them.
fn nominal(lot: usize) -> [Axis; 3] {
    let (s, k) = if lot == 0 { (1.0, 15.0) } else { (1.35, 5.0) };
    [
        Axis {
            level_g: 0.0,
            slope_g_per_c: 1.0e-4 * s,
            knee_c: k,
            width_c: 35.0,
            bow_g_per_c2: 1.5e-7,
            split_g: 2.0e-4,
        },
        Axis {
            level_g: 0.0,
            slope_g_per_c: -6.0e-5 * s,
            knee_c: k,
            width_c: 40.0,
            bow_g_per_c2: -1.0e-7,
            split_g: 8.0e-5,
        },
        Axis {
            level_g: -1.0 + 1.5e-3 * lot as f64,
            slope_g_per_c: 4.0e-5 * s,
            knee_c: k + 10.0,
            width_c: 30.0,
            bow_g_per_c2: 5.0e-8,
            split_g: 1.2e-4,
        },
    ]
}

/// The generator of one purpose of one unit.
fn rng(seed: u64, unit: usize, purpose: u64) -> XorShiftRng {
    XorShiftRng::seed_from_u64(seed.wrapping_mul(1_000_003).wrapping_add(unit as u64 * 16 + purpose))
}

/// Draw a population: lots drawn per unit (about 40 % in the second), defects placed on
/// random units.
#[must_use]
pub fn draw(spec: &Spec) -> Vec<Unit> {
    let n = spec.units;
    let mut place = rng(spec.seed, usize::MAX >> 8, 0);
    let mut order: Vec<usize> = (0..n).collect();
    for i in (1..n).rev() {
        order.swap(i, place.random_range(0..=i));
    }
    let per_kind = if spec.bad { n.div_ceil(50) } else { 0 };
    let mut defect = vec![None; n];
    let mut truncation = vec![None; n];
    let mut next = order.iter();
    for d in Defect::ALL {
        for _ in 0..per_kind {
            if let Some(&i) = next.next() {
                defect[i] = Some(d);
            }
        }
    }
    for (j, &i) in next.take(spec.truncated).enumerate() {
        truncation[i] = Some(if j % 2 == 0 { Truncation::HeatingOnly } else { Truncation::FirstHalf });
    }
    let mut counts = [0usize; 2];
    (0..n)
        .map(|i| {
            let mut r = rng(spec.seed, i, 1);
            let lot = usize::from(r.random::<f64>() < 0.4);
            counts[lot] += 1;
            let mut axes = nominal(lot);
            for a in &mut axes {
                // Mounting (±3 mg), slope 15 %, knee ±5 °C, width ±10 %, bow 30 %, split 20 %.
                a.level_g += 3.0e-3 * (2.0 * r.random::<f64>() - 1.0);
                a.slope_g_per_c *= 1.0 + 0.15 * (2.0 * r.random::<f64>() - 1.0);
                a.knee_c += 5.0 * (2.0 * r.random::<f64>() - 1.0);
                a.width_c *= 1.0 + 0.1 * (2.0 * r.random::<f64>() - 1.0);
                a.bow_g_per_c2 *= 1.0 + 0.3 * (2.0 * r.random::<f64>() - 1.0);
                a.split_g *= 1.0 + 0.2 * (2.0 * r.random::<f64>() - 1.0);
            }
            let d = defect[i];
            if d == Some(Defect::Hysteresis3x) {
                for a in &mut axes {
                    a.split_g *= 3.0;
                }
            }
            let noise = 1.5e-4 + 1.0e-4 * r.random::<f64>();
            let shock = (d == Some(Defect::Damaged)).then(|| {
                let axis = r.random_range(0..3);
                let at = (0.45 + 0.25 * r.random::<f64>()) * duration_s();
                let size = (3.0e-3 + 3.0e-3 * r.random::<f64>()) * if r.random::<bool>() { 1.0 } else { -1.0 };
                (axis, at, size)
            });
            Unit {
                serial: format!("{}{:04}", ["A", "B"][lot], counts[lot]),
                lot,
                defect: d,
                truncation: truncation[i],
                case_tau_s: 150.0 + 250.0 * r.random::<f64>(),
                die_tau_s: MAX_DIE_LAG_S * r.random::<f64>(),
                sensor_offset_c: 0.3 * lot as f64 + 0.4 * (2.0 * r.random::<f64>() - 1.0),
                sensor_drift_c_per_h: if d == Some(Defect::DriftingSensor) { 2.0 } else { 0.0 },
                noise_g: if d == Some(Defect::Noisy) { 4.0 * noise } else { noise },
                shock,
                axes,
            }
        })
        .collect()
}

/// The program's length, s.
#[must_use]
pub fn duration_s() -> f64 {
    let mut t = FIRST_HOLD_S;
    let mut at = START_C;
    for (target, hold) in LEGS {
        t += (target - at).abs() / RAMP_C_PER_MIN * 60.0 + hold;
        at = target;
    }
    t
}

/// The chamber air at `t_s`, °C.
#[must_use]
pub fn air_c(t_s: f64) -> f64 {
    let mut start = FIRST_HOLD_S;
    let mut at = START_C;
    if t_s < start {
        return at;
    }
    for (target, hold) in LEGS {
        let ramp = (target - at).abs() / RAMP_C_PER_MIN * 60.0;
        if t_s < start + ramp {
            return at + (target - at) * (t_s - start) / ramp;
        }
        if t_s < start + ramp + hold {
            return target;
        }
        start += ramp + hold;
        at = target;
    }
    at
}

/// Rows of the full run.
#[must_use]
pub fn rows() -> usize {
    (duration_s() / ROW_S) as usize
}

/// One unit's rows: (time s, sensor reading °C, [ax, ay, az] g).
#[must_use]
pub fn unit_rows(u: &Unit, seed: u64, index: usize) -> Vec<(f64, f64, [f64; 3])> {
    unit_rows_under(u, seed, index, &air_c, rows())
}

/// One unit's `n` rows under the air `air(t_s)` instead of the chamber's (a vehicle's
/// warm-up and flight), the unit soaked at `air(0)` and its play on the cooling side.
#[must_use]
pub fn unit_rows_under(
    u: &Unit,
    seed: u64,
    index: usize,
    air: &dyn Fn(f64) -> f64,
    n: usize,
) -> Vec<(f64, f64, [f64; 3])> {
    let mut noise = rng(seed, index, 2);
    let mut spikes = rng(seed, index, 3);
    let mut sensor = rng(seed, index, 4);
    let t3 = StudentT::new(3.0).expect("3 degrees of freedom");
    // A Student-t of 3 degrees of freedom has variance 3.
    let scale = u.noise_g / 3f64.sqrt();
    let h = ROW_S / SUBSTEPS as f64;
    let (a_case, a_die) = ((-h / u.case_tau_s).exp(), if u.die_tau_s > 0.0 { (-h / u.die_tau_s).exp() } else { 0.0 });
    let start_c = air(0.0);
    let (mut case, mut die) = (start_c, start_c);
    // The unit was cooled to the start: its play sits on the cooling side.
    let mut play = start_c + PLAY_HALF_WIDTH_C;
    let mut out = Vec::with_capacity(n);
    for i in 0..n {
        let t = i as f64 * ROW_S;
        if i > 0 {
            for s in 0..SUBSTEPS {
                let air = air(t - ROW_S + (s as f64 + 0.5) * h);
                case = air + (case - air) * a_case;
                die = case + (die - case) * a_die;
                play = play.clamp(die - PLAY_HALF_WIDTH_C, die + PLAY_HALF_WIDTH_C);
            }
        }
        let drift = u.sensor_drift_c_per_h * t / 3600.0;
        let reading =
            ((case + u.sensor_offset_c + drift + 0.02 * sensor.random::<f64>() - 0.01) * 100.0).round() / 100.0;
        let mut acc = [0.0; 3];
        for (k, a) in u.axes.iter().enumerate() {
            let hyst = 0.5 * a.split_g * (die - play) / PLAY_HALF_WIDTH_C;
            let shock = u.shock.filter(|s| s.0 == k && t >= s.1).map_or(0.0, |s| s.2);
            let mut v = a.curve(die) + hyst + shock + scale * t3.sample(&mut noise);
            if spikes.random::<f64>() < SPIKE_PER_SAMPLE {
                v += (4.0e-3 + 8.0e-3 * spikes.random::<f64>()) * if spikes.random::<bool>() { 1.0 } else { -1.0 };
            }
            acc[k] = v;
        }
        out.push((t, reading, acc));
    }
    out
}

/// The rows a truncated log keeps.
#[must_use]
pub fn kept(t: Option<Truncation>) -> std::ops::Range<usize> {
    let n = rows();
    match t {
        None => 0..n,
        Some(Truncation::FirstHalf) => 0..n / 2,
        Some(Truncation::HeatingOnly) => {
            let ramp = |from: f64, to: f64| (to - from).abs() / RAMP_C_PER_MIN * 60.0;
            let start = FIRST_HOLD_S + ramp(START_C, LEGS[0].0) + LEGS[0].1;
            let top = start + ramp(LEGS[0].0, LEGS[1].0);
            (start / ROW_S) as usize..(top / ROW_S) as usize
        }
    }
}

/// One chamber log holding every unit's full run, in g, tab-separated: `time`, then per
/// unit `SERIAL.temp`, `SERIAL.ax`, `SERIAL.ay`, `SERIAL.az`. Returns its path.
///
/// # Panics
/// The file cannot be written.
#[must_use]
pub fn write_chamber(dir: &Path, units: &[Unit], seed: u64) -> PathBuf {
    let all: Vec<_> = units.iter().enumerate().map(|(i, u)| unit_rows(u, seed, i)).collect();
    let mut s = String::from("time");
    for u in units {
        for c in ["temp", "ax", "ay", "az"] {
            let _ = write!(s, "\t{}.{c}", u.serial);
        }
    }
    s.push('\n');
    for i in 0..rows() {
        let _ = write!(s, "{:.0}", all[0][i].0);
        for r in &all {
            let (_, t, a) = r[i];
            let _ = write!(s, "\t{t:.2}\t{:.7}\t{:.7}\t{:.7}", a[0], a[1], a[2]);
        }
        s.push('\n');
    }
    let path = dir.join("chamber.tsv");
    std::fs::write(&path, s).expect("chamber log written");
    path
}

/// One log per unit and the manifest naming them (`batch.toml`), each unit's rows as its
/// truncation keeps. The first lot's logger writes tab-separated g under `time`, `temp`,
/// `ax`…; the second lot's writes comma-separated mg under `t_s`, `imu_temp_c`, `acc_x_mg`…,
/// given per unit in the manifest. Returns the manifest's path.
///
/// # Panics
/// A file cannot be written.
#[must_use]
pub fn write_manifest(dir: &Path, units: &[Unit], seed: u64) -> PathBuf {
    let logs = dir.join("units");
    std::fs::create_dir_all(&logs).expect("units folder");
    let mut manifest = String::from("time_unit = \"s\"\ntemp_unit = \"C\"\n");
    for (i, u) in units.iter().enumerate() {
        let rows = unit_rows(u, seed, i);
        let kept = &rows[kept(u.truncation)];
        let (name, text) = if u.lot == 0 {
            let mut s = String::from("time\ttemp\tax\tay\taz\n");
            for (t, r, a) in kept {
                let _ = writeln!(s, "{t:.0}\t{r:.2}\t{:.7}\t{:.7}\t{:.7}", a[0], a[1], a[2]);
            }
            let _ = write!(
                manifest,
                "\n[[unit]]\nserial = \"{}\"\nlog = \"units/{}.tsv\"\naccel_unit = \"g\"\n",
                u.serial, u.serial
            );
            (format!("{}.tsv", u.serial), s)
        } else {
            let mut s = String::from("t_s,imu_temp_c,acc_x_mg,acc_y_mg,acc_z_mg\n");
            for (t, r, a) in kept {
                let _ = writeln!(s, "{t:.0},{r:.2},{:.4},{:.4},{:.4}", a[0] * 1e3, a[1] * 1e3, a[2] * 1e3);
            }
            let _ = write!(
                manifest,
                "\n[[unit]]\nserial = \"{}\"\nlog = \"units/{}.csv\"\naccel_unit = \"mg\"\n\
                 columns = \"time=t_s,temp=imu_temp_c,ax=acc_x_mg,ay=acc_y_mg,az=acc_z_mg\"\n",
                u.serial, u.serial
            );
            (format!("{}.csv", u.serial), s)
        };
        std::fs::write(logs.join(name), text).expect("unit log written");
    }
    let path = dir.join("batch.toml");
    std::fs::write(&path, manifest).expect("manifest written");
    path
}
