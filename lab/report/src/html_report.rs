//! `report.html`: the one page each run writes into its output folder, self-contained
//! (plots inline as base64 PNG data URIs, no script, no external file), built from sections,
//! key/value tables, tables, warnings, preformatted text and images.
//!
//! Every command that writes a page (`calibrate`, `discover`, `navigate`, `demo`) goes
//! through [`Page`]; the page always opens with the command line that produced it.

use crate::plot_png::Plot;
use std::fmt::Write as _;
use std::path::{Path, PathBuf};

/// File name of the page in an output folder.
pub const FILE: &str = "report.html";

const STYLE: &str = "body{font-family:sans-serif;max-width:1700px;margin:1em auto;padding:0 1em;color:#222}\
h1{font-size:1.5em}h2{font-size:1.2em;border-bottom:1px solid #ccc;margin-top:1.6em}\
table{border-collapse:collapse;margin:.5em 0}td,th{border:1px solid #bbb;padding:2px 8px;text-align:left;\
vertical-align:top}th{background:#eee}pre{background:#f6f6f6;padding:.5em;overflow-x:auto;white-space:pre-wrap}\
.warn{background:#fff3cd;border:1px solid #e0b000;padding:.4em .8em;margin:.4em 0}\
.fail{background:#f8d7da;border:1px solid #c0392b;padding:.4em .8em;margin:.4em 0}\
.pass{background:#d4edda;border:1px solid #2e7d32;padding:.4em .8em;margin:.4em 0}\
figure{margin:1em 0}img{max-width:100%;border:1px solid #ddd}figcaption{font-size:.9em;color:#555}\
code{background:#f0f0f0}";

/// A page under construction.
#[derive(Clone, Debug)]
pub struct Page {
    title: String,
    body: String,
}

impl Page {
    /// A page titled `title`, opening with the process's command line ([`command_line`]).
    #[must_use]
    pub fn new(title: &str) -> Self {
        Self::with_command(title, &command_line())
    }

    /// A page titled `title`, opening with `command`: what produced it, when that is not
    /// this process's command line (a batch's unit pages, written by whichever worker
    /// ran the unit, name the batch instead, so every worker writes the same bytes).
    #[must_use]
    pub fn with_command(title: &str, command: &str) -> Self {
        let mut p = Self { title: title.to_string(), body: String::new() };
        let _ = write!(p.body, "<h1>{}</h1>\n<p>Command: <code>{}</code></p>\n", escape(title), escape(command));
        p
    }

    /// Markup the caller built and escaped (the verdict's section,
    /// [`crate::verdict::Verdict::to_page`]).
    pub fn raw(&mut self, html: &str) -> &mut Self {
        self.body.push_str(html);
        self
    }

    /// A section heading.
    pub fn section(&mut self, heading: &str) -> &mut Self {
        let _ = writeln!(self.body, "<h2>{}</h2>", escape(heading));
        self
    }

    /// A paragraph of text.
    pub fn para(&mut self, text: &str) -> &mut Self {
        let _ = writeln!(self.body, "<p>{}</p>", escape(text));
        self
    }

    /// A warning, set off from the text.
    pub fn warning(&mut self, text: &str) -> &mut Self {
        let _ = writeln!(self.body, "<div class=\"warn\"><b>Warning:</b> {}</div>", escape(text));
        self
    }

    /// Preformatted text (a Markdown report, a console summary).
    pub fn pre(&mut self, text: &str) -> &mut Self {
        let _ = writeln!(self.body, "<pre>{}</pre>", escape(text));
        self
    }

    /// Preformatted text folded under `summary` (long detail).
    pub fn details(&mut self, summary: &str, text: &str) -> &mut Self {
        let _ =
            writeln!(self.body, "<details><summary>{}</summary><pre>{}</pre></details>", escape(summary), escape(text));
        self
    }

