//! PNG of a flight: temperatures, and per variant the radial, East and North position
//! errors and the East and North velocity errors against time; and the Monte Carlo
//! distributions. Each panel's legend sits in a strip above its chart, off the data.

use std::fmt;

use plotters::prelude::*;

use super::run::FlightResult;
use qfa_report::plot_legend::{heading, DrawError, Entry, Mark};
use qfa_report::plot_png::{Area, Plot};

/// Why a plot could not be drawn.
#[derive(Debug)]
#[non_exhaustive]
pub enum PlotError {
    /// plotters could not draw the plot (a chart, or a panel's title and legend), or its
    /// bitmap did not encode as a PNG.
    Draw(qfa_report::plot_png::PlotError),
    /// No finite value to plot.
    NoFiniteValues,
}

impl fmt::Display for PlotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Draw(e) => write!(f, "{e}"),
            Self::NoFiniteValues => f.write_str("no finite values to plot"),
        }
    }
}

impl std::error::Error for PlotError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            // Printed as it is (above): its cause comes next.
            Self::Draw(e) => e.source(),
            Self::NoFiniteValues => None,
        }
    }
}

impl From<qfa_report::plot_png::PlotError> for PlotError {
    fn from(e: qfa_report::plot_png::PlotError) -> Self {
        Self::Draw(e)
    }
}

const COLORS: [RGBColor; 5] = [
    RGBColor(120, 120, 120),
    RGBColor(230, 140, 0),
    RGBColor(0, 130, 60),
    RGBColor(150, 60, 200),
    RGBColor(30, 60, 200),
];

/// A series' colour: a variant's is the same on every plot (its place in
/// [`super::VARIANTS`]), any other series' its place `k` in the panel.
fn color_of(name: &str, k: usize) -> RGBColor {
    let i = super::VARIANTS.iter().position(|v| *v == name).unwrap_or(k);
    COLORS[i % COLORS.len()]
}

fn panel(
    area: &Area<'_>,
    title: &str,
    y_desc: &str,
    t_h: &[f64],
    series: &[(String, Vec<f64>)],
) -> Result<(), DrawError> {
    let lo = series.iter().flat_map(|s| s.1.iter()).copied().fold(f64::INFINITY, f64::min);
    let hi = series.iter().flat_map(|s| s.1.iter()).copied().fold(f64::NEG_INFINITY, f64::max);
    let pad = ((hi - lo) * 0.05).max(1e-6);
    let xmax = t_h.last().copied().unwrap_or(1.0);
    let entries: Vec<Entry> =
        series.iter().enumerate().map(|(k, (name, _))| (name.clone(), color_of(name, k), Mark::Line)).collect();
    let body = heading(area, title, &entries)?;
    let mut chart = ChartBuilder::on(&body)
        .margin(10)
        .x_label_area_size(35)
        .y_label_area_size(60)
        .build_cartesian_2d(0.0..xmax, (lo - pad)..(hi + pad))?;
    chart.configure_mesh().x_desc("time (h)").y_desc(y_desc).draw()?;
    for (k, (name, y)) in series.iter().enumerate() {
        let c = color_of(name, k);
        chart.draw_series(LineSeries::new(t_h.iter().copied().zip(y.iter().copied()), c.stroke_width(2)))?;
    }
    Ok(())
}

/// File name of [`plot_flight`]'s plot.
pub const FLIGHT_PLOT: &str = "nav_errors.png";

/// `nav_errors.png` (1600 × 1200) of `res`.
///
/// # Errors
/// Drawing or encoding errors.
pub fn plot_flight(title: &str, res: &FlightResult) -> Result<Plot, PlotError> {
    Ok(Plot::draw(FLIGHT_PLOT, (1600, 1200), |root| draw_flight(root, title, res))?)
}

