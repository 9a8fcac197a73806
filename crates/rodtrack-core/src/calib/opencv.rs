//! OpenCV camera models as `cv::FileStorage` writes them (after `calibrateCamera`), in YAML or
//! JSON, read without a YAML library.
//!
//! What is read:
//! - YAML as OpenCV writes it (`%YAML:1.0` or `%YAML 1.2`, `---`, block maps by indentation,
//!   `!!opencv-matrix` maps with `rows`, `cols`, `dt`, `data: [ ... ]` over several lines,
//!   block sequences, flow `[ ]` / `{ }`, quoted strings, `#` comments). ROS `camera_info` files
//!   (plain `rows`/`cols`/`data` maps) read the same way.
//! - JSON as OpenCV writes it (`{"type_id": "opencv-matrix", "rows": 3, "cols": 3, "dt": "d",
//!   "data": [...]}`; numbers such as `0.` are accepted).
//! - The camera matrix under `camera_matrix`, `cameraMatrix`, `K` (any case, `_` ignored; also
//!   `intrinsic_matrix`, `mtx`), as a 3x3 opencv-matrix, a flat list of 9 or a list of 3 rows;
//!   the distortion coefficients under `distortion_coefficients`, `dist_coeffs`, `distCoeffs`,
//!   `D` (also `dist`), as a 1xN or Nx1 opencv-matrix or a list: 4, 5, 8, 12 or 14 of them.
//!   rodtrack's model has `k1, k2, p1, p2, k3`: higher coefficients must be zero, else the file
//!   is refused with the names of those that are not.
//!
//! Everything else in the file (image size, reprojection error, per-view extrinsics, ...) is
//! parsed and ignored. XML FileStorage files are refused with a clear message.

use super::inputs::{ImageSize, OpencvModel};
use thiserror::Error;

/// Why an OpenCV file (or an inline model) could not be read. The caller adds the file name.
#[derive(Debug, Clone, PartialEq, Error)]
pub enum OpencvFileError {
    /// The text is not the YAML/JSON that OpenCV writes.
    #[error("line {line}: {reason}")]
    Syntax {
        /// 1-based line number.
        line: usize,
        /// What is wrong.
        reason: String,
    },
    /// A field is there but unusable.
    #[error("field `{field}`: {reason}")]
    Field {
        /// The field (key path, e.g. `camera_matrix.data`).
        field: String,
        /// What is wrong.
        reason: String,
    },
    /// A required field is missing.
    #[error("no {what} (looked for {looked_for}); fields found: {found}")]
    Missing {
        /// What is missing.
        what: &'static str,
        /// The key names accepted.
        looked_for: String,
        /// The keys the file has.
        found: String,
    },
}

/// A parsed FileStorage value.
#[derive(Debug, Clone, PartialEq)]
pub enum Node {
    /// A map in file order, with its tag (`opencv-matrix` from `!!opencv-matrix` or from a JSON
    /// `type_id`), if any.
    Map(Vec<(String, Node)>, Option<String>),
    /// A sequence.
    Seq(Vec<Node>),
    /// A number.
    Num(f64),
    /// Any other scalar (string, `true`, `null`, ...).
    Text(String),
}