    /// A two-column table of names and values.
    pub fn kv<K: AsRef<str>, V: AsRef<str>>(&mut self, rows: &[(K, V)]) -> &mut Self {
        self.body.push_str("<table>\n");
        for (k, v) in rows {
            let _ = writeln!(self.body, "<tr><th>{}</th><td>{}</td></tr>", escape(k.as_ref()), escape(v.as_ref()));
        }
        self.body.push_str("</table>\n");
        self
    }

    /// A table with a header row.
    pub fn table<H: AsRef<str>, C: AsRef<str>>(&mut self, header: &[H], rows: &[Vec<C>]) -> &mut Self {
        self.body.push_str("<table>\n<tr>");
        for h in header {
            let _ = write!(self.body, "<th>{}</th>", escape(h.as_ref()));
        }
        self.body.push_str("</tr>\n");
        for r in rows {
            self.body.push_str("<tr>");
            for c in r {
                let _ = write!(self.body, "<td>{}</td>", escape(c.as_ref()));
            }
            self.body.push_str("</tr>\n");
        }
        self.body.push_str("</table>\n");
        self
    }

    /// A list of links, `(text, href)` each; `href` is a path relative to the page's
    /// folder (`kt8-1/report.html`), percent-encoded and escaped here.
    pub fn links<T: AsRef<str>, H: AsRef<str>>(&mut self, links: &[(T, H)]) -> &mut Self {
        self.body.push_str("<ul>\n");
        for (text, href) in links {
            let _ = writeln!(
                self.body,
                "<li><a href=\"{}\">{}</a></li>",
                escape(&percent_encode(href.as_ref())),
                escape(text.as_ref())
            );
        }
        self.body.push_str("</ul>\n");
        self
    }

    /// A plot embedded as a data URI, with its caption (the file name is added): the bytes
    /// the run drew, never a file read back.
    pub fn plot(&mut self, plot: &Plot, caption: &str) -> &mut Self {
        let _ = writeln!(
            self.body,
            "<figure><img alt=\"{}\" src=\"data:image/png;base64,{}\"><figcaption>{} (<code>{}</code>)</figcaption></figure>",
            escape(&plot.file),
            base64(plot.png()),
            escape(caption),
            escape(&plot.file)
        );
        self
    }

    /// Each of `plots` (what this run drew), in their order, captioned by `caption(file)`.
    pub fn plots(&mut self, plots: &[Plot], caption: impl Fn(&str) -> String) -> &mut Self {
        for p in plots {
            self.plot(p, &caption(&p.file));
        }
        self
    }

    /// The complete document.
    #[must_use]
    pub fn html(&self) -> String {
        format!(
            "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n<title>{}</title>\n\
             <style>{STYLE}</style>\n</head>\n<body>\n{}</body>\n</html>\n",
            escape(&self.title),
            self.body
        )
    }

    /// Write the page as `dir/report.html`; returns its path.
    ///
    /// # Errors
    /// I/O.
    pub fn write(&self, dir: &Path) -> std::io::Result<PathBuf> {
        let p = dir.join(FILE);
        std::fs::write(&p, self.html()).map_err(|e| std::io::Error::new(e.kind(), format!("{}: {e}", p.display())))?;
        Ok(p)
    }
}

/// `text` with `&`, `<`, `>`, `"` and `'` escaped, for element text and attribute values.
#[must_use]
pub fn escape(text: &str) -> String {
    let mut s = String::with_capacity(text.len());
    for c in text.chars() {
        match c {
            '&' => s.push_str("&amp;"),
            '<' => s.push_str("&lt;"),
            '>' => s.push_str("&gt;"),
            '"' => s.push_str("&quot;"),
            '\'' => s.push_str("&#39;"),
            c => s.push(c),
        }
    }
    s
}

