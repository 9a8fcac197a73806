//! The camera model: [`OpencvModel`], read from a parsed FileStorage tree (the keys, the
//! matrices, the checks on the coefficients) and written as OpenCV's YAML.

use super::error::OpencvFileError;
use super::node::Node;
use crate::calib::image_size::ImageSize;
use serde::{Deserialize, Deserializer, Serialize};

/// An OpenCV camera model as in the calibration inputs.
///
/// Written as `{"camera_matrix": [[fx, 0, cx], [0, fy, cy], [0, 0, 1]], "dist_coeffs": [k1, k2,
/// p1, p2, k3]}`. Read from that, and also from the forms `cv::FileStorage` writes: the keys
/// `cameraMatrix`/`K` and `distortion_coefficients`/`distCoeffs`/`D`, matrices as
/// `{"type_id": "opencv-matrix", "rows": 3, "cols": 3, "dt": "d", "data": [...]}`, 4, 5, 8, 12
/// or 14 coefficients of which those after `k3` must be zero. Other keys are refused.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct OpencvModel {
    /// 3x3 camera matrix.
    pub camera_matrix: [[f64; 3]; 3],
    /// Distortion coefficients `(k1, k2, p1, p2[, k3[, zeros]])`.
    pub dist_coeffs: Vec<f64>,
}

impl<'de> Deserialize<'de> for OpencvModel {
    fn deserialize<D: Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let node = Node::deserialize(d)?;
        model_from_node(&node, true).map_err(serde::de::Error::custom)
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
