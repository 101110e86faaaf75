//! Reading a TOML document beyond what serde does: arrays of an exact length, and
//! where a place in it is (the key path to a value, [`Key`], and back from a byte
//! offset to a line, a column and a readable path such as `tube 2: length_mm`), for
//! errors that name the file, line and field.

use serde::Deserialize;

/// An array of exactly `N` numbers (serde's own arrays ignore extra elements).
pub(crate) fn exact<'de, D: serde::Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<[f64; N], D::Error> {
    let v = Vec::<f64>::deserialize(d)?;
    let len = v.len();
    v.try_into().map_err(|_| {
        serde::de::Error::invalid_length(len, &format!("an array of {N} numbers").as_str())
    })
}

pub(crate) fn exact_opt<'de, D: serde::Deserializer<'de>, const N: usize>(
    d: D,
) -> Result<Option<[f64; N]>, D::Error> {
    exact(d).map(Some)
}

/// A key path in the TOML document, for locating semantic errors.
pub(crate) enum Key {
    Name(&'static str),
    Index(usize),
}

/// Byte offset of the value at `path`, if the document parses and has it.
pub(crate) fn span_of(text: &str, path: &[Key]) -> Option<usize> {
    if path.is_empty() {
        return None;
    }
    let doc = toml::de::DeTable::parse(text).ok()?;
    let root = toml::de::DeValue::Table(doc.into_inner());
    let mut cur = &root;
    let mut span = None;
    for k in path {
        let next = match k {
            Key::Name(n) => cur.get(*n)?,
            Key::Index(i) => cur.get(*i)?,
        };
        span = Some(next.span().start);
        cur = next.get_ref();
    }
    span
}

/// Where byte offset `at` is in the document, as `tube 2: length_mm` or `model.kind`:
/// the tables and arrays holding it and the key whose value holds it (not a key whose
/// name holds it: an unknown key is named by the message). `None` if the document does
/// not parse (then the error is a syntax error and the position says it all).
pub(crate) fn path_at(text: &str, at: usize) -> Option<String> {
    use toml::de::DeValue;
    let doc = toml::de::DeTable::parse(text).ok()?;
    let root = DeValue::Table(doc.into_inner());
    let mut out = String::new();
    let mut after_index = false;
    let mut cur = &root;
    loop {
        match cur {
            DeValue::Table(t) => {
                let Some((k, v)) = t
                    .iter()
                    .find(|(k, v)| extent(v).contains(&at) && !k.span().contains(&at))
                else {
                    break;
                };
                if after_index {
                    out.push_str(": ");
                } else if !out.is_empty() {
                    out.push('.');
                }
                out.push_str(k.get_ref());
                after_index = false;
                cur = v.get_ref();
            }
            DeValue::Array(a) => {
                let Some((i, v)) = a.iter().enumerate().find(|(_, v)| extent(v).contains(&at))
                else {
                    break;
                };
                out.push_str(&format!(" {}", i + 1));
                after_index = true;
                cur = v.get_ref();
            }
            _ => break,
        }
    }
    (!out.is_empty()).then_some(out)
}

/// The text a value covers: a table's own span covers only its header (and an array of
/// tables' only its first header), so entries and elements extend it.
fn extent(v: &toml::Spanned<toml::de::DeValue<'_>>) -> std::ops::Range<usize> {
    let span = v.span();
    match v.get_ref() {
        toml::de::DeValue::Table(t) => {
            let end = t
                .iter()
                .flat_map(|(k, v)| [k.span().end, extent(v).end])
                .fold(span.end, usize::max);
            let start = t
                .iter()
                .map(|(k, _)| k.span().start)
                .fold(span.start, usize::min);
            start..end
        }
        toml::de::DeValue::Array(a) => a
            .iter()
            .map(extent)
            .fold(span, |acc, r| acc.start.min(r.start)..acc.end.max(r.end)),
        _ => span,
    }
}

/// 1-based line and column (in characters) of byte offset `at`.
pub(crate) fn line_col(text: &str, at: usize) -> (usize, usize) {
    let at = at.min(text.len());
    let before = &text[..at];
    let line = before.matches('\n').count() + 1;
    let line_start = before.rfind('\n').map_or(0, |i| i + 1);
    (line, before[line_start..].chars().count() + 1)
}

/// `text` without a leading byte-order mark (U+FEFF, which Windows editors write before
/// "UTF-8" text): positions in errors are then the lines and columns an editor shows.
pub(crate) fn without_bom(text: &str) -> &str {
    text.strip_prefix('\u{feff}').unwrap_or(text)
}

/// Joins a multi-line message into one line.
pub(crate) fn one_line(s: &str) -> String {
    s.lines()
        .map(str::trim)
        .filter(|l| !l.is_empty())
        .collect::<Vec<_>>()
        .join("; ")
}
