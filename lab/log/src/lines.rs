//! Line numbers of CSV records as an editor shows them, for both readers' messages.
//!
//! The `csv` crate's `Position::line` is not that number: on CRLF files it lags by one from
//! the second record on (a record ends at the `\r`, so the `\n` is counted only when the
//! next record has already started), blank lines are skipped without being counted, and a
//! CR-only file stays on line 1. The byte offset of a record is exact, so the line is
//! counted here from the bytes: every `\n`, and every `\r` not followed by `\n`, before
//! the record's first byte.

/// Counts lines up to records' start offsets, in increasing order.
#[derive(Debug)]
pub(crate) struct LineCounter<'a> {
    text: &'a [u8],
    pos: usize,
    line: u64,
}

impl<'a> LineCounter<'a> {
    /// A counter over the whole text of a file.
    #[must_use]
    pub(crate) fn new(text: &'a [u8]) -> Self {
        Self { text, pos: 0, line: 1 }
    }

    /// The 1-based line of the record that the `csv` crate says starts at byte `start`.
    /// That offset may point at the terminator bytes before the record (the `\n` of a
    /// CRLF, blank lines): they are skipped first. Offsets must not decrease.
    pub(crate) fn line_of(&mut self, start: u64) -> u64 {
        let n = self.text.len();
        let mut b = usize::try_from(start).unwrap_or(n).min(n);
        while b < n && matches!(self.text[b], b'\r' | b'\n') {
            b += 1;
        }
        if b < self.pos {
            // Not expected (offsets increase); count again from the start rather than
            // give a wrong number.
            self.pos = 0;
            self.line = 1;
        }
        for i in self.pos..b {
            match self.text[i] {
                b'\n' => self.line += 1,
                b'\r' if self.text.get(i + 1) != Some(&b'\n') => self.line += 1,
                _ => {}
            }
        }
        self.pos = b;
        self.line
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Lines of the first field of every record, through the csv crate as the readers use it.
    fn lines(text: &str) -> Vec<(String, u64)> {
        let mut rdr = csv::ReaderBuilder::new().has_headers(false).flexible(true).from_reader(text.as_bytes());
        let mut lc = LineCounter::new(text.as_bytes());
        let mut rec = csv::ByteRecord::new();
        let mut out = Vec::new();
        while rdr.read_byte_record(&mut rec).unwrap() {
            let line = lc.line_of(rec.position().unwrap().byte());
            out.push((String::from_utf8_lossy(&rec[0]).into_owned(), line));
        }
        out
    }

    #[test]
    fn lines_as_an_editor_shows_them() {
        let want = |v: &[(&str, u64)]| v.iter().map(|(s, l)| ((*s).to_string(), *l)).collect::<Vec<_>>();
        // LF, CRLF, CR-only, and each with a blank line before `c` (line 5).
        for end in ["\n", "\r\n", "\r"] {
            let text = ["h", "a", "b", "", "c", ""].join(end);
            assert_eq!(lines(&text), want(&[("h", 1), ("a", 2), ("b", 3), ("c", 5)]), "{text:?}");
        }
        // A quoted field spanning two lines: the next record is on line 4.
        assert_eq!(lines("h\n\"a\nb\"\nc\n"), want(&[("h", 1), ("a\nb", 2), ("c", 4)]));
    }
}

/// Rows a reader skipped for one reason: the count and the first
/// line numbers a reader keeps (20; 1-based, the header is line 1).
#[derive(Clone, Debug, Default, PartialEq, Eq, serde::Serialize)]
pub struct SkipCount {
    /// Rows skipped.
    pub count: usize,
    /// First line numbers.
    pub lines: Vec<u64>,
}

impl SkipCount {
    /// The lines kept, as a message lists them: `3, 7, 12, ...` (the dots when more rows
    /// were counted than kept).
    #[must_use]
    pub fn listed(&self) -> String {
        let lines: Vec<String> = self.lines.iter().map(u64::to_string).collect();
        let more = if self.count > self.lines.len() { ", ..." } else { "" };
        format!("{}{more}", lines.join(", "))
    }

    /// Count the row at `line`, keeping its number while fewer are kept than the limit.
    pub(crate) fn add(&mut self, line: u64) {
        self.count += 1;
        if self.lines.len() < crate::static_log::KEPT_LINES {
            self.lines.push(line);
        }
    }
}