impl Node {
    fn get(&self, key: &str) -> Option<&Node> {
        match self {
            Node::Map(entries, _) => entries.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    fn as_f64(&self) -> Option<f64> {
        match self {
            Node::Num(v) => Some(*v),
            Node::Text(t) => parse_number(t),
            _ => None,
        }
    }

    fn kind(&self) -> &'static str {
        match self {
            Node::Map(..) => "a map",
            Node::Seq(_) => "a list",
            Node::Num(_) => "a number",
            Node::Text(_) => "text",
        }
    }
}

/// Key names (lower case, without `_` and `-`) of the camera matrix.
const CAMERA_KEYS: [&str; 5] = ["cameramatrix", "k", "intrinsicmatrix", "intrinsics", "mtx"];
/// Key names (lower case, without `_` and `-`) of the distortion coefficients.
const DIST_KEYS: [&str; 6] = [
    "distortioncoefficients",
    "distcoeffs",
    "distcoeff",
    "d",
    "dist",
    "distortioncoeffs",
];
/// The names printed in messages.
const CAMERA_NAMES: &str = "camera_matrix, cameraMatrix or K";
const DIST_NAMES: &str = "distortion_coefficients, dist_coeffs, distCoeffs or D";
/// Names of OpenCV's distortion coefficients from the sixth on.
const HIGHER_NAMES: [&str; 9] = ["k4", "k5", "k6", "s1", "s2", "s3", "s4", "tauX", "tauY"];

/// True when `key` names a camera matrix or distortion coefficients in any of the spellings
/// an OpenCV model is read from (other keys of an inline model are refused by the strict
/// reader; a loader that accepts other tools' files drops them with a warning first).
pub fn is_model_key(key: &str) -> bool {
    let n = normalise_key(key);
    CAMERA_KEYS.contains(&n.as_str()) || DIST_KEYS.contains(&n.as_str())
}

fn normalise_key(k: &str) -> String {
    k.chars()
        .filter(|c| *c != '_' && *c != '-')
        .flat_map(char::to_lowercase)
        .collect()
}

/// Reads an OpenCV camera model from the text of a FileStorage file (YAML or JSON).
pub fn parse_opencv_model(text: &str) -> Result<OpencvModel, OpencvFileError> {
    let root = parse_file_storage(text)?;
    model_from_node(&root, false)
}

impl OpencvModel {
    /// The model as the YAML file OpenCV's `cv::FileStorage` writes after `calibrateCamera`
    /// (`image_width`, `image_height`, `camera_matrix`, `distortion_coefficients`). Numbers
    /// carry the shortest digits that read back as the same double.
    pub fn to_file_storage_yaml(&self, image_size: ImageSize) -> String {
        let opencv_matrix = |rows: usize, cols: usize, data: &[f64]| {
            let data: Vec<String> = data.iter().map(|v| format!("{v:e}")).collect();
            format!(
                "!!opencv-matrix\n   rows: {rows}\n   cols: {cols}\n   dt: d\n   data: [ {} ]\n",
                data.join(", ")
            )
        };
        format!(
            "%YAML:1.0\n---\nimage_width: {}\nimage_height: {}\ncamera_matrix: {}\
             distortion_coefficients: {}",
            image_size.width,
            image_size.height,
            opencv_matrix(3, 3, self.camera_matrix.as_flattened()),
            opencv_matrix(1, self.dist_coeffs.len(), &self.dist_coeffs),
        )
    }
}

/// Parses the text of a FileStorage file (YAML or JSON) into its tree.
pub fn parse_file_storage(text: &str) -> Result<Node, OpencvFileError> {
    let text = text.strip_prefix('\u{feff}').unwrap_or(text);
    let start = text.trim_start();
    if start.starts_with("<?xml") || start.starts_with("<opencv_storage") {
        return Err(OpencvFileError::Syntax {
            line: 1,
            reason: "XML FileStorage files are not supported: write the calibration as .yml or \
                     .json"
                .into(),
        });
    }
    if start.starts_with('{') {
        let mut p = Flow::new(text, 1);
        p.skip_ws();
        let node = p.value()?;
        p.skip_ws();
        if p.pos < p.chars.len() {
            return Err(p.err("text after the end of the JSON document"));
        }
        return Ok(node);
    }
    parse_yaml(text)
}

/// Builds the model from a parsed tree: the top-level map, or (when not there) a map one level
/// down. `strict`: every key must be the camera matrix or the distortion coefficients (an
/// inline model in the calibration inputs, where a typo must not pass silently).
pub fn model_from_node(root: &Node, strict: bool) -> Result<OpencvModel, OpencvFileError> {
    let Node::Map(entries, _) = root else {
        return Err(OpencvFileError::Field {
            field: "(top level)".into(),
            reason: format!("must be a map of named fields, is {}", root.kind()),
        });
    };
    let mut scopes: Vec<(String, &Vec<(String, Node)>)> = vec![(String::new(), entries)];
    let found_keys = entries
        .iter()
        .map(|(k, _)| k.as_str())
        .collect::<Vec<_>>()
        .join(", ");
    if !strict {
        for (k, v) in entries {
            if let Node::Map(inner, None) = v {
                scopes.push((format!("{k}."), inner));
            }
        }
    }
    let mut camera = None;
    let mut dist = None;
    for (prefix, scope) in &scopes {
        let cam = find_role(scope, &CAMERA_KEYS, prefix)?;
        let d = find_role(scope, &DIST_KEYS, prefix)?;
        if cam.is_some() || d.is_some() {
            camera = cam;
            dist = d;
            if strict {
                for (k, _) in scope.iter() {
                    let n = normalise_key(k);
                    if !CAMERA_KEYS.contains(&n.as_str()) && !DIST_KEYS.contains(&n.as_str()) {
                        return Err(OpencvFileError::Field {
                            field: k.clone(),
                            reason: format!(
                                "unknown field: an OpenCV model holds {CAMERA_NAMES} and \
                                 {DIST_NAMES}"
                            ),
                        });
                    }
                }
            }
            break;
        }
    }
    let (cam_key, cam_node) = camera.ok_or_else(|| OpencvFileError::Missing {
        what: "camera matrix",
        looked_for: CAMERA_NAMES.into(),
        found: or_none(&found_keys),
    })?;
    let (dist_key, dist_node) = dist.ok_or_else(|| OpencvFileError::Missing {
        what: "distortion coefficients",
        looked_for: DIST_NAMES.into(),
        found: or_none(&found_keys),
    })?;
    let (mut rows, mut cols, data) = matrix(cam_node, &cam_key)?;
    if matches!(cam_node, Node::Seq(_)) && rows == 1 && cols == 9 {
        // A flat list of 9, row by row.
        (rows, cols) = (3, 3);
    }
    if rows != 3 || cols != 3 {
        return Err(OpencvFileError::Field {
            field: cam_key,
            reason: format!("must be 3x3, is {rows}x{cols}"),
        });
    }
    let camera_matrix = [
        [data[0], data[1], data[2]],
        [data[3], data[4], data[5]],
        [data[6], data[7], data[8]],
    ];
    let (rows, cols, dist_coeffs) = matrix(dist_node, &dist_key)?;
    if rows != 1 && cols != 1 {
        return Err(OpencvFileError::Field {
            field: dist_key,
            reason: format!("must be one row or one column, is {rows}x{cols}"),
        });
    }
    if !matches!(dist_coeffs.len(), 4 | 5 | 8 | 12 | 14) {
        return Err(OpencvFileError::Field {
            field: dist_key,
            reason: format!(
                "must hold 4, 5, 8, 12 or 14 coefficients, holds {}",
                dist_coeffs.len()
            ),
        });
    }
    let higher: Vec<String> = dist_coeffs
        .iter()
        .enumerate()
        .skip(5)
        .filter(|(_, v)| **v != 0.0)
        .map(|(i, v)| format!("{} = {v}", HIGHER_NAMES[i - 5]))
        .collect();
    if !higher.is_empty() {
        return Err(OpencvFileError::Field {
            field: dist_key,
            reason: format!(
                "{} not zero: rodtrack's camera model has k1, k2, p1, p2, k3 only (no rational \
                 k4-k6, thin-prism s1-s4 or tilt tauX, tauY terms); calibrate with OpenCV's \
                 default flags",
                higher.join(", ")
            ),
        });
    }
    Ok(OpencvModel {
        camera_matrix,
        dist_coeffs,
    })
}

fn or_none(s: &str) -> String {
    if s.is_empty() {
        "none".into()
    } else {
        s.into()
    }
}

type Role<'a> = Option<(String, &'a Node)>;