/// The bytes a URL path keeps as they are: RFC 3986's unreserved characters and `/`.
const URL_PATH_KEEPS: &percent_encoding::AsciiSet =
    &percent_encoding::NON_ALPHANUMERIC.remove(b'-').remove(b'.').remove(b'_').remove(b'~').remove(b'/');

/// A relative path as a URL path: every byte outside RFC 3986's unreserved characters and
/// `/` percent-encoded (a space, `#` or `?` in a folder name would otherwise end the path).
#[must_use]
pub fn percent_encode(path: &str) -> String {
    percent_encoding::utf8_percent_encode(path, URL_PATH_KEEPS).to_string()
}

/// Standard base64 (RFC 4648, with padding), as a data URI holds an image.
#[must_use]
pub fn base64(bytes: &[u8]) -> String {
    use base64::Engine as _;
    base64::engine::general_purpose::STANDARD.encode(bytes)
}

/// The process's command line, each argument quoted for a POSIX shell when it needs it.
#[must_use]
pub fn command_line() -> String {
    let plain = |a: &str| !a.is_empty() && a.chars().all(|c| c.is_ascii_alphanumeric() || "-_./=,:+@%".contains(c));
    std::env::args()
        .map(|a| if plain(&a) { a } else { format!("'{}'", a.replace('\'', "'\\''")) })
        .collect::<Vec<_>>()
        .join(" ")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn base64_matches_rfc4648_vectors() {
        for (i, o) in
            [("", ""), ("f", "Zg=="), ("fo", "Zm8="), ("foo", "Zm9v"), ("foob", "Zm9vYg=="), ("fooba", "Zm9vYmE=")]
        {
            assert_eq!(base64(i.as_bytes()), o, "{i:?}");
        }
        assert_eq!(base64(&[0xff, 0xfe, 0xfd]), "//79");
    }

    /// The encoding a browser undoes (RFC 3986): unreserved bytes and `/` kept, the rest of
    /// the UTF-8 bytes as `%XX`.
    #[test]
    fn a_path_is_percent_encoded_byte_by_byte() {
        assert_eq!(percent_encode("run 1/a#b?c/Ω-x_y.z~w.html"), "run%201/a%23b%3Fc/%CE%A9-x_y.z~w.html");
    }

    #[test]
    fn text_is_escaped_everywhere() {
        let mut p = Page::new("a <b> & \"c\"");
        p.section("<h>").para("x < y").warning("'w'").kv(&[("k&", "v>")]).table(&["<t>"], &[vec!["&"]]);
        let h = p.html();
        assert!(h.contains("<title>a &lt;b&gt; &amp; &quot;c&quot;</title>"), "{h}");
        for s in ["<h2>&lt;h&gt;</h2>", "x &lt; y", "&#39;w&#39;", "<th>k&amp;</th><td>v&gt;</td>", "<td>&amp;</td>"] {
            assert!(h.contains(s), "{s} in {h}");
        }
        assert!(!h.contains("<script"), "no script in a report");
        let mut p = Page::new("links");
        p.links(&[("a & b", "kt8 #1/report.html?x\"")]);
        assert!(p.html().contains("<li><a href=\"kt8%20%231/report.html%3Fx%22\">a &amp; b</a></li>"), "{}", p.html());
    }

    /// A plot is inlined from the bytes it was drawn into, with its name and caption
    /// escaped; no file is read.
    #[test]
    fn a_plot_is_inlined_from_its_bytes() {
        let plot = crate::plot_png::Plot::draw("a&b.png", (40, 30), |root| root.fill(&plotters::style::WHITE))
            .expect("a white plot");
        let mut p = Page::new("t");
        p.plots(std::slice::from_ref(&plot), |f| format!("caption of {f} <x>"));
        let h = p.html();
        assert!(h.contains(&format!("src=\"data:image/png;base64,{}\"", base64(plot.png()))), "{h}");
        assert!(h.contains("caption of a&amp;b.png &lt;x&gt; (<code>a&amp;b.png</code>)"), "{h}");
    }
}
