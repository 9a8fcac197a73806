//! Flow values: JSON, and YAML's `[ ]` / `{ }`.

use super::error::OpencvFileError;
use super::node::{scalar, Node};

// ---- flow values (JSON, YAML `[ ]` and `{ }`) ----

/// A parser of flow values: JSON, and YAML's `[ ]` / `{ }` with plain (unquoted) scalars.
pub(super) struct Flow {
    pub(super) chars: Vec<char>,
    pub(super) pos: usize,
    /// Line number of `chars[0]`, and the offsets of the line starts after it.
    pub(super) first_line: usize,
    pub(super) line_starts: Vec<usize>,
}

impl Flow {
    pub(super) fn new(text: &str, first_line: usize) -> Flow {
        let chars: Vec<char> = text.chars().collect();
        let line_starts = chars
            .iter()
            .enumerate()
            .filter(|(_, c)| **c == '\n')
            .map(|(i, _)| i + 1)
            .collect();
        Flow {
            chars,
            pos: 0,
            first_line,
            line_starts,
        }
    }

    fn line(&self) -> usize {
        self.first_line + self.line_starts.iter().filter(|s| **s <= self.pos).count()
    }

    pub(super) fn err(&self, reason: &str) -> OpencvFileError {
        OpencvFileError::Syntax {
            line: self.line(),
            reason: reason.to_string(),
        }
    }

    fn peek(&self) -> Option<char> {
        self.chars.get(self.pos).copied()
    }

    pub(super) fn skip_ws(&mut self) {
        while let Some(c) = self.peek() {
            if c.is_whitespace() {
                self.pos += 1;
            } else if c == '#' {
                // YAML comment inside a flow value (to the end of the line).
                while self.peek().is_some_and(|c| c != '\n') {
                    self.pos += 1;
                }
            } else {
                break;
            }
        }
    }

    pub(super) fn value(&mut self) -> Result<Node, OpencvFileError> {
        self.skip_ws();
        match self.peek() {
            None => Err(self.err("unexpected end of the text: a value is missing")),
            Some('{') => self.map(),
            Some('[') => self.seq(),
            Some('"') | Some('\'') => Ok(Node::Text(self.quoted()?)),
            Some(_) => {
                let t = self.plain(&[',', ']', '}'])?;
                Ok(scalar(&t))
            }
        }
    }

    fn map(&mut self) -> Result<Node, OpencvFileError> {
        self.pos += 1; // {
        let mut entries = Vec::new();
        loop {
            self.skip_ws();
            match self.peek() {
                Some('}') => {
                    self.pos += 1;
                    break;
                }
                None => return Err(self.err("unclosed `{`")),
                _ => {}
            }
            let key = match self.peek() {
                Some('"') | Some('\'') => self.quoted()?,
                _ => self.plain(&[':', ',', '}'])?,
            };
            self.skip_ws();
            if self.peek() != Some(':') {
                return Err(self.err(&format!("expected `:` after the key `{key}`")));
            }
            self.pos += 1;
            let v = self.value()?;
            entries.push((key, v));
            self.skip_ws();
            match self.peek() {
                Some(',') => self.pos += 1,
                Some('}') => {}
                _ => return Err(self.err("expected `,` or `}` in a map")),
            }
        }
        let tag = match entries.iter().find(|(k, _)| k == "type_id") {
            Some((_, Node::Text(t))) => Some(t.clone()),
            _ => None,
        };
        Ok(Node::Map(entries, tag))
    }

    fn seq(&mut self) -> Result<Node, OpencvFileError> {
        self.pos += 1; // [
        let mut items = Vec::new();
        loop {
            self.skip_ws();
            match self.peek() {
                Some(']') => {
                    self.pos += 1;
                    break;
                }
                None => return Err(self.err("unclosed `[`")),
                _ => {}
            }
            items.push(self.value()?);
            self.skip_ws();
            match self.peek() {
                Some(',') => self.pos += 1,
                Some(']') => {}
                _ => return Err(self.err("expected `,` or `]` in a list")),
            }
        }
        Ok(Node::Seq(items))
    }

    pub(super) fn quoted(&mut self) -> Result<String, OpencvFileError> {
        let q = self.peek().unwrap_or('"');
        self.pos += 1;
        let mut s = String::new();
        loop {
            let Some(c) = self.peek() else {
                return Err(self.err("unclosed string"));
            };
            self.pos += 1;
            if c == q {
                if q == '\'' && self.peek() == Some('\'') {
                    s.push('\'');
                    self.pos += 1;
                    continue;
                }
                return Ok(s);
            }
            if c == '\\' && q == '"' {
                let Some(e) = self.peek() else {
                    return Err(self.err("unclosed string"));
                };
                self.pos += 1;
                match e {
                    'n' => s.push('\n'),
                    't' => s.push('\t'),
                    'r' => s.push('\r'),
                    'u' => {
                        let hex: String = self.chars.iter().skip(self.pos).take(4).collect();
                        let code = u32::from_str_radix(&hex, 16)
                            .ok()
                            .and_then(char::from_u32)
                            .ok_or_else(|| self.err("bad `\\u` escape"))?;
                        s.push(code);
                        self.pos += 4;
                    }
                    other => s.push(other),
                }
            } else {
                s.push(c);
            }
        }
    }

    /// A plain scalar up to one of `stops` (or a line end), trimmed.
    fn plain(&mut self, stops: &[char]) -> Result<String, OpencvFileError> {
        let start = self.pos;
        while let Some(c) = self.peek() {
            if stops.contains(&c) || c == '\n' {
                break;
            }
            self.pos += 1;
        }
        let t: String = self.chars[start..self.pos].iter().collect();
        let t = t.trim().to_string();
        if t.is_empty() {
            return Err(self.err("a value is missing"));
        }
        Ok(t)
    }
}