fn find_role<'a>(
    scope: &'a [(String, Node)],
    keys: &[&str],
    prefix: &str,
) -> Result<Role<'a>, OpencvFileError> {
    let mut hits = scope
        .iter()
        .filter(|(k, _)| keys.contains(&normalise_key(k).as_str()));
    let first = hits.next();
    if let (Some((a, _)), Some((b, _))) = (first, hits.next()) {
        return Err(OpencvFileError::Field {
            field: format!("{prefix}{b}"),
            reason: format!("the file has both `{prefix}{a}` and `{prefix}{b}`: keep one"),
        });
    }
    Ok(first.map(|(k, v)| (format!("{prefix}{k}"), v)))
}

/// A matrix as `(rows, cols, data row-major)`: an opencv-matrix map (or a plain map with `rows`,
/// `cols`, `data`), a flat list (one row) or a list of rows.
fn matrix(node: &Node, field: &str) -> Result<(usize, usize, Vec<f64>), OpencvFileError> {
    let bad = |sub: &str, reason: String| OpencvFileError::Field {
        field: if sub.is_empty() {
            field.to_string()
        } else {
            format!("{field}.{sub}")
        },
        reason,
    };
    let numbers = |sub: &str, items: &[Node]| -> Result<Vec<f64>, OpencvFileError> {
        items
            .iter()
            .enumerate()
            .map(|(i, n)| {
                n.as_f64()
                    .ok_or_else(|| bad(sub, format!("entry {i} is not a number ({n:?})")))
            })
            .collect()
    };
    match node {
        Node::Map(_, tag) => {
            let type_id = match node.get("type_id") {
                Some(Node::Text(t)) => Some(t.as_str()),
                Some(other) => return Err(bad("type_id", format!("is {}", other.kind()))),
                None => tag.as_deref(),
            };
            if let Some(t) = type_id {
                if t != "opencv-matrix" {
                    return Err(bad(
                        "",
                        format!("is an `{t}`; only `opencv-matrix` (a 2-D cv::Mat) is supported"),
                    ));
                }
            }
            let dim = |key: &str| -> Result<usize, OpencvFileError> {
                let n = node
                    .get(key)
                    .ok_or_else(|| bad(key, "missing".into()))?
                    .as_f64()
                    .ok_or_else(|| bad(key, "must be a number".into()))?;
                if n >= 1.0 && n.fract() == 0.0 && n <= 1e6 {
                    Ok(n as usize)
                } else {
                    Err(bad(key, format!("must be a positive whole number, is {n}")))
                }
            };
            let rows = dim("rows")?;
            let cols = dim("cols")?;
            let mut single = false;
            if let Some(dt) = node.get("dt") {
                let Node::Text(dt) = dt else {
                    return Err(bad(
                        "dt",
                        format!("must be a type letter, is {}", dt.kind()),
                    ));
                };
                let letters = dt.trim_start_matches(|c: char| c.is_ascii_digit());
                let count = &dt[..dt.len() - letters.len()];
                if !matches!(letters, "u" | "c" | "w" | "s" | "i" | "f" | "d" | "h")
                    || !(count.is_empty() || count == "1")
                {
                    return Err(bad(
                        "dt",
                        format!("`{dt}` is not a one-channel number type (u, c, w, s, i, f, d)"),
                    ));
                }
                single = letters == "f";
            }
            let data = match node.get("data") {
                // A `dt: f` matrix holds floats, written with the digits that identify them.
                Some(Node::Seq(items)) if single => numbers("data", items)?
                    .into_iter()
                    .map(|v| v as f32 as f64)
                    .collect(),
                Some(Node::Seq(items)) => numbers("data", items)?,
                Some(other) => {
                    return Err(bad("data", format!("must be a list, is {}", other.kind())))
                }
                None => return Err(bad("data", "missing".into())),
            };
            if data.len() != rows * cols {
                return Err(bad(
                    "data",
                    format!(
                        "holds {} numbers but rows x cols = {rows} x {cols} = {}",
                        data.len(),
                        rows * cols
                    ),
                ));
            }
            Ok((rows, cols, data))
        }
        Node::Seq(items)
            if items.iter().all(|n| matches!(n, Node::Seq(_))) && !items.is_empty() =>
        {
            let mut data = Vec::new();
            let mut cols = None;
            for (r, row) in items.iter().enumerate() {
                let Node::Seq(row) = row else { continue };
                let v = numbers(&format!("[{r}]"), row)?;
                if *cols.get_or_insert(v.len()) != v.len() {
                    return Err(bad(
                        "",
                        format!(
                            "row {r} has {} entries, row 0 has {}",
                            v.len(),
                            cols.unwrap_or(0)
                        ),
                    ));
                }
                data.extend(v);
            }
            Ok((items.len(), cols.unwrap_or(0), data))
        }
        Node::Seq(items) => {
            let data = numbers("", items)?;
            Ok((1, data.len(), data))
        }
        other => Err(bad(
            "",
            format!(
                "must be an opencv-matrix or a list of numbers, is {}",
                other.kind()
            ),
        )),
    }
}

