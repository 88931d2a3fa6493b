//! A small HTML reader for the tests: a page's elements with their attributes, parents
//! and text (entities decoded), enough to read a report's verdict section and its links
//! without relying on how `html_report` lays out its markup: tags in any case, attributes
//! quoted either way or bare, comments, void elements, and raw text in `script`/`style`.

/// One element of a page.
#[derive(Debug, Clone)]
pub struct Element {
    /// Tag name, lower case.
    pub name: String,
    /// Attributes, names lower case, values decoded.
    pub attrs: Vec<(String, String)>,
    /// All the text inside it, entities decoded.
    pub text: String,
    /// Index of its parent in the document (`None`: top level).
    pub parent: Option<usize>,
}

impl Element {
    /// The value of attribute `name`.
    pub fn attr(&self, name: &str) -> Option<&str> {
        self.attrs.iter().find(|(n, _)| n == name).map(|(_, v)| v.as_str())
    }
}

const VOID: [&str; 8] = ["meta", "img", "br", "hr", "input", "link", "source", "wbr"];

/// Decode `&amp;`, `&lt;`, `&gt;`, `&quot;`, `&#39;`, `&apos;`, `&nbsp;` and numeric
/// references; anything else is kept as written.
pub fn decode(s: &str) -> String {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find('&') {
        out.push_str(&rest[..i]);
        rest = &rest[i..];
        let Some(end) = rest.find(';').filter(|&e| e <= 10) else {
            out.push('&');
            rest = &rest[1..];
            continue;
        };
        let name = &rest[1..end];
        let c = match name {
            "amp" => Some('&'),
            "lt" => Some('<'),
            "gt" => Some('>'),
            "quot" => Some('"'),
            "apos" => Some('\''),
            "nbsp" => Some('\u{a0}'),
            n if n.starts_with("#x") || n.starts_with("#X") => {
                u32::from_str_radix(&n[2..], 16).ok().and_then(char::from_u32)
            }
            n if n.starts_with('#') => n[1..].parse().ok().and_then(char::from_u32),
            _ => None,
        };
        match c {
            Some(c) => {
                out.push(c);
                rest = &rest[end + 1..];
            }
            None => {
                out.push('&');
                rest = &rest[1..];
            }
        }
    }
    out.push_str(rest);
    out
}

fn parse_attrs(s: &str) -> Vec<(String, String)> {
    let b = s.as_bytes();
    let mut i = 0;
    let mut out = Vec::new();
    while i < b.len() {
        while i < b.len() && (b[i].is_ascii_whitespace() || b[i] == b'/') {
            i += 1;
        }
        let start = i;
        while i < b.len() && !b[i].is_ascii_whitespace() && b[i] != b'=' && b[i] != b'/' {
            i += 1;
        }
        if start == i {
            break;
        }
        let name = s[start..i].to_ascii_lowercase();
        while i < b.len() && b[i].is_ascii_whitespace() {
            i += 1;
        }
        let mut value = String::new();
        if i < b.len() && b[i] == b'=' {
            i += 1;
            while i < b.len() && b[i].is_ascii_whitespace() {
                i += 1;
            }
            if i < b.len() && (b[i] == b'"' || b[i] == b'\'') {
                let q = b[i];
                let v0 = i + 1;
                i = v0;
                while i < b.len() && b[i] != q {
                    i += 1;
                }
                value = decode(&s[v0..i.min(b.len())]);
                i += 1;
            } else {
                let v0 = i;
                while i < b.len() && !b[i].is_ascii_whitespace() {
                    i += 1;
                }
                value = decode(&s[v0..i]);
            }
        }
        out.push((name, value));
    }
    out
}

/// The elements of `html`, in document order.
pub fn parse(html: &str) -> Vec<Element> {
    let mut doc: Vec<Element> = Vec::new();
    let mut open: Vec<usize> = Vec::new();
    let mut rest = html;
    let add_text = |doc: &mut Vec<Element>, open: &[usize], t: &str| {
        let t = decode(t);
        for &i in open {
            doc[i].text.push_str(&t);
        }
    };
    while !rest.is_empty() {
        let Some(lt) = rest.find('<') else {
            add_text(&mut doc, &open, rest);
            break;
        };
        add_text(&mut doc, &open, &rest[..lt]);
        rest = &rest[lt..];
        if let Some(after) = rest.strip_prefix("<!--") {
            rest = after.find("-->").map_or("", |e| &after[e + 3..]);
            continue;
        }
        let Some(gt) = rest.find('>') else { break };
        let tag = &rest[1..gt];
        rest = &rest[gt + 1..];
        if tag.starts_with('!') || tag.starts_with('?') {
            continue;
        }
        if let Some(name) = tag.strip_prefix('/') {
            let name = name.trim().to_ascii_lowercase();
            if let Some(k) = open.iter().rposition(|&i| doc[i].name == name) {
                open.truncate(k);
            }
            continue;
        }
        let split = tag.find(|c: char| c.is_ascii_whitespace() || c == '/').unwrap_or(tag.len());
        let name = tag[..split].to_ascii_lowercase();
        let attrs = parse_attrs(&tag[split..]);
        doc.push(Element { name: name.clone(), attrs, text: String::new(), parent: open.last().copied() });
        let idx = doc.len() - 1;
        if name == "script" || name == "style" {
            // Raw text: up to the closing tag, not parsed as markup.
            let close = format!("</{name}");
            let end = rest.to_ascii_lowercase().find(&close).unwrap_or(rest.len());
            doc[idx].text.push_str(&rest[..end]);
            rest = &rest[end..];
            rest = rest.find('>').map_or("", |e| &rest[e + 1..]);
            continue;
        }
        if !(VOID.contains(&name.as_str()) || tag.ends_with('/')) {
            open.push(idx);
        }
    }
    doc
}

/// Whether element `i` lies inside element `ancestor`.
pub fn inside(doc: &[Element], mut i: usize, ancestor: usize) -> bool {
    while let Some(p) = doc[i].parent {
        if p == ancestor {
            return true;
        }
        i = p;
    }
    false
}

/// The texts of the `<li>` items inside the element whose `id` is `id`, trimmed (inner
/// whitespace kept as written: the console's lines must match it exactly); `None` when
/// no element has that id.
pub fn list_items_in(html: &str, id: &str) -> Option<Vec<String>> {
    let doc = parse(html);
    let s = doc.iter().position(|e| e.attr("id") == Some(id))?;
    Some(
        doc.iter()
            .enumerate()
            .filter(|(i, e)| e.name == "li" && inside(&doc, *i, s))
            .map(|(_, e)| e.text.trim().to_string())
            .collect(),
    )
}

/// Every `href` of an `<a>` in `html`, decoded.
pub fn hrefs(html: &str) -> Vec<String> {
    parse(html).iter().filter(|e| e.name == "a").filter_map(|e| e.attr("href").map(String::from)).collect()
}

/// `%XX` sequences of a URL path decoded.
pub fn percent_decode(s: &str) -> String {
    let b = s.as_bytes();
    let mut out = Vec::with_capacity(b.len());
    let mut i = 0;
    while i < b.len() {
        if b[i] == b'%' && i + 2 < b.len() {
            if let Ok(v) = u8::from_str_radix(&s[i + 1..i + 3], 16) {
                out.push(v);
                i += 3;
                continue;
            }
        }
        out.push(b[i]);
        i += 1;
    }
    String::from_utf8_lossy(&out).into_owned()
}
