//! qfa-report: what the lab's pages are made of. The `report.html` builder
//! ([`html_report::Page`]), the one plot font ([`plot_font`]), plot legends placed out of
//! the data ([`plot_legend`]), plots drawn in memory ([`plot_png::Plot`]) and the verdict every command prints and writes
//! ([`verdict::Verdict`]). It knows nothing of logs or fits: the crates that do hand it
//! sections, tables, PNG bytes and figures.

pub mod html_report;
pub mod plot_font;
pub mod plot_legend;
pub mod plot_png;
pub mod verdict;
