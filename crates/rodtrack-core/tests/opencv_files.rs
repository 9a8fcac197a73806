//! OpenCV camera models as `cv::FileStorage` wrote them (OpenCV 4.14 and 5.0, YAML and JSON,
//! made by `tests/data/opencv/make_fixtures.py`): read to the exact doubles OpenCV held.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_core::calib::opencv::parse_opencv_model;
use rodtrack_core::CameraIntrinsics;
use std::path::PathBuf;

fn data(name: &str) -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
        .join("tests/data/opencv")
        .join(name)
}

/// `camera_matrix` and `dist_coeffs` from `<file>.expected.txt` (hex of the doubles' bits).
fn expected(name: &str) -> (Vec<f64>, Vec<f64>) {
    let text = std::fs::read_to_string(data(&format!("{name}.expected.txt"))).unwrap();
    let mut cam = Vec::new();
    let mut dist = Vec::new();
    for line in text.lines() {
        let mut words = line.split_whitespace();
        let key = words.next().unwrap();
        let values: Vec<f64> = words
            .map(|w| f64::from_bits(u64::from_str_radix(w, 16).unwrap()))
            .collect();
        match key {
            "camera_matrix" => cam = values,
            "dist_coeffs" => dist = values,
            other => panic!("{other}"),
        }
    }
    assert_eq!(cam.len(), 9);
    (cam, dist)
}

#[test]
fn filestorage_files_read_to_the_exact_values() {
    for name in [
        "opencv4_calib.yml",
        "opencv4_calib.json",
        "opencv5_calib.yml",
        "opencv5_calib.json",
        "opencv4_14_coeffs.json",
        "opencv4_float.yml",
    ] {
        let text = std::fs::read_to_string(data(name)).unwrap();
        let model = parse_opencv_model(&text).unwrap_or_else(|e| panic!("{name}: {e}"));
        let (cam, dist) = expected(name);
        let got: Vec<f64> = model.camera_matrix.iter().flatten().copied().collect();
        // Bit for bit: FileStorage writes the digits that identify each double.
        let bits = |v: &[f64]| v.iter().map(|x| x.to_bits()).collect::<Vec<_>>();
        assert_eq!(bits(&got), bits(&cam), "{name}: camera matrix");
        assert_eq!(bits(&model.dist_coeffs), bits(&dist), "{name}: distortion");
        assert!(matches!(model.dist_coeffs.len(), 4 | 5 | 14), "{name}");
        // And the model is one rodtrack can use.
        CameraIntrinsics::from_opencv(model.camera_matrix, &model.dist_coeffs)
            .unwrap_or_else(|e| panic!("{name}: {e}"));
    }
}

#[test]
fn yaml_and_json_of_one_calibration_agree() {
    for v in ["opencv4", "opencv5"] {
        let y = std::fs::read_to_string(data(&format!("{v}_calib.yml"))).unwrap();
        let j = std::fs::read_to_string(data(&format!("{v}_calib.json"))).unwrap();
        assert_eq!(
            parse_opencv_model(&y).unwrap(),
            parse_opencv_model(&j).unwrap()
        );
    }
}

#[test]
fn the_rational_model_is_refused_by_name() {
    let text = std::fs::read_to_string(data("opencv4_rational.yml")).unwrap();
    let e = parse_opencv_model(&text).unwrap_err().to_string();
    assert!(
        e.contains("distortion_coefficients") && e.contains("k4 = ") && e.contains("k6 = "),
        "{e}"
    );
    assert!(
        !e.contains("s1 ="),
        "the zero thin-prism terms are not blamed: {e}"
    );
}
