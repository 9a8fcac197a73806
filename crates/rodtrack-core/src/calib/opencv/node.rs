//! The parsed tree of a FileStorage file, its scalars, and its serde form (an inline model in
//! the calibration inputs).

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
    pub(super) fn get(&self, key: &str) -> Option<&Node> {
        match self {
            Node::Map(entries, _) => entries.iter().find(|(k, _)| k == key).map(|(_, v)| v),
            _ => None,
        }
    }

    pub(super) fn as_f64(&self) -> Option<f64> {
        match self {
            Node::Num(v) => Some(*v),
            Node::Text(t) => parse_number(t),
            _ => None,
        }
    }

    pub(super) fn kind(&self) -> &'static str {
        match self {
            Node::Map(..) => "a map",
            Node::Seq(_) => "a list",
            Node::Num(_) => "a number",
            Node::Text(_) => "text",
        }
    }
}

/// A number as OpenCV writes it: `1.5`, `0.`, `-2.5e-01`, `.Inf`, `-.Inf`, `.Nan`.
pub(super) fn parse_number(t: &str) -> Option<f64> {
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

pub(super) fn scalar(text: &str) -> Node {
    match parse_number(text) {
        Some(v) => Node::Num(v),
        None => Node::Text(text.to_string()),
    }
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
