//! Positions of fields in scene text: field path -> line/column, and byte offset -> field path.
//!
//! Uses `toml_edit`'s span-preserving [`toml_edit::Document`].

use toml_edit::{Array, ArrayOfTables, InlineTable, Item, Table, Value};

type Doc<'a> = toml_edit::Document<&'a str>;

/// 1-based (line, column) of byte `offset` in `text` (column counted in characters).
pub fn line_col(text: &str, offset: usize) -> (usize, usize) {
    let mut offset = offset.min(text.len());
    while !text.is_char_boundary(offset) {
        offset -= 1;
    }
    let before = &text[..offset];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map(|i| i + 1).unwrap_or(0);
    let col = text[line_start..offset].chars().count() + 1;
    (line, col)
}

#[derive(Debug, PartialEq)]
enum Seg<'p> {
    Key(&'p str),
    Index(usize),
}

/// Split `material[1].poisson_ratio` into `material`, `1`, `poisson_ratio`.
fn parse_path(path: &str) -> Vec<Seg<'_>> {
    let mut segs = Vec::new();
    for part in path.split('.') {
        let (key, mut rest) = match part.find('[') {
            Some(i) => (&part[..i], &part[i..]),
            None => (part, ""),
        };
        if !key.is_empty() {
            segs.push(Seg::Key(key));
        }
        while let Some(stripped) = rest.strip_prefix('[') {
            let Some(end) = stripped.find(']') else { break };
            if let Ok(i) = stripped[..end].parse() {
                segs.push(Seg::Index(i));
            }
            rest = &stripped[end + 1..];
        }
    }
    segs
}

#[derive(Clone, Copy)]
enum Node<'a> {
    Table(&'a Table),
    Inline(&'a InlineTable),
    Aot(&'a ArrayOfTables),
    Array(&'a Array),
    Leaf,
}

fn node_of_item(item: &Item) -> Node<'_> {
    match item {
        Item::Table(t) => Node::Table(t),
        Item::ArrayOfTables(a) => Node::Aot(a),
        Item::Value(v) => node_of_value(v),
        Item::None => Node::Leaf,
    }
}

fn node_of_value(v: &Value) -> Node<'_> {
    match v {
        Value::InlineTable(t) => Node::Inline(t),
        Value::Array(a) => Node::Array(a),
        _ => Node::Leaf,
    }
}

/// Byte span of the deepest part of `path` found in the parsed document (the key of the last
/// segment when present; otherwise the nearest enclosing key or table).
pub fn span_in_doc(doc: &Doc<'_>, path: &str) -> Option<usize> {
    let mut node = Node::Table(doc.as_table());
    let mut best: Option<usize> = None;
    for seg in parse_path(path) {
        let next = match (seg, node) {
            (Seg::Key(k), Node::Table(t)) => t
                .get_key_value(k)
                .map(|(key, item)| (key.span().or_else(|| item.span()), node_of_item(item))),
            (Seg::Key(k), Node::Inline(t)) => t
                .get_key_value(k)
                .map(|(key, item)| (key.span().or_else(|| item.span()), node_of_item(item))),
            (Seg::Index(i), Node::Aot(a)) => a.get(i).map(|t| (t.span(), Node::Table(t))),
            (Seg::Index(i), Node::Array(a)) => a.get(i).map(|v| (v.span(), node_of_value(v))),
            _ => None,
        };
        match next {
            Some((span, n)) => {
                if let Some(s) = span {
                    best = Some(s.start);
                }
                node = n;
            }
            None => break,
        }
    }
    best
}

/// 1-based (line, column) of the field at `path` (e.g. `material[1].poisson_ratio`) in the
/// TOML `text`, or of its deepest enclosing part that exists. `None` if the text does not parse.
pub fn span_of(text: &str, path: &str) -> Option<(usize, usize)> {
    let doc = Doc::parse(text).ok()?;
    span_in_doc(&doc, path).map(|o| line_col(text, o))
}

/// Dotted path of the key or value whose span contains byte `offset` (deepest match), e.g.
/// `body[0].radius`; array-of-tables entries whose span contains it give `body[0]`.
pub fn path_at(doc: &Doc<'_>, offset: usize) -> Option<String> {
    fn contains(span: Option<std::ops::Range<usize>>, o: usize) -> bool {
        span.is_some_and(|s| s.start <= o && o < s.end.max(s.start + 1))
    }
    fn walk_table<'a>(
        entries: Vec<(&'a toml_edit::Key, &'a Item)>,
        prefix: &str,
        o: usize,
    ) -> Option<String> {
        for (key, item) in entries {
            let path = if prefix.is_empty() {
                key.get().to_string()
            } else {
                format!("{prefix}.{}", key.get())
            };
            if let Some(p) = walk_item(item, &path, o) {
                return Some(p);
            }
            if contains(key.span(), o) || contains(item.span(), o) {
                return Some(path);
            }
        }
        None
    }
    fn walk_item(item: &Item, path: &str, o: usize) -> Option<String> {
        match node_of_item(item) {
            Node::Table(t) => walk_table(t.iter_kv(), path, o),
            Node::Inline(t) => walk_table(t.iter_kv(), path, o),
            Node::Aot(a) => {
                for (i, t) in a.iter().enumerate() {
                    let p = format!("{path}[{i}]");
                    if let Some(found) = walk_table(t.iter_kv(), &p, o) {
                        return Some(found);
                    }
                    if contains(t.span(), o) {
                        return Some(p);
                    }
                }
                None
            }
            Node::Array(a) => {
                for (i, v) in a.iter().enumerate() {
                    if contains(v.span(), o) {
                        return Some(format!("{path}[{i}]"));
                    }
                }
                None
            }
            Node::Leaf => None,
        }
    }
    walk_table(doc.as_table().iter_kv(), "", offset)
}

