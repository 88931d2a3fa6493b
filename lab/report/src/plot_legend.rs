//! A panel's heading: its title, then its legend in a strip of its own above the chart, so
//! a legend never covers data (plotters' in-chart legend sits on whatever is drawn in its
//! corner).

use plotters::coord::Shift;
use plotters::prelude::*;

/// How an entry's series is drawn.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mark {
    /// A line in the series' colour.
    Line,
    /// A filled dot in the series' colour.
    Dot,
}

/// One legend entry: the series' name, colour and mark.
pub type Entry = (String, RGBColor, Mark);

/// Why a drawing on a bitmap failed (plotters does not name this type): the backend's
/// error (writing or encoding the image) or the drawing area's own. It is `Send` and
/// `Sync`, so error enums can hold it.
pub type DrawError = DrawingAreaErrorKind<<BitMapBackend<'static> as DrawingBackend>::ErrorType>;

type DrawResult = Result<(), DrawError>;

/// Height of one line of a heading, px (a 16-px title or a 14-px legend row).
pub const LINE_PX: u32 = 22;

const SAMPLE_PX: i32 = 22;
const GAP_PX: i32 = 18;
const LEFT_PX: i32 = 12;

/// Legend rows `entries` take in a strip `width` px wide (each entry its mark and name;
/// an entry that does not fit starts a new row).
#[must_use]
pub fn rows_needed(area: &DrawingArea<BitMapBackend<'_>, Shift>, entries: &[Entry]) -> u32 {
    layout(area, entries).last().map_or(0, |&(_, row)| row + 1)
}

fn layout(area: &DrawingArea<BitMapBackend<'_>, Shift>, entries: &[Entry]) -> Vec<(i32, u32)> {
    let width = area.dim_in_pixel().0 as i32;
    let font = ("sans-serif", 14).into_text_style(area);
    let (mut x, mut row) = (LEFT_PX, 0u32);
    let mut out = Vec::new();
    for (name, _, _) in entries {
        let w = SAMPLE_PX + 6 + area.estimate_text_size(name, &font).map_or(8 * name.len() as u32, |s| s.0) as i32;
        if x > LEFT_PX && x + w > width - LEFT_PX {
            x = LEFT_PX;
            row += 1;
        }
        out.push((x, row));
        x += w + GAP_PX;
    }
    out
}

/// Split `area` into a heading (the title centred on its first line, the legend on the
/// lines below) and the rest, which is returned for the chart.
///
/// # Errors
/// Drawing errors.
pub fn heading<'a>(
    area: &DrawingArea<BitMapBackend<'a>, Shift>,
    title: &str,
    entries: &[Entry],
) -> Result<DrawingArea<BitMapBackend<'a>, Shift>, DrawError> {
    let lines = 1 + rows_needed(area, entries);
    let (head, chart) = area.split_vertically(LINE_PX * lines + 4);
    let (title_area, legend_area) = head.split_vertically(LINE_PX);
    title_area.draw_text(
        title,
        &("sans-serif", 16).into_font().color(&BLACK).pos(plotters::style::text_anchor::Pos::new(
            plotters::style::text_anchor::HPos::Center,
            plotters::style::text_anchor::VPos::Center,
        )),
        (title_area.dim_in_pixel().0 as i32 / 2, LINE_PX as i32 / 2),
    )?;
    draw_entries(&legend_area, entries)?;
    Ok(chart)
}

fn draw_entries(area: &DrawingArea<BitMapBackend<'_>, Shift>, entries: &[Entry]) -> DrawResult {
    let font = ("sans-serif", 14).into_font();
    for ((name, color, mark), (x, row)) in entries.iter().zip(layout(area, entries)) {
        let y = (row * LINE_PX + LINE_PX / 2) as i32;
        match mark {
            Mark::Line => area.draw(&PathElement::new(vec![(x, y), (x + SAMPLE_PX, y)], color.stroke_width(3)))?,
            Mark::Dot => area.draw(&Circle::new((x + SAMPLE_PX / 2, y), 4, color.filled()))?,
        }
        area.draw_text(
            name,
            &font.color(&BLACK).pos(plotters::style::text_anchor::Pos::new(
                plotters::style::text_anchor::HPos::Left,
                plotters::style::text_anchor::VPos::Center,
            )),
            (x + SAMPLE_PX + 6, y),
        )?;
    }
    Ok(())
}
