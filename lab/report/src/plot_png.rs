//! A plot drawn in memory ([`Plot`]): its PNG bytes are written into the run's folder and
//! inlined in the run's page from the same bytes. A page therefore never reads a file back,
//! and cannot show a PNG that another run left in the folder.

use std::fmt;
use std::path::{Path, PathBuf};

use image::ImageEncoder;
use plotters::coord::Shift;
use plotters::prelude::*;

use crate::plot_legend::DrawError;

/// The drawing area a plot draws on: a bitmap in memory.
pub type Area<'a> = DrawingArea<BitMapBackend<'a>, Shift>;

/// Why a plot could not be made: the drawing failed, or its bitmap did not encode as a PNG.
#[derive(Debug)]
#[non_exhaustive]
pub enum PlotError {
    /// The drawing area's or the backend's error.
    Draw(DrawError),
    /// The PNG encoder's error.
    Encode(image::ImageError),
}

impl fmt::Display for PlotError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Draw(e) => write!(f, "drawing: {e}"),
            Self::Encode(e) => write!(f, "encoding the PNG: {e}"),
        }
    }
}

impl std::error::Error for PlotError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        match self {
            Self::Draw(e) => Some(e),
            Self::Encode(e) => Some(e),
        }
    }
}

impl From<DrawError> for PlotError {
    fn from(e: DrawError) -> Self {
        Self::Draw(e)
    }
}

/// One plot: the file name it is written under and its PNG bytes.
#[derive(Clone, PartialEq, Eq)]
pub struct Plot {
    /// The file name (`sf_vs_temp.png`), inside the run's folder.
    pub file: String,
    /// The encoded PNG: only [`Plot::draw`] makes one, so it is always a PNG.
    png: Vec<u8>,
}

impl fmt::Debug for Plot {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(f, "Plot {{ file: {:?}, png: {} bytes }}", self.file, self.png.len())
    }
}

impl Plot {
    /// Draw a `width` × `height` px plot named `file` with `draw`, on the one plot font, and
    /// encode it as PNG: the bytes plotters' own `BitMapBackend::new(path, …)` writes to a file
    /// (the same RGB buffer through the same `image` PNG encoder at its defaults).
    ///
    /// # Errors
    /// The drawing's error, or the encoder's.
    pub fn draw(
        file: impl Into<String>,
        (width, height): (u32, u32),
        draw: impl FnOnce(&Area<'_>) -> Result<(), DrawError>,
    ) -> Result<Self, PlotError> {
        crate::plot_font::register();
        let mut rgb = vec![0u8; 3 * width as usize * height as usize];
        {
            let root = BitMapBackend::with_buffer(&mut rgb, (width, height)).into_drawing_area();
            draw(&root)?;
            root.present()?;
        }
        let mut png = Vec::new();
        image::codecs::png::PngEncoder::new(&mut png)
            .write_image(&rgb, width, height, image::ColorType::Rgb8)
            .map_err(PlotError::Encode)?;
        Ok(Self { file: file.into(), png })
    }

    /// The PNG's bytes.
    #[must_use]
    pub fn png(&self) -> &[u8] {
        &self.png
    }

    /// Write the plot as `dir/<file>`; returns its path.
    ///
    /// # Errors
    /// I/O, the path named.
    pub fn write_into(&self, dir: &Path) -> std::io::Result<PathBuf> {
        let p = dir.join(&self.file);
        std::fs::write(&p, &self.png).map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", p.display())))?;
        Ok(p)
    }
}

/// Write every plot of `plots` into `dir`.
///
/// # Errors
/// The first that could not be written.
pub fn write_all(plots: &[Plot], dir: &Path) -> std::io::Result<()> {
    for p in plots {
        p.write_into(dir)?;
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn scene(root: &Area<'_>) -> Result<(), DrawError> {
        root.fill(&WHITE)?;
        let mut chart = ChartBuilder::on(root)
            .margin(10)
            .caption("a scene", ("sans-serif", 20))
            .x_label_area_size(30)
            .y_label_area_size(40)
            .build_cartesian_2d(0.0..10.0, -1.0..1.0)?;
        chart.configure_mesh().x_desc("x").draw()?;
        chart.draw_series(LineSeries::new((0..100).map(|i| (f64::from(i) / 10.0, (f64::from(i) / 7.0).sin())), RED))?;
        Ok(())
    }

    /// The bytes in memory are the bytes plotters writes to a file itself, so a plot moved
    /// from a file backend to [`Plot::draw`] changes no output file.
    #[test]
    fn a_plot_in_memory_is_the_file_plotters_writes() {
        let dir = std::env::temp_dir().join(format!("qfa-plot-png-{}", std::process::id()));
        std::fs::create_dir_all(&dir).expect("a temporary folder");
        let on_disk = dir.join("scene.png");
        crate::plot_font::register();
        {
            let root = BitMapBackend::new(&on_disk, (320, 200)).into_drawing_area();
            scene(&root).expect("drawn");
            root.present().expect("written");
        }
        let file = std::fs::read(&on_disk).expect("plotters wrote it");
        let plot = Plot::draw("scene.png", (320, 200), scene).expect("drawn in memory");
        assert!(plot.png.starts_with(b"\x89PNG\r\n\x1a\n"));
        assert_eq!(plot.png, file, "the encoder's bytes differ from plotters' file");
        let again = dir.join("again");
        std::fs::create_dir_all(&again).expect("a folder");
        assert_eq!(plot.write_into(&again).expect("written"), again.join("scene.png"));
        assert_eq!(std::fs::read(again.join("scene.png")).expect("read"), file);
        std::fs::remove_dir_all(&dir).expect("removed");
    }

    /// A drawing that fails is the drawing's error, not an empty PNG.
    #[test]
    fn a_drawing_that_fails_is_an_error() {
        let e = Plot::draw("bad.png", (100, 100), |root| {
            root.fill(&WHITE)?;
            Err(DrawingAreaErrorKind::LayoutError)
        })
        .expect_err("a failing drawing");
        assert!(matches!(e, PlotError::Draw(_)), "{e:?}");
        assert!(e.to_string().starts_with("drawing: "), "{e}");
    }
}