/// True when `path` names a table (a `[table]`, an inline table or an entry of an array of
/// tables) of the document; the empty path is the root table.
pub fn is_table(doc: &Doc<'_>, path: &str) -> bool {
    let mut node = Node::Table(doc.as_table());
    for seg in parse_path(path) {
        node = match (seg, node) {
            (Seg::Key(k), Node::Table(t)) => match t.get(k) {
                Some(i) => node_of_item(i),
                None => return false,
            },
            (Seg::Key(k), Node::Inline(t)) => match t.get(k) {
                Some(v) => node_of_value(v),
                None => return false,
            },
            (Seg::Index(i), Node::Aot(a)) => match a.get(i) {
                Some(t) => Node::Table(t),
                None => return false,
            },
            (Seg::Index(i), Node::Array(a)) => match a.get(i) {
                Some(v) => node_of_value(v),
                None => return false,
            },
            _ => return false,
        };
    }
    matches!(node, Node::Table(_) | Node::Inline(_))
}

/// The numbers written at `path` (one for a number, each number of an array of numbers),
/// exactly as the text gives them (before they are narrowed to the field's type); empty when
/// the path does not name a number or an array of them.
pub fn numbers_at(doc: &Doc<'_>, path: &str) -> Vec<f64> {
    fn number(v: &Value) -> Option<f64> {
        match v {
            Value::Float(f) => Some(*f.value()),
            Value::Integer(i) => Some(*i.value() as f64),
            _ => None,
        }
    }
    let mut item: Option<&Value> = None;
    let mut node = Node::Table(doc.as_table());
    for seg in parse_path(path) {
        let value = match (seg, node) {
            (Seg::Key(k), Node::Table(t)) => match t.get(k) {
                Some(Item::Value(v)) => Some(v),
                Some(i) => {
                    node = node_of_item(i);
                    item = None;
                    continue;
                }
                None => return Vec::new(),
            },
            (Seg::Key(k), Node::Inline(t)) => t.get(k),
            (Seg::Index(i), Node::Aot(a)) => match a.get(i) {
                Some(t) => {
                    node = Node::Table(t);
                    item = None;
                    continue;
                }
                None => return Vec::new(),
            },
            (Seg::Index(i), Node::Array(a)) => a.get(i),
            _ => return Vec::new(),
        };
        let Some(v) = value else {
            return Vec::new();
        };
        node = node_of_value(v);
        item = Some(v);
    }
    match item {
        Some(Value::Array(a)) => a.iter().filter_map(number).collect(),
        Some(v) => number(v).into_iter().collect(),
        None => Vec::new(),
    }
}