/// A number as OpenCV writes it: `1.5`, `0.`, `-2.5e-01`, `.Inf`, `-.Inf`, `.Nan`.
fn parse_number(t: &str) -> Option<f64> {
    let t = t.trim();
    match t.to_ascii_lowercase().as_str() {
        ".inf" | "+.inf" => return Some(f64::INFINITY),
        "-.inf" => return Some(f64::NEG_INFINITY),
        ".nan" => return Some(f64::NAN),
        _ => {}
    }
    if !t.starts_with(|c: char| c.is_ascii_digit() || matches!(c, '-' | '+' | '.')) {
        return None;
    }
    t.parse::<f64>().ok()
}

fn scalar(text: &str) -> Node {
    match parse_number(text) {
        Some(v) => Node::Num(v),
        None => Node::Text(text.to_string()),
    }
}

// ---- flow values (JSON, YAML `[ ]` and `{ }`) ----

/// A parser of flow values: JSON, and YAML's `[ ]` / `{ }` with plain (unquoted) scalars.
struct Flow {
    chars: Vec<char>,
    pos: usize,
    /// Line number of `chars[0]`, and the offsets of the line starts after it.
    first_line: usize,
    line_starts: Vec<usize>,
}

impl Flow {
    fn new(text: &str, first_line: usize) -> Flow {
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

    fn err(&self, reason: &str) -> OpencvFileError {
        OpencvFileError::Syntax {
            line: self.line(),
            reason: reason.to_string(),
        }
    }

    fn peek(&self) -> Option<char> {
        self.chars.get(self.pos).copied()
    }

    fn skip_ws(&mut self) {
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

    fn value(&mut self) -> Result<Node, OpencvFileError> {
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

    fn quoted(&mut self) -> Result<String, OpencvFileError> {
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

fn parse_yaml(text: &str) -> Result<Node, OpencvFileError> {
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

// ---- serde: an inline model in the calibration inputs ----

impl<'de> serde::Deserialize<'de> for Node {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        struct V;
        impl<'de> serde::de::Visitor<'de> for V {
            type Value = Node;
            fn expecting(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
                f.write_str("a number, string, list or map")
            }
            fn visit_bool<E>(self, v: bool) -> Result<Node, E> {
                Ok(Node::Text(v.to_string()))
            }
            fn visit_i64<E>(self, v: i64) -> Result<Node, E> {
                Ok(Node::Num(v as f64))
            }
            fn visit_u64<E>(self, v: u64) -> Result<Node, E> {
                Ok(Node::Num(v as f64))
            }
            fn visit_f64<E>(self, v: f64) -> Result<Node, E> {
                Ok(Node::Num(v))
            }
            fn visit_str<E>(self, v: &str) -> Result<Node, E> {
                Ok(Node::Text(v.to_string()))
            }
            fn visit_unit<E>(self) -> Result<Node, E> {
                Ok(Node::Text("null".into()))
            }
            fn visit_none<E>(self) -> Result<Node, E> {
                Ok(Node::Text("null".into()))
            }
            fn visit_some<D2: serde::Deserializer<'de>>(self, d: D2) -> Result<Node, D2::Error> {
                <Node as serde::Deserialize>::deserialize(d)
            }
            fn visit_seq<A: serde::de::SeqAccess<'de>>(self, mut a: A) -> Result<Node, A::Error> {
                let mut items = Vec::new();
                while let Some(n) = a.next_element()? {
                    items.push(n);
                }
                Ok(Node::Seq(items))
            }
            fn visit_map<A: serde::de::MapAccess<'de>>(self, mut a: A) -> Result<Node, A::Error> {
                let mut entries: Vec<(String, Node)> = Vec::new();
                while let Some((k, v)) = a.next_entry::<String, Node>()? {
                    entries.push((k, v));
                }
                let tag = match entries.iter().find(|(k, _)| k == "type_id") {
                    Some((_, Node::Text(t))) => Some(t.clone()),
                    _ => None,
                };
                Ok(Node::Map(entries, tag))
            }
        }
        d.deserialize_any(V)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    const YAML: &str = "%YAML:1.0\n---\nimage_width: 1440\ncamera_matrix: !!opencv-matrix\n   \
        rows: 3\n   cols: 3\n   dt: d\n   data: [ 1.0780000000000000e+03, 0., 7.1950000000000000e+02, 0.,\n       \
        1078., 539.5, 0., 0., 1. ]\ndistortion_coefficients: !!opencv-matrix\n   rows: 1\n   \
        cols: 5\n   dt: d\n   data: [ -2.5e-01, 8.0000000000000002e-02, 0., 0., 0. ]\n\
        calibration_time: \"Mon 1 Jan # not a comment\"  # a comment\nflags: 0\n";

    #[test]
    fn reads_opencv_yaml() {
        let m = parse_opencv_model(YAML).unwrap();
        assert_eq!(
            m.camera_matrix,
            [[1078.0, 0.0, 719.5], [0.0, 1078.0, 539.5], [0.0, 0.0, 1.0]]
        );
        assert_eq!(m.dist_coeffs, vec![-0.25, 0.08, 0.0, 0.0, 0.0]);
        let root = parse_file_storage(YAML).unwrap();
        assert_eq!(
            root.get("calibration_time"),
            Some(&Node::Text("Mon 1 Jan # not a comment".into()))
        );
    }

    #[test]
    fn written_yaml_reads_back_bit_for_bit() {
        let m = OpencvModel {
            camera_matrix: [
                [1150.123456789012, 0.0, 719.5],
                [0.0, 1149.987654321098, 540.25],
                [0.0, 0.0, 1.0],
            ],
            dist_coeffs: vec![-0.2512345678901234, 0.08, 1e-4, -2.5e-5, 0.0],
        };
        let size = ImageSize {
            width: 1440,
            height: 1080,
        };
        let text = m.to_file_storage_yaml(size);
        assert!(
            text.starts_with("%YAML:1.0\n---\nimage_width: 1440\n"),
            "{text}"
        );
        assert_eq!(parse_opencv_model(&text).unwrap(), m);
        let root = parse_file_storage(&text).unwrap();
        assert_eq!(
            root.get("image_height").and_then(Node::as_f64),
            Some(1080.0)
        );
    }

    #[test]
    fn reads_lists_and_other_names() {
        let t = "K: [[2, 0, 3], [0, 2, 4], [0, 0, 1]]\nD:\n  - 0.1\n  - 0.2\n  - 0\n  - 0\n";
        let m = parse_opencv_model(t).unwrap();
        assert_eq!(m.camera_matrix[1], [0.0, 2.0, 4.0]);
        assert_eq!(m.dist_coeffs, vec![0.1, 0.2, 0.0, 0.0]);
        let j =
            r#"{"cameraMatrix": [2, 0, 3, 0, 2, 4, 0, 0, 1], "distCoeffs": [0.1, 0.2, 0., 0.]}"#;
        let m = parse_opencv_model(j).unwrap();
        assert_eq!(m.camera_matrix[0], [2.0, 0.0, 3.0]);
    }

    #[test]
    fn errors_name_the_field_and_line() {
        let t = YAML.replace("cols: 5", "cols: 6");
        let e = parse_opencv_model(&t).unwrap_err().to_string();
        assert!(e.contains("distortion_coefficients.data"), "{e}");
        let t = YAML.replace("data: [ -2.5e-01", "data: [ oops");
        let e = parse_opencv_model(&t).unwrap_err().to_string();
        assert!(
            e.contains("distortion_coefficients.data") && e.contains("entry 0"),
            "{e}"
        );
        let t = YAML.replace("1078., 539.5", "1078., 539.5 ");
        assert!(parse_opencv_model(&t).is_ok());
        let t = YAML.replace("0., 0., 1. ]", "0., 0., 1. ");
        let e = parse_opencv_model(&t).unwrap_err().to_string();
        assert!(e.contains("line") && e.contains("unclosed"), "{e}");
        let e = parse_opencv_model("a: 1\nb: 2\n").unwrap_err().to_string();
        assert!(e.contains("camera_matrix") && e.contains("a, b"), "{e}");
        let e =
            parse_opencv_model("K: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nD: [0, 0, 0, 0, 0, 0.5, 0, 0]\n")
                .unwrap_err()
                .to_string();
        assert!(e.contains("k4 = 0.5") && e.contains("`D`"), "{e}");
        let e = parse_opencv_model("K: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nD: [0, 0, 0]\n")
            .unwrap_err()
            .to_string();
        assert!(e.contains("4, 5, 8, 12 or 14"), "{e}");
        let e = parse_opencv_model("<?xml version=\"1.0\"?>\n<opencv_storage>").unwrap_err();
        assert!(e.to_string().contains("XML"));
        let e = parse_opencv_model(
            "K: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nk: [1, 0, 0, 0, 1, 0, 0, 0, 1]\nD: [0,0,0,0]",
        )
        .unwrap_err()
        .to_string();
        assert!(e.contains("both"), "{e}");
    }

    #[test]
    fn never_panics_on_garbage() {
        for t in [
            "",
            "{",
            "[",
            "}",
            "a:",
            ":",
            "- - -",
            "a: [",
            "a: {b: [1, 2}",
            "\"",
            "a: \"x",
            "  a: 1\nb: 2",
            "a:\n  - b: 1\n    c: [\n",
            "{\"a\": 1,}",
            "{\"a\" 1}",
            "\u{feff}",
            "a: !!opencv-matrix\n  rows: -1\n  cols: 3\n  data: []",
        ] {
            let _ = parse_opencv_model(t);
        }
    }
}