fn draw_flight(root: &Area<'_>, title: &str, res: &FlightResult) -> Result<(), DrawError> {
    root.fill(&WHITE)?;
    let (top, body) = root.split_vertically(30);
    top.titled(title, ("sans-serif", 20))?;
    let areas = body.split_evenly((3, 2));
    let t_h: Vec<f64> = res.t.iter().map(|t| t / 3600.0).collect();
    let temps: Vec<(String, Vec<f64>)> = ["bay air", "case (DS18B20)", "element"]
        .iter()
        .enumerate()
        .map(|(i, n)| ((*n).to_string(), res.temps.iter().map(|t| t[i]).collect()))
        .collect();
    panel(&areas[0], "IMU temperature", "degC", &t_h, &temps)?;
    let by = |f: &dyn Fn(usize, usize) -> f64| -> Vec<(String, Vec<f64>)> {
        res.names.iter().enumerate().map(|(v, n)| (n.clone(), (0..res.t.len()).map(|i| f(v, i)).collect())).collect()
    };
    let tr = &res.tracks;
    panel(&areas[1], "radial position error", "m", &t_h, &by(&|v, i| tr[v].dn[i].hypot(tr[v].de[i])))?;
    panel(&areas[2], "East velocity error", "m/s", &t_h, &by(&|v, i| tr[v].ve[i]))?;
    panel(&areas[3], "North velocity error", "m/s", &t_h, &by(&|v, i| tr[v].vn[i]))?;
    panel(&areas[4], "East position error", "m", &t_h, &by(&|v, i| tr[v].de[i]))?;
    panel(&areas[5], "North position error", "m", &t_h, &by(&|v, i| tr[v].dn[i]))?;
    Ok(())
}

/// `file`: empirical distribution functions of one quantity per variant (x: value, y:
/// fraction of runs ≤ x), with the median marked; 1200 × 700.
///
/// # Errors
/// Drawing or encoding errors, or no values.
pub fn plot_distributions(
    file: &str,
    title: &str,
    x_desc: &str,
    series: &[(String, Vec<f64>)],
) -> Result<Plot, PlotError> {
    let all = series.iter().flat_map(|s| s.1.iter()).copied();
    let lo = all.clone().fold(f64::INFINITY, f64::min);
    let hi = all.fold(f64::NEG_INFINITY, f64::max);
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(PlotError::NoFiniteValues);
    }
    let pad = ((hi - lo) * 0.05).max(1e-6);
    Ok(Plot::draw(file, (1200, 700), |root| draw_distributions(root, title, x_desc, series, (lo - pad, hi + pad)))?)
}

fn draw_distributions(
    root: &Area<'_>,
    title: &str,
    x_desc: &str,
    series: &[(String, Vec<f64>)],
    (xlo, xhi): (f64, f64),
) -> Result<(), DrawError> {
    root.fill(&WHITE)?;
    let mut entries: Vec<Entry> =
        series.iter().enumerate().map(|(k, (name, _))| (name.clone(), color_of(name, k), Mark::Line)).collect();
    entries.push(("dot: the curve's median".to_string(), BLACK, Mark::Dot));
    let body = heading(root, title, &entries)?;
    let mut chart = ChartBuilder::on(&body)
        .margin(15)
        .x_label_area_size(40)
        .y_label_area_size(60)
        .build_cartesian_2d(xlo..xhi, 0.0..1.0)?;
    chart.configure_mesh().x_desc(x_desc).y_desc("fraction of runs ≤ x").draw()?;
    for (k, (name, v)) in series.iter().enumerate() {
        let mut s = v.clone();
        s.sort_by(f64::total_cmp);
        let n = s.len() as f64;
        let c = color_of(name, k);
        let pts: Vec<(f64, f64)> =
            s.iter().enumerate().flat_map(|(i, &x)| [(x, i as f64 / n), (x, (i + 1) as f64 / n)]).collect();
        chart.draw_series(LineSeries::new(pts, c.stroke_width(2)))?;
        if let Some(&m) = s.get(s.len() / 2) {
            chart.draw_series(std::iter::once(Circle::new((m, 0.5), 5, c.filled())))?;
        }
    }
    Ok(())
}
