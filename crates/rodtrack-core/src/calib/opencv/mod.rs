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
//!
//! The parts: `node` (the parsed tree), `flow` (JSON and YAML flow values), `yaml` (block
//! YAML), `model` (the camera model from the tree, and back to YAML), `error`.

mod error;
mod flow;
mod model;
mod node;
mod yaml;

pub use error::OpencvFileError;
pub use model::{is_model_key, model_from_node, OpencvModel};
pub use node::Node;

use flow::Flow;
use yaml::parse_yaml;

/// Reads an OpenCV camera model from the text of a FileStorage file (YAML or JSON).
pub fn parse_opencv_model(text: &str) -> Result<OpencvModel, OpencvFileError> {
    let root = parse_file_storage(text)?;
    model_from_node(&root, false)
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::calib::ImageSize;

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