/// The field at byte `offset` read from the text alone, for text that `toml_edit` cannot parse
/// (e.g. an integer beyond 64 bits): the key before `=` on that line, under the last table
/// header above it (`[[body]]` headers counted, giving `body[2].count`).
pub fn path_by_text(text: &str, offset: usize) -> Option<String> {
    let offset = offset.min(text.len());
    let mut table = String::new();
    let mut counts: Vec<(String, usize)> = Vec::new();
    let mut line_start = 0;
    for line in text.split_inclusive('\n') {
        let end = line_start + line.len();
        let t = line.trim();
        if let Some(name) = t.strip_prefix("[[").and_then(|r| r.split("]]").next()) {
            let name = name.trim().to_string();
            let n = match counts.iter_mut().find(|(k, _)| *k == name) {
                Some((_, c)) => {
                    *c += 1;
                    *c - 1
                }
                None => {
                    counts.push((name.clone(), 1));
                    0
                }
            };
            table = format!("{name}[{n}]");
        } else if let Some(name) = t.strip_prefix('[').and_then(|r| r.split(']').next()) {
            table = name.trim().to_string();
        }
        if offset < end || end == text.len() {
            let key = t.split('=').next()?.trim().trim_matches('"');
            if key.is_empty() || key.starts_with('[') || !t.contains('=') {
                return None;
            }
            return Some(if table.is_empty() {
                key.to_string()
            } else {
                format!("{table}.{key}")
            });
        }
        line_start = end;
    }
    None
}

trait IterKv {
    fn iter_kv(&self) -> Vec<(&toml_edit::Key, &Item)>;
}

impl IterKv for Table {
    fn iter_kv(&self) -> Vec<(&toml_edit::Key, &Item)> {
        self.iter()
            .filter_map(|(k, _)| self.get_key_value(k))
            .collect()
    }
}

impl IterKv for InlineTable {
    fn iter_kv(&self) -> Vec<(&toml_edit::Key, &Item)> {
        self.iter()
            .filter_map(|(k, _)| self.get_key_value(k))
            .collect()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const TEXT: &str = "name = \"x\"\n[domain]\nmin = [0, 0, 0]\ndx = 0.1\n\n[[material]]\nname = \"a\"\n\n[[material]]\nname = \"b\"\n  poisson_ratio = 0.5\n";

    #[test]
    fn paths() {
        assert_eq!(
            parse_path("material[1].poisson_ratio"),
            vec![
                Seg::Key("material"),
                Seg::Index(1),
                Seg::Key("poisson_ratio")
            ]
        );
        assert_eq!(span_of(TEXT, "name"), Some((1, 1)));
        assert_eq!(span_of(TEXT, "domain.dx"), Some((4, 1)));
        assert_eq!(span_of(TEXT, "material[1].poisson_ratio"), Some((11, 3)));
        assert_eq!(span_of(TEXT, "domain.min[1]"), Some((3, 11)));
        // Missing field: falls back to the enclosing table.
        let (line, _) = span_of(TEXT, "material[1].density").unwrap();
        assert!((9..=10).contains(&line), "{line}");
    }

    #[test]
    fn offset_to_path() {
        let doc = Doc::parse(TEXT).unwrap();
        let off = TEXT.find("poisson").unwrap() + 3;
        assert_eq!(
            path_at(&doc, off).as_deref(),
            Some("material[1].poisson_ratio")
        );
        let off = TEXT.find("0.5").unwrap();
        assert_eq!(
            path_at(&doc, off).as_deref(),
            Some("material[1].poisson_ratio")
        );
        assert_eq!(line_col("ab\ncd", 4), (2, 2));
        assert!(is_table(&doc, "") && is_table(&doc, "material[1]") && is_table(&doc, "domain"));
        assert!(!is_table(&doc, "name") && !is_table(&doc, "domain.dx"));
    }

    #[test]
    fn numbers_as_written() {
        let t = "g = [0, -1e300, 2]\n[[m]]\nx = 1e-50\n[[m]]\nk = { a = [1.5] }\n";
        let doc = Doc::parse(t).unwrap();
        assert_eq!(numbers_at(&doc, "g"), vec![0.0, -1e300, 2.0]);
        assert_eq!(numbers_at(&doc, "g[1]"), vec![-1e300]);
        assert_eq!(numbers_at(&doc, "m[0].x"), vec![1e-50]);
        assert_eq!(numbers_at(&doc, "m[1].k.a"), vec![1.5]);
        assert!(numbers_at(&doc, "m[1]").is_empty() && numbers_at(&doc, "nope").is_empty());
    }

    #[test]
    fn path_from_text_alone() {
        let t = "seed = 1\n[[body]]\na = 1\n[[body]]\ncount = 99999999999999999999\n[time]\nx=1\n";
        let at = |s: &str| path_by_text(t, t.find(s).unwrap());
        assert_eq!(at("99999").as_deref(), Some("body[1].count"));
        assert_eq!(at("seed").as_deref(), Some("seed"));
        assert_eq!(at("x=1").as_deref(), Some("time.x"));
        assert_eq!(at("[time]"), None);
    }
}
