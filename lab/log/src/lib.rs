//! qfa-log, the lab's data layer: every log kind the lab reads or writes, and the channels the fitters
//! see. Data flows one way: a log ([`cycling`] or [`static_log`]) → its channels
//! ([`pairing`] for the ±1 g runs of a cycling log, [`channels`] for discovery's binned
//! series) → a fit (in qfa-calibrate) → a table → compensation and evaluation.

pub mod autopilot;
pub mod channels;
pub mod cycling;
pub(crate) mod dataflash;
pub mod io_fault;
pub(crate) mod lines;
pub mod open;
pub mod pairing;
pub mod replay;
pub mod robust;
pub(crate) mod single;
pub mod spelling;
pub mod static_log;
pub(crate) mod ulog;
pub mod units;

pub use io_fault::IoFault;

/// The temperature span, °C, a bias grid of `nodes` nodes needs: its nodes at least the root
/// crate's smallest grid step apart (`MIN_GRID_STEP_C`, 0.1 °C), so 1.5 °C for the 16 nodes
/// of `MAX_BIAS_POINTS`. The one rule behind a static log's coverage check and a cycling
/// log's contents check; `nodes` is clamped to the grid's 2…`MAX_BIAS_POINTS`.
#[must_use]
pub fn grid_span_needed_c(nodes: usize) -> f64 {
    let g = nodes.clamp(2, qfa_thermal::model::MAX_BIAS_POINTS);
    (g - 1) as f64 * f64::from(qfa_thermal::table::limits::MIN_GRID_STEP_C)
}

#[cfg(test)]
mod tests {
    /// The datasheet figures by hand: 16 nodes, 15 gaps of 0.1 °C; 2 nodes, one gap; a
    /// grid of one node or of more than 16 is clamped to the grid's bounds.
    #[test]
    fn a_grid_needs_its_gaps_times_the_smallest_step() {
        for (nodes, span) in [(16, 1.5), (2, 0.1), (1, 0.1), (40, 1.5), (9, 0.8)] {
            let got = super::grid_span_needed_c(nodes);
            assert!((got - span).abs() < 1e-6, "{nodes} nodes: {got} °C, not {span}");
        }
    }
}
