//! A small XML tree (quick-xml) with 1-based line numbers, plus Mitsuba's `$name`
//! parameter substitution.

use super::error::SceneFileError;
use quick_xml::events::{BytesStart, Event};
use quick_xml::reader::Reader;
use std::collections::HashMap;
use std::path::Path;

/// One XML element.
#[derive(Clone, Debug)]
pub(crate) struct Node {
    /// Tag name.
    pub tag: String,
    /// Attributes in document order (values unescaped, later `$`-substituted).
    pub attrs: Vec<(String, String)>,
    /// Child elements.
    pub children: Vec<Node>,
    /// 1-based line of the start tag.
    pub line: usize,
}

impl Node {
    /// The value of attribute `key`.
    pub fn attr(&self, key: &str) -> Option<&str> {
        self.attrs.iter().find(|(k, _)| k == key).map(|(_, v)| v.as_str())
    }

    /// `<tag type="T" ...>` as written in messages.
    pub fn describe(&self) -> String {
        match (self.attr("type"), self.attr("name")) {
            (Some(t), _) => format!("<{} type=\"{t}\">", self.tag),
            (None, Some(n)) => format!("<{} name=\"{n}\">", self.tag),
            _ => format!("<{}>", self.tag),
        }
    }
}

/// Byte offset to 1-based line.
struct Lines(Vec<usize>);

impl Lines {
    fn new(text: &str) -> Self {
        Lines(text.bytes().enumerate().filter(|&(_, b)| b == b'\n').map(|(i, _)| i).collect())
    }
    fn line(&self, offset: u64) -> usize {
        let offset = usize::try_from(offset).unwrap_or(usize::MAX);
        self.0.partition_point(|&nl| nl < offset) + 1
    }
}

/// Parses `text` into its root element.
pub(crate) fn parse(text: &str, path: &Path) -> Result<Node, SceneFileError> {
    let lines = Lines::new(text);
    let xml_err = |line: usize, message: String| SceneFileError::Xml { path: path.to_path_buf(), line, message };
    let mut reader = Reader::from_str(text);
    reader.config_mut().trim_text(false);
    let mut stack: Vec<Node> = Vec::new();
    let mut root: Option<Node> = None;
    loop {
        let start = reader.buffer_position();
        let event = match reader.read_event() {
            Ok(e) => e,
            Err(e) => return Err(xml_err(lines.line(reader.error_position()), e.to_string())),
        };
        let line = lines.line(start);
        match event {
            Event::Start(e) | Event::Empty(e) if root.is_some() && stack.is_empty() => {
                return Err(xml_err(line, format!("second root element <{}> after the root element", String::from_utf8_lossy(e.name().as_ref()))));
            }
            Event::Start(e) => stack.push(node(&e, line, &|m| xml_err(line, m))?),
            Event::Empty(e) => {
                let n = node(&e, line, &|m| xml_err(line, m))?;
                match stack.last_mut() {
                    Some(parent) => parent.children.push(n),
                    None => root = Some(n),
                }
            }
            Event::End(_) => {
                // quick-xml checks that end names match their start tags.
                let Some(n) = stack.pop() else { return Err(xml_err(line, "closing tag without an opening tag".into())) };
                match stack.last_mut() {
                    Some(parent) => parent.children.push(n),
                    None => root = Some(n),
                }
            }
            Event::Text(t) => {
                if !t.iter().all(|b| b.is_ascii_whitespace()) {
                    let s = String::from_utf8_lossy(&t).trim().chars().take(40).collect::<String>();
                    return Err(xml_err(line, format!("unexpected text '{s}' (Mitsuba scenes carry no text content)")));
                }
            }
            Event::CData(_) | Event::GeneralRef(_) => return Err(xml_err(line, "unexpected text content (Mitsuba scenes carry no text content)".into())),
            Event::Comment(_) | Event::Decl(_) | Event::PI(_) | Event::DocType(_) => {}
            Event::Eof => break,
        }
    }
    if let Some(open) = stack.last() {
        return Err(xml_err(lines.line(text.len() as u64), format!("file ends inside <{}> opened at line {}", open.tag, open.line)));
    }
    root.ok_or_else(|| xml_err(1, "no root element".into()))
}

fn node(e: &BytesStart<'_>, line: usize, err: &dyn Fn(String) -> SceneFileError) -> Result<Node, SceneFileError> {
    let tag = String::from_utf8_lossy(e.name().as_ref()).into_owned();
    let mut attrs = Vec::new();
    for a in e.attributes() {
        let a = a.map_err(|x| err(format!("bad attribute in <{tag}>: {x}")))?;
        let key = String::from_utf8_lossy(a.key.as_ref()).into_owned();
        let value = a.unescape_value().map_err(|x| err(format!("bad value of attribute '{key}' in <{tag}>: {x}")))?.into_owned();
        attrs.push((key, value));
    }
    Ok(Node { tag, attrs, children: Vec::new(), line })
}

/// Replaces every `$name` in attribute values (longest identifier after `$`) by its value;
/// an unknown name is an error naming the line.
pub(crate) fn substitute(node: &mut Node, params: &HashMap<String, String>, path: &Path) -> Result<(), SceneFileError> {
    for (_, v) in node.attrs.iter_mut() {
        if v.contains('$') {
            *v = substitute_str(v, params).map_err(|name| SceneFileError::UndefinedVariable { path: path.to_path_buf(), line: node.line, name })?;
        }
    }
    for c in node.children.iter_mut() {
        substitute(c, params, path)?;
    }
    Ok(())
}

fn substitute_str(s: &str, params: &HashMap<String, String>) -> Result<String, String> {
    let mut out = String::with_capacity(s.len());
    let mut rest = s;
    while let Some(i) = rest.find('$') {
        out.push_str(&rest[..i]);
        let after = &rest[i + 1..];
        let len = after.find(|c: char| !(c.is_ascii_alphanumeric() || c == '_')).unwrap_or(after.len());
        let name = &after[..len];
        match params.get(name) {
            Some(v) if !name.is_empty() => out.push_str(v),
            _ => return Err(name.to_string()),
        }
        rest = &after[len..];
    }
    out.push_str(rest);
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lines_and_substitution() {
        let p = Path::new("t.xml");
        let root = parse("<?xml version=\"1.0\"?>\n<scene>\n  <a x=\"$v\"/>\n\n  <b>\n  </b>\n</scene>\n", p).unwrap();
        assert_eq!(root.line, 2);
        assert_eq!((root.children[0].line, root.children[1].line), (3, 5));
        let mut params = HashMap::new();
        params.insert("v".to_string(), "7".to_string());
        params.insert("res_x".to_string(), "5".to_string());
        let mut r = root.clone();
        substitute(&mut r, &params, p).unwrap();
        assert_eq!(r.children[0].attr("x"), Some("7"));
        assert_eq!(substitute_str("$res_x,$v", &params).unwrap(), "5,7");
        assert_eq!(substitute_str("$res", &params).unwrap_err(), "res");
        assert_eq!(substitute_str("a$", &params).unwrap_err(), "");
    }

    #[test]
    fn malformed_xml_names_the_line() {
        let e = parse("<scene>\n<a>\n</b>\n</scene>", Path::new("t.xml")).unwrap_err();
        assert!(matches!(e, SceneFileError::Xml { line: 3, .. }), "{e}");
        let e = parse("<scene>\n<a>\n", Path::new("t.xml")).unwrap_err();
        assert!(e.to_string().contains("opened at line 2"), "{e}");
    }
}
