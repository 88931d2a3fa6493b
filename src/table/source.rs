//! A table as Rust source: the `const` expression that builds it, for a `static` in flash.

use core::fmt;

use super::{Input, Table};
use crate::model::AxisModel;

/// `table` written as a Rust expression of type [`Table`], every number exactly
/// (`f32::from_bits`), every path absolute, so `static TABLE: qfa_thermal::Table = …;`
/// compiles in any crate that depends on `qfa_thermal`. `qfa-lab table-rs` writes it from a
/// `table.bin`, and a board's `build.rs` can too; the expression decodes to nothing else
/// than the table it was written from (`Table::decode` of the same bytes equals it).
///
/// ```
/// use qfa_thermal::table::RustSource;
/// use qfa_thermal::{AxisModel, BiasGrid, Extensions, Input, ScaleFactor, Table};
///
/// let axis = AxisModel {
///     scale: ScaleFactor::simple(22.0, 320_320.0, -32.76),
///     bias: BiasGrid::flat(-40.0, 10.0, [1e-4; 13]),
///     rate_limit_c_per_min: 2.0,
///     ext: Extensions::NONE,
/// };
/// let table = Table::new(Input::PulseCounts, 32, [axis], None);
/// let source = format!("{}", RustSource(&table));
/// assert!(source.starts_with("::qfa_thermal::Table {"));
/// assert!(source.contains("f32::from_bits(0x489c6800)")); // γ = 320 320 exactly (Python: struct.pack("<f", 320320.0))
/// ```
#[derive(Clone, Copy, Debug)]
pub struct RustSource<'a>(pub &'a Table);

/// An `f32` exactly, as a const expression.
struct Exact(f32);

impl fmt::Display for Exact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "f32::from_bits({:#010x})", self.0.to_bits())
    }
}

/// `[x, y, …]`, each exactly.
struct Floats<'a>(&'a [f32]);

impl fmt::Display for Floats<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str("[")?;
        for (i, &x) in self.0.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            write!(f, "{}", Exact(x))?;
        }
        f.write_str("]")
    }
}

/// `Some(x)` or `None`, for an optional `f32`.
struct OptionalExact(Option<f32>);

impl fmt::Display for OptionalExact {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self.0 {
            Some(x) => write!(f, "Some({})", Exact(x)),
            None => f.write_str("None"),
        }
    }
}

fn axis(f: &mut fmt::Formatter<'_>, a: &AxisModel) -> fmt::Result {
    let (s, b, e) = (&a.scale, &a.bias, &a.ext);
    write!(
        f,
        "::qfa_thermal::AxisModel {{ scale: ::qfa_thermal::ScaleFactor {{ t0_c: {}, gamma: {}, mu: {}, beta: {}, \
         epsilon: {}, eta: {}, alpha: {} }}, ",
        Exact(s.t0_c),
        Exact(s.gamma),
        Exact(s.mu),
        Exact(s.beta),
        Exact(s.epsilon),
        Exact(s.eta),
        Exact(s.alpha)
    )?;
    write!(
        f,
        "bias: ::qfa_thermal::BiasGrid {{ t_start_c: {}, t_step_c: {}, deadband_c_per_min: {}, \
         heating_g: ::qfa_thermal::heapless::Vec::from_array({}), \
         cooling_g: ::qfa_thermal::heapless::Vec::from_array({}), residual_rms_g: {} }}, ",
        Exact(b.t_start_c),
        Exact(b.t_step_c),
        Exact(b.deadband_c_per_min),
        Floats(&b.heating_g),
        Floats(&b.cooling_g),
        Exact(b.residual_rms_g)
    )?;
    write!(
        f,
        "rate_limit_c_per_min: {}, ext: ::qfa_thermal::Extensions {{ sensor_lag: ",
        Exact(a.rate_limit_c_per_min)
    )?;
    match e.sensor_lag {
        Some(l) => write!(f, "Some(::qfa_thermal::model::SensorLag {{ tau_s: {} }})", Exact(l.tau_s))?,
        None => f.write_str("None")?,
    }
    f.write_str(", bias_branch_hysteresis: ")?;
    match e.bias_branch_hysteresis {
        Some(h) => write!(
            f,
            "Some(::qfa_thermal::model::BranchHysteresis {{ half_width_c: {}, weight_g: {} }})",
            Exact(h.half_width_c),
            Exact(h.weight_g)
        )?,
        None => f.write_str("None")?,
    }
    f.write_str(", bias_creep: ")?;
    match e.bias_creep {
        Some(c) => write!(
            f,
            "Some(::qfa_thermal::model::Creep {{ gain_g_per_c: {}, tau_ref_s: {}, t_ref_c: {}, activation_k: {} }})",
            Exact(c.gain_g_per_c),
            Exact(c.tau_ref_s),
            Exact(c.t_ref_c),
            Exact(c.activation_k)
        )?,
        None => f.write_str("None")?,
    }
    f.write_str(" } }")
}

impl fmt::Display for RustSource<'_> {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let t = self.0;
        let input = match t.input {
            Input::PulseCounts => "PulseCounts",
            Input::Samples => "Samples",
        };
        write!(
            f,
            "::qfa_thermal::Table {{ input: ::qfa_thermal::Input::{input}, rate_window: {}, \
             axes: ::qfa_thermal::heapless::Vec::from_array([",
            t.rate_window
        )?;
        for (i, a) in t.axes.iter().enumerate() {
            if i > 0 {
                f.write_str(", ")?;
            }
            axis(f, a)?;
        }
        f.write_str("]), misalignment: ")?;
        match &t.misalignment {
            Some(m) => write!(f, "Some({})", Floats(m))?,
            None => f.write_str("None")?,
        }
        write!(f, ", part_lsb_per_g: {} }}", OptionalExact(t.part_lsb_per_g))
    }
}
