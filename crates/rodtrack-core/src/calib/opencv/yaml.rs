//! Block YAML as OpenCV writes it: maps by indentation, sequences, tags, comments, and flow
//! values inside (read by [`super::flow`]).

use super::error::OpencvFileError;
use super::flow::Flow;
use super::node::{scalar, Node};

// ---- block YAML ----

/// One significant line: number (1-based), indentation, content without the comment.
struct Line {
    no: usize,
    indent: usize,
    text: String,
}

/// Removes a `#` comment (one at the start or after a blank, outside quotes).
fn strip_comment(s: &str) -> &str {
    let mut quote: Option<char> = None;
    let mut prev = ' ';
    for (i, c) in s.char_indices() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if c == '"' || c == '\'' => quote = Some(c),
            None if c == '#' && prev.is_whitespace() => return &s[..i],
            None => {}
        }
        prev = c;
    }
    s
}

pub(super) fn parse_yaml(text: &str) -> Result<Node, OpencvFileError> {
    let mut lines = Vec::new();
    for (i, raw) in text.lines().enumerate() {
        let no = i + 1;
        if raw.starts_with('\t') {
            return Err(OpencvFileError::Syntax {
                line: no,
                reason: "tabs may not indent YAML".into(),
            });
        }
        let content = strip_comment(raw).trim_end();
        let trimmed = content.trim_start();
        if trimmed.is_empty()
            || (trimmed.starts_with('%') && lines.is_empty())
            || trimmed == "---"
            || trimmed == "..."
        {
            continue;
        }
        // `--- !!opencv-storage` and similar document starts.
        if trimmed.starts_with("--- ") && lines.is_empty() {
            continue;
        }
        lines.push(Line {
            no,
            indent: content.len() - trimmed.len(),
            text: trimmed.to_string(),
        });
    }
    if lines.is_empty() {
        return Err(OpencvFileError::Syntax {
            line: 1,
            reason: "the file holds no fields".into(),
        });
    }
    let mut pos = 0;
    let indent = lines[0].indent;
    let node = block(&mut lines, &mut pos, indent)?;
    if let Some(l) = lines.get(pos) {
        return Err(OpencvFileError::Syntax {
            line: l.no,
            reason: "unexpected indentation".into(),
        });
    }
    Ok(node)
}

/// Splits `key: rest` (the `:` followed by a blank or the end, outside quotes).
fn split_key(s: &str) -> Option<(String, &str)> {
    let mut quote: Option<char> = None;
    let bytes: Vec<(usize, char)> = s.char_indices().collect();
    for (n, &(i, c)) in bytes.iter().enumerate() {
        match quote {
            Some(q) if c == q => quote = None,
            Some(_) => {}
            None if (c == '"' || c == '\'') && n == 0 => quote = Some(c),
            None if c == ':' => {
                let next = bytes.get(n + 1).map(|x| x.1);
                if next.is_none_or(char::is_whitespace) {
                    let k = s[..i].trim();
                    let k = k
                        .strip_prefix('"')
                        .and_then(|k| k.strip_suffix('"'))
                        .or_else(|| k.strip_prefix('\'').and_then(|k| k.strip_suffix('\'')))
                        .unwrap_or(k);
                    return Some((k.to_string(), s[i + 1..].trim()));
                }
            }
            None => {}
        }
    }
    None
}

