//! Automatic calibration on the simulator: markers found without clicks, and path points from a
//! sweep recording, good enough to calibrate and track.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_core::calib::calibrate_rod;
use rodtrack_core::calib::find::{find_markers, path_points_from_sweep};
use rodtrack_core::{CameraIntrinsics, FrameView, Marker, Mode, RodTracker, Status};
use rodtrack_sim::{default_cameras, RenderMode, Scenario, SceneConfig, Simulation};

fn sim(scenario: &str, frames: usize) -> Simulation {
    let scene = SceneConfig::default();
    let sc = Scenario::by_name(scenario, &scene, 2)
        .unwrap()
        .with_frames(frames);
    Simulation::new(scene, default_cameras(), sc, RenderMode::Fast)
        .unwrap()
        .with_seed(2)
}

#[test]
fn markers_are_found_where_they_are() {
    let mut s = sim("static", 1);
    let marker = Marker::v1();
    for cam in 0..2 {
        let mut buf = vec![0u8; s.frame_bytes(cam).unwrap()];
        let meta = s.render_reference(cam, &mut buf).unwrap();
        let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
        let found = find_markers(&view, &marker, true, 0.7);
        let inputs = s.calibration_inputs(cam, 2).unwrap();
        assert_eq!(found.len(), inputs.rods.len(), "camera {cam}: {found:?}");
        for r in &inputs.rods {
            let rod = &s.scene().rods[r.rod as usize];
            let centre_y = rod.marker_y(36.0, 0.0);
            let (tx, ty) = s
                .project_rod_axis(cam, r.rod as usize, centre_y)
                .unwrap()
                .unwrap();
            let best = found
                .iter()
                .map(|f| ((f.x_px - tx).powi(2) + (f.y_px - ty).powi(2)).sqrt())
                .fold(f64::MAX, f64::min);
            eprintln!("camera {cam} rod {}: nearest detection {best:.2} px", r.rod);
            assert!(best < 3.0, "camera {cam} rod {}: {best} px", r.rod);
        }
    }
}

#[test]
fn sweep_path_points_calibrate_as_well_as_clicks() {
    let mut sweep = sim("sweep", 400);
    let marker = Marker::v1();
    let cam = 0;
    let mut buf = vec![0u8; sweep.frame_bytes(cam).unwrap()];
    let mut detections = Vec::new();
    for f in (0..sweep.frame_count()).step_by(10) {
        let meta = sweep.render(f, cam, &mut buf).unwrap();
        let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
        detections.extend(find_markers(&view, &marker, true, 0.7));
    }
    // Calibrate every rod from the sweep's path points instead of the clicks, then track exp3.
    let mut run = sim("exp3", 60);
    let mut inputs = run.calibration_inputs(cam, 2).unwrap();
    let meta = run.render_reference(cam, &mut buf).unwrap();
    let m = inputs.opencv_model_optional.clone().unwrap();
    let intr = CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs).unwrap();
    let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
    let mut trackers = Vec::new();
    for r in &mut inputs.rods {
        let clicked_x =
            r.path_points_px.iter().map(|p| p[0]).sum::<f64>() / r.path_points_px.len() as f64;
        let pts = path_points_from_sweep(&detections, clicked_x, true, 25.0);
        eprintln!("rod {}: {} path points from the sweep", r.rod, pts.len());
        assert!(pts.len() >= 5, "rod {}: {} points", r.rod, pts.len());
        r.path_points_px = pts;
        let cal = calibrate_rod(r, &view, Some(&intr)).unwrap();
        eprintln!(
            "rod {}: path rms {:.3} px",
            r.rod, cal.residuals.path_rms_px
        );
        // Clicked points carry about 1 px of error: the sweep's points must do at least as well.
        assert!(cal.residuals.path_rms_px < 1.0, "rod {}", r.rod);
        trackers.push(RodTracker::new(&cal, meta.width, meta.height, Mode::Enhanced).unwrap());
    }
    let mut worst_pos = 0.0f64;
    let mut n = 0;
    for f in 0..run.frame_count() {
        let meta = run.render(f, cam, &mut buf).unwrap();
        let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
        let truth = run.truth(f, cam).unwrap();
        for tr in &mut trackers {
            let r = tr.process(&view).unwrap();
            let t = truth.iter().find(|t| t.m.rod == tr.rod()).unwrap();
            if t.visible && r.status == Status::Ok {
                worst_pos = worst_pos.max((r.position_mm - t.m.position_mm).abs());
                n += 1;
            }
        }
    }
    eprintln!("exp3 after sweep calibration: {n} rows, worst position error {worst_pos:.3} mm");
    assert!(n > 300);
    assert!(worst_pos < 0.5);
}