fn block(lines: &mut [Line], pos: &mut usize, indent: usize) -> Result<Node, OpencvFileError> {
    let is_item = |t: &str| t == "-" || t.starts_with("- ");
    if lines.get(*pos).is_some_and(|l| is_item(&l.text)) {
        let mut items = Vec::new();
        while let Some(l) = lines.get(*pos) {
            if l.indent != indent || !is_item(&l.text) {
                break;
            }
            let rest = l.text[1..].trim_start().to_string();
            let no = l.no;
            if rest.is_empty() {
                *pos += 1;
                items.push(nested(lines, pos, indent, no)?);
            } else if split_key(&rest).is_some() && !rest.starts_with(['[', '{', '"', '\'']) {
                // `- key: value`: a map whose first entry is on this line.
                let inner = indent + (l.text.len() - rest.len());
                let line = &mut lines[*pos];
                line.indent = inner;
                line.text = rest;
                items.push(block(lines, pos, inner)?);
            } else {
                *pos += 1;
                items.push(inline_value(lines, pos, &rest, no, indent)?);
            }
        }
        return Ok(Node::Seq(items));
    }
    let mut entries = Vec::new();
    while let Some(l) = lines.get(*pos) {
        if l.indent < indent {
            break;
        }
        if l.indent > indent {
            return Err(OpencvFileError::Syntax {
                line: l.no,
                reason: "unexpected indentation".into(),
            });
        }
        if is_item(&l.text) {
            break;
        }
        let no = l.no;
        let Some((key, rest)) = split_key(&l.text) else {
            return Err(OpencvFileError::Syntax {
                line: no,
                reason: format!("expected `key: value`, found `{}`", l.text),
            });
        };
        let mut rest = rest.to_string();
        let mut tag = None;
        if rest.starts_with('!') {
            let end = rest.find(char::is_whitespace).unwrap_or(rest.len());
            tag = Some(normalise_tag(&rest[..end]));
            rest = rest[end..].trim_start().to_string();
        }
        *pos += 1;
        let mut value = if rest.is_empty() {
            nested(lines, pos, indent, no)?
        } else {
            inline_value(lines, pos, &rest, no, indent)?
        };
        if let (Node::Map(_, t), Some(tag)) = (&mut value, tag) {
            *t = Some(tag);
        }
        entries.push((key, value));
    }
    Ok(Node::Map(entries, None))
}

/// `!!opencv-matrix`, `!<tag:yaml.org,2002:opencv-matrix>` -> `opencv-matrix`.
fn normalise_tag(t: &str) -> String {
    let t = t.trim_start_matches('!');
    let t = t.trim_start_matches('<').trim_end_matches('>');
    t.rsplit(':').next().unwrap_or(t).to_string()
}

/// The value of a `key:` (or `-`) with nothing after it: the more indented block below, a
/// sequence at the same indentation (`key:\n- a`), or empty.
fn nested(
    lines: &mut [Line],
    pos: &mut usize,
    indent: usize,
    _no: usize,
) -> Result<Node, OpencvFileError> {
    match lines.get(*pos) {
        Some(n) if n.indent > indent => {
            let ind = n.indent;
            block(lines, pos, ind)
        }
        Some(n) if n.indent == indent && (n.text == "-" || n.text.starts_with("- ")) => {
            block(lines, pos, indent)
        }
        _ => Ok(Node::Text(String::new())),
    }
}

/// A value that starts on the key's line: a flow value (possibly over several lines), a quoted
/// string or a plain scalar.
fn inline_value(
    lines: &[Line],
    pos: &mut usize,
    rest: &str,
    no: usize,
    indent: usize,
) -> Result<Node, OpencvFileError> {
    if rest.starts_with(['[', '{']) {
        // Gather lines until the brackets balance.
        let mut text = rest.to_string();
        while !balanced(&text) {
            let Some(l) = lines.get(*pos) else {
                return Err(OpencvFileError::Syntax {
                    line: no,
                    reason: format!("unclosed `{}`", &rest[..1]),
                });
            };
            text.push('\n');
            text.push_str(&l.text);
            *pos += 1;
        }
        let mut p = Flow::new(&text, no);
        let v = p.value()?;
        p.skip_ws();
        if p.pos < p.chars.len() {
            return Err(p.err("text after a closing bracket"));
        }
        return Ok(v);
    }
    if rest.starts_with(['"', '\'']) {
        let mut p = Flow::new(rest, no);
        let s = p.quoted()?;
        p.skip_ws();
        if p.pos < p.chars.len() {
            return Err(p.err("text after a closing quote"));
        }
        return Ok(Node::Text(s));
    }
    // A plain scalar, folded over more indented lines.
    let mut text = rest.to_string();
    while let Some(l) = lines.get(*pos) {
        if l.indent <= indent {
            break;
        }
        text.push(' ');
        text.push_str(&l.text);
        *pos += 1;
    }
    Ok(scalar(&text))
}

/// True when every `[` and `{` outside quotes is closed.
fn balanced(s: &str) -> bool {
    let mut depth = 0i64;
    let mut quote: Option<char> = None;
    let mut escaped = false;
    for c in s.chars() {
        match quote {
            Some(q) => {
                if escaped {
                    escaped = false;
                } else if c == '\\' && q == '"' {
                    escaped = true;
                } else if c == q {
                    quote = None;
                }
            }
            None => match c {
                '"' | '\'' => quote = Some(c),
                '[' | '{' => depth += 1,
                ']' | '}' => depth -= 1,
                _ => {}
            },
        }
    }
    depth <= 0 && quote.is_none()
}
