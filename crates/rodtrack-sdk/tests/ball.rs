//! The table frame and the ball, end to end on the simulator: calibration from the simulated
//! clicks, a session with the ball, the rows against the simulator's truth.

#![allow(clippy::unwrap_used)]

use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::calib::table::calibrate_table;
use rodtrack_core::calib::CalibrationFile;
use rodtrack_core::CameraIntrinsics;
use rodtrack_io::{BallVecSink, VecSink};
use rodtrack_sdk::{Session, SessionOptions};
use rodtrack_sim::{build_simulation, Simulation};

mod common;
use common::{calibrate, session_cameras};

/// The ball rows of a session over every frame of `sim`.
fn track_ball(sim: &Simulation, cal: &CalibrationFile) -> Vec<BallRow> {
    let cameras = session_cameras(sim, cal);
    let rows = BallVecSink::default();
    let session = Session::from_cameras(cameras, SessionOptions::default())
        .with_ball(cal, Box::new(rows.clone()))
        .unwrap();
    let (report, _) = session.run(VecSink::default()).unwrap();
    let out = rows.rows();
    let counts = report.ball.unwrap();
    assert_eq!(
        counts.ok + counts.predicted + counts.lost + counts.conflict,
        out.len() as u64
    );
    out
}

#[test]
fn table_frame_camera_centre_over_seeded_asbuilt_setups() {
    let seeds: Vec<u64> = (1..=10).collect();
    let errors: Vec<(u64, usize, f64)> = std::thread::scope(|s| {
        let handles: Vec<_> = seeds
            .chunks(5)
            .map(|chunk| {
                s.spawn(move || {
                    let mut out = Vec::new();
                    for &seed in chunk {
                        let sim = build_simulation(
                            "static",
                            Some(1),
                            seed,
                            false,
                            &format!("asbuilt:{seed}"),
                        )
                        .unwrap();
                        for cam in 0..sim.cameras().len() {
                            let inputs = sim.calibration_inputs(cam, seed).unwrap();
                            let m = inputs.opencv_model_optional.as_ref().unwrap();
                            let k = CameraIntrinsics::from_opencv(m.camera_matrix, &m.dist_coeffs)
                                .unwrap();
                            let table = inputs
                                .table
                                .as_ref()
                                .expect("the simulator clicks the field");
                            let cal = calibrate_table(table, &k, "sim").unwrap();
                            let truth = sim.table_pose(cam).unwrap().centre_world();
                            let c = cal.camera_centre_mm;
                            let e = ((c[0] - truth[0]).powi(2)
                                + (c[1] - truth[1]).powi(2)
                                + (c[2] - truth[2]).powi(2))
                            .sqrt();
                            out.push((seed, cam, e));
                        }
                    }
                    out
                })
            })
            .collect();
        handles
            .into_iter()
            .flat_map(|h| h.join().unwrap())
            .collect()
    });
    let mut e: Vec<f64> = errors.iter().map(|x| x.2).collect();
    e.sort_by(|a, b| a.total_cmp(b));
    let (median, worst) = (e[e.len() / 2], e[e.len() - 1]);
    eprintln!(
        "camera centre error over {} cameras: median {median:.2} mm, worst {worst:.2} mm",
        e.len()
    );
    for (seed, cam, err) in &errors {
        eprintln!("  asbuilt:{seed} camera {cam}: {err:.2} mm");
    }
    assert_eq!(
        e.len(),
        20,
        "every camera of every setup gives a table pose"
    );
    assert!(
        median < MEDIAN_BOUND_MM && worst < WORST_BOUND_MM,
        "median {median:.2}, worst {worst:.2} mm"
    );
}

/// Bounds with margin over what was measured (see docs/ball.md).
const MEDIAN_BOUND_MM: f64 = 2.5;
const WORST_BOUND_MM: f64 = 6.0;

#[test]
fn ball_rolling_at_up_to_2_m_s_is_measured_within_the_targets() {
    let seed = 3;
    let mut sim = build_simulation("ball", Some(240), seed, false, "default").unwrap();
    let cal = calibrate(&mut sim, seed);
    let rows = track_ball(&sim, &cal);
    for cam in 0..sim.cameras().len() as u32 {
        let (mut errs, mut half, mut found, mut false_ok) = (Vec::new(), 0usize, 0usize, 0usize);
        for r in rows
            .iter()
            .filter(|r| r.camera == rodtrack_core::CameraId::Camera(cam))
        {
            let t = sim.ball_truth(r.frame as usize).unwrap();
            let vis = t.visible[cam as usize];
            let ok = r.status == BallStatus::Ok;
            if vis >= 0.5 {
                half += 1;
                found += ok as usize;
            }
            if ok {
                if vis == 0.0 {
                    false_ok += 1;
                } else {
                    errs.push((r.x_mm - t.x_mm, r.y_mm - t.y_mm));
                }
            }
        }
        let n = errs.len() as f64;
        let (mx, my) = (
            errs.iter().map(|e| e.0).sum::<f64>() / n,
            errs.iter().map(|e| e.1).sum::<f64>() / n,
        );
        let std = (errs
            .iter()
            .map(|e| (e.0 - mx).powi(2) + (e.1 - my).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let max = errs.iter().map(|e| e.0.hypot(e.1)).fold(0.0, f64::max);
        let rate = found as f64 / half.max(1) as f64;
        eprintln!(
            "camera {cam}: {} ok rows, error std {std:.2} mm, max {max:.2} mm, bias ({mx:.2}, {my:.2}) mm, \
             detected on {found}/{half} = {rate:.3} of the frames at least half visible, {false_ok} without a ball",
            errs.len()
        );
        assert!(half > 50, "camera {cam}: the scenario shows the ball");
        assert!(
            std <= 1.0 && max <= 3.0,
            "camera {cam}: std {std:.2} mm, max {max:.2} mm (targets 1 and 3)"
        );
        assert_eq!(
            false_ok, 0,
            "camera {cam}: a position where no ball is visible"
        );
        // The target.
        assert!(
            rate >= 0.99,
            "camera {cam}: detected on {rate:.3} of the half-visible frames"
        );
    }
    fused_within_the_targets(&sim, &rows);
}

/// The fused rows: one per frame; `ok` on every frame a camera has `ok`; error std <= 1 mm and
/// max <= 3 mm against the truth; no conflict; and the fused track's frame-to-frame motion
/// never departs from the truth's by more than the cameras' 3 mm bound (no hand-over jump).
fn fused_within_the_targets(sim: &Simulation, rows: &[BallRow]) {
    let fused: Vec<&BallRow> = rows
        .iter()
        .filter(|r| r.camera == rodtrack_core::CameraId::Fused)
        .collect();
    assert_eq!(fused.len(), sim.frame_count(), "one fused row per frame");
    let (mut errs, mut both, mut one, mut conflict, mut missed) = (Vec::new(), 0, 0, 0, 0);
    for f in &fused {
        let cams_ok = rows
            .iter()
            .filter(|r| {
                r.frame == f.frame
                    && r.camera != rodtrack_core::CameraId::Fused
                    && r.status == BallStatus::Ok
            })
            .count();
        match cams_ok {
            0 => {}
            1 => one += 1,
            _ => both += 1,
        }
        conflict += (f.status == BallStatus::Conflict) as usize;
        if cams_ok > 0 && f.status != BallStatus::Ok {
            missed += 1;
        }
        if f.status == BallStatus::Ok {
            let t = sim.ball_truth(f.frame as usize).unwrap();
            errs.push((f.frame, f.x_mm - t.x_mm, f.y_mm - t.y_mm));
        }
    }
    let n = errs.len() as f64;
    let (mx, my) = (
        errs.iter().map(|e| e.1).sum::<f64>() / n,
        errs.iter().map(|e| e.2).sum::<f64>() / n,
    );
    let std = (errs
        .iter()
        .map(|e| (e.1 - mx).powi(2) + (e.2 - my).powi(2))
        .sum::<f64>()
        / n)
        .sqrt();
    let max = errs.iter().map(|e| e.1.hypot(e.2)).fold(0.0, f64::max);
    // The error's change between consecutive ok frames: a jump at a hand-over shows here.
    let step = errs
        .windows(2)
        .filter(|w| w[1].0 == w[0].0 + 1)
        .map(|w| (w[1].1 - w[0].1).hypot(w[1].2 - w[0].2))
        .fold(0.0, f64::max);
    eprintln!(
        "fused: {} ok rows ({both} frames with both cameras, {one} with one), error std {std:.2} mm, \
         max {max:.2} mm, bias ({mx:.2}, {my:.2}) mm, largest error change between frames \
         {step:.2} mm, {conflict} conflicts, {missed} frames a camera saw but the fused row is not ok",
        errs.len()
    );
    assert!(both > 50 && one > 0, "the scenario crosses the overlap");
    assert!(
        std <= 1.0 && max <= 3.0,
        "fused: std {std:.2} mm, max {max:.2} mm"
    );
    assert_eq!(conflict, 0, "fused conflicts on a clean scenario");
    assert_eq!(missed, 0, "fused not ok where a camera is");
    assert!(
        step <= 1.5,
        "fused error jumps by {step:.2} mm between frames"
    );
}

/// Tracks the ball over `frames` frames of the `hands` scenario (hands and moving figures, no
/// ball) and returns the frames with hands and every `ok` ball row (each one a false
/// detection).
fn hands_run(seed: u64, frames: usize, setup: &str) -> (usize, Vec<BallRow>) {
    let mut sim = build_simulation("hands", Some(frames), seed, false, setup).unwrap();
    let with_hands = (0..frames)
        .filter(|&f| !sim.state_at(sim.timestamp_s(f)).hands.is_empty())
        .count();
    let cal = calibrate(&mut sim, seed);
    let rows = track_ball(&sim, &cal);
    // One row per camera and frame, and the fused row of each frame.
    assert_eq!(rows.len(), (sim.cameras().len() + 1) * frames, "{setup}");
    let found = rows
        .into_iter()
        .filter(|r| r.status == BallStatus::Ok)
        .collect();
    (with_hands, found)
}

#[test]
fn hands_and_figures_without_a_ball_give_no_detection() {
    let frames = 400;
    let (with_hands, found) = hands_run(5, frames, "default");
    assert!(
        with_hands > 50,
        "hands over the table in {with_hands} frames only"
    );
    eprintln!(
        "{frames} frames ({with_hands} with hands): {} detections",
        found.len()
    );
    assert!(
        found.is_empty(),
        "false detections: {:?}",
        &found[..found.len().min(5)]
    );
}

/// The long run of the target "0 false detections over 10,000 frames with hands and figures",
/// by hand: `cargo test --release -p rodtrack-sdk --test ball hands_soak -- --ignored
/// --nocapture` (two runs of `RODTRACK_HANDS_FRAMES` frames, 5000 by default: the reference
/// table and a table as built, both cameras).
#[test]
#[ignore = "long: about 10,000 frame sets; run by hand"]
fn hands_soak_gives_no_false_detection() {
    let frames: usize = std::env::var("RODTRACK_HANDS_FRAMES")
        .ok()
        .and_then(|v| v.parse().ok())
        .unwrap_or(5000);
    let runs = std::thread::scope(|s| {
        let handles: Vec<_> = [(5, "default"), (6, "asbuilt:6")]
            .into_iter()
            .map(|(seed, setup)| s.spawn(move || (setup, hands_run(seed, frames, setup))))
            .collect();
        handles
            .into_iter()
            .map(|h| h.join().unwrap())
            .collect::<Vec<_>>()
    });
    let mut false_rows = Vec::new();
    for (setup, (with_hands, found)) in runs {
        eprintln!(
            "hands, {setup}: {frames} frame sets, {with_hands} with hands, {} false detections",
            found.len()
        );
        false_rows.extend(found);
    }
    assert!(
        false_rows.is_empty(),
        "false detections: {:?}",
        &false_rows[..false_rows.len().min(5)]
    );
}

/// The detector's fast path (specks rejected before their ray, each quad's colour computed
/// once per fit) gives exactly the plain reference's detections: over the ball scenario on
/// tables as built, by the coarse scan of the whole image and by the window around the last
/// detection, and in the hands scenario (no ball, many specks).
#[test]
fn fast_ball_detection_equals_the_plain_reference() {
    use rodtrack_core::ball::BallDetector;
    use rodtrack_core::FrameView;
    let mut compared = (0usize, 0usize);
    for (scenario, seed, setup) in [
        ("ball", 1, "asbuilt:1"),
        ("ball", 2, "asbuilt:2"),
        ("hands", 5, "default"),
    ] {
        let frames = 40;
        let mut sim = build_simulation(scenario, Some(frames), seed, false, setup).unwrap();
        for cam in 0..sim.cameras().len() {
            let cal = sim.calibrated_camera_with_ball(cam, seed).unwrap();
            let mut fast = BallDetector::new(&cal).unwrap().unwrap();
            let mut plain = BallDetector::new(&cal).unwrap().unwrap().reference();
            let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
            let mut around = None;
            for f in 0..frames {
                let meta = sim.render(f, cam, &mut buf).unwrap();
                let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)
                    .unwrap();
                for at in [None, around] {
                    let a = fast.detect(&view, at);
                    let b = plain.detect(&view, at);
                    assert_eq!(
                        a, b,
                        "{scenario} {setup} camera {cam} frame {f} around {at:?}"
                    );
                    compared.0 += 1;
                    compared.1 += a.is_some() as usize;
                }
                around = fast.detect(&view, None).map(|d| (d.u_px, d.v_px));
            }
        }
    }
    eprintln!(
        "{} detections compared, {} with a ball",
        compared.0, compared.1
    );
    assert!(
        compared.1 > 100,
        "too few detections to compare: {compared:?}"
    );
}

/// A ball partly under a rod or a figure, at least half of it visible, is found by the
/// detector on its own (the coarse scan, no prediction), at its place: the rays through the
/// rod do not take the rod's far edge for the ball's (a grey rod's colour lies between the
/// field's and the ball's on their axis; it is off the mixture line of the two colours).
#[test]
fn a_ball_half_hidden_by_a_rod_is_found_at_its_place() {
    use rodtrack_core::ball::BallDetector;
    use rodtrack_core::FrameView;
    let seed = 3;
    let frames = 240;
    let mut sim = build_simulation("ball", Some(frames), seed, false, "default").unwrap();
    for cam in 0..sim.cameras().len() {
        let cal = sim.calibrated_camera_with_ball(cam, seed).unwrap();
        let mut det = BallDetector::new(&cal).unwrap().unwrap();
        let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
        let (mut partly, mut found, mut missed) = (0usize, 0usize, Vec::new());
        for f in 0..frames {
            let t = sim.ball_truth(f).unwrap();
            let vis = t.visible[cam];
            if !(0.5..0.95).contains(&vis) {
                continue;
            }
            let meta = sim.render(f, cam, &mut buf).unwrap();
            let view =
                FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
            partly += 1;
            match det.detect(&view, None) {
                Some(d) if (d.x_mm - t.x_mm).hypot(d.y_mm - t.y_mm) <= 3.0 => found += 1,
                other => missed.push((
                    f,
                    vis,
                    other.map(|d| (d.x_mm - t.x_mm).hypot(d.y_mm - t.y_mm)),
                )),
            }
        }
        eprintln!("camera {cam}: {found} of {partly} partly hidden frames found within 3 mm; missed {missed:?}");
        assert!(
            partly >= 10,
            "camera {cam}: the scenario hides the ball partly"
        );
        assert!(
            found as f64 >= 0.99 * partly as f64,
            "camera {cam}: found on {found} of {partly} frames; missed (frame, visible, error mm): {missed:?}"
        );
    }
}

/// The rolling ball over 10 tables as built (cameras tilted, shifted, other lenses; rods off
/// their places): per camera the detection on half-visible frames and the error of `ok` rows,
/// fused the error; worst and median over the setups against the targets. About two
/// minutes: run by hand.
#[test]
#[ignore = "long: 10 tables as built x 240 frames; run by hand"]
fn ball_over_tables_as_built() {
    let (mut rates, mut stds, mut maxs) = (Vec::new(), Vec::new(), Vec::new());
    for k in 1..=10u64 {
        let setup = format!("asbuilt:{k}");
        let mut sim = build_simulation("ball", Some(240), k, false, &setup).unwrap();
        let cal = calibrate(&mut sim, k);
        let rows = track_ball(&sim, &cal);
        let mut line = format!("{setup}:");
        for cam in 0..=sim.cameras().len() as u32 {
            let id = if cam as usize == sim.cameras().len() {
                rodtrack_core::CameraId::Fused
            } else {
                rodtrack_core::CameraId::Camera(cam)
            };
            let (mut errs, mut half, mut found) = (Vec::new(), 0usize, 0usize);
            for r in rows.iter().filter(|r| r.camera == id) {
                let t = sim.ball_truth(r.frame as usize).unwrap();
                let vis = match id {
                    rodtrack_core::CameraId::Camera(c) => t.visible[c as usize],
                    _ => t.visible.iter().copied().fold(0.0, f64::max),
                };
                let ok = r.status == BallStatus::Ok;
                if vis >= 0.5 {
                    half += 1;
                    found += ok as usize;
                }
                if ok && vis > 0.0 {
                    errs.push((r.x_mm - t.x_mm).hypot(r.y_mm - t.y_mm));
                }
            }
            let n = errs.len().max(1) as f64;
            let rms = (errs.iter().map(|e| e * e).sum::<f64>() / n).sqrt();
            let max = errs.iter().copied().fold(0.0, f64::max);
            let rate = found as f64 / half.max(1) as f64;
            line += &format!(
                " {id}: {found}/{half} = {rate:.3}, error rms {rms:.2} mm, max {max:.2} mm;"
            );
            rates.push(rate);
            stds.push(rms);
            maxs.push(max);
        }
        eprintln!("{line}");
    }
    let worst_median = |v: &mut Vec<f64>, worst_is_low: bool| {
        v.sort_by(f64::total_cmp);
        let w = if worst_is_low { v[0] } else { v[v.len() - 1] };
        (w, v[v.len() / 2])
    };
    let (rw, rm) = worst_median(&mut rates, true);
    let (sw, sm) = worst_median(&mut stds, false);
    let (mw, mm) = worst_median(&mut maxs, false);
    eprintln!(
        "over 10 tables as built, cameras and fused: detection worst {rw:.3} median {rm:.3}; \
         error rms worst {sw:.2} median {sm:.2} mm; max worst {mw:.2} median {mm:.2} mm"
    );
    assert!(rw >= 0.99, "detection {rw:.3}");
    assert!(
        sw <= 1.0 && mw <= 3.0,
        "error rms {sw:.2} mm, max {mw:.2} mm"
    );
}

/// Table as built 7 (seed 7), camera 0: the ball rolls along the end wall past the goal's
/// mouth (frames 195-214) with more than half of it in view, but the field shows only along a
/// sixth of its outline (the wall and the goal behind it elsewhere): 6 or 7 edge rays. The
/// tracker follows it (the prediction stands in for the missing rays) within 3 mm.
#[test]
fn a_ball_along_the_end_wall_is_followed() {
    use rodtrack_core::ball::track::BallTracker;
    use rodtrack_core::{FrameView, Timestamp};
    let mut sim = build_simulation("ball", Some(215), 7, false, "asbuilt:7").unwrap();
    let cal = calibrate(&mut sim, 7);
    let mut tracker = BallTracker::new(&cal.cameras[0]).unwrap().unwrap();
    let mut buf = vec![0u8; sim.frame_bytes(0).unwrap()];
    let (mut half, mut missed, mut worst_mm) = (0usize, Vec::new(), 0.0f64);
    for f in 185..215usize {
        let info = sim.render(f, 0, &mut buf).unwrap();
        let view = FrameView::new(&buf, info.width, info.height, info.stride, info.format).unwrap();
        let t_ns = (sim.timestamp_s(f) * 1e9).round() as u64;
        let row = tracker.process(&view, f as u64, Timestamp::from_nanos(t_ns));
        let truth = sim.ball_truth(f).unwrap();
        if f < 195 || truth.visible[0] < 0.5 {
            continue;
        }
        half += 1;
        if row.status == BallStatus::Ok {
            worst_mm = worst_mm.max((row.x_mm - truth.x_mm).hypot(row.y_mm - truth.y_mm));
        } else {
            missed.push((f, row.status));
        }
    }
    eprintln!(
        "{half} frames at least half in view, missed {missed:?}, worst error {worst_mm:.2} mm"
    );
    assert!(half >= 10, "only {half} frames at least half in view");
    assert!(missed.is_empty(), "not detected: {missed:?}");
    assert!(worst_mm <= 3.0, "worst error {worst_mm:.2} mm");

    // The fewer points hold only near a prediction: frame 203 alone (6 or 7 points) is found
    // from a prediction at the ball, not from one 1.5 image radii off (the fit's centre is
    // then farther than a radius from it) nor by the coarse scan (8 points).
    use rodtrack_core::ball::BallDetector;
    let mut det = BallDetector::new(&cal.cameras[0]).unwrap().unwrap();
    let info = sim.render(203, 0, &mut buf).unwrap();
    let view = FrameView::new(&buf, info.width, info.height, info.stride, info.format).unwrap();
    let truth = sim.ball_truth(203).unwrap();
    let (u, v) = det
        .camera()
        .project([truth.x_mm, truth.y_mm, det.radius_mm()])
        .unwrap();
    let r = rodtrack_core::calib::ball::expected_radius_px(det.camera(), u, v, det.radius_mm())
        .unwrap();
    let at = det
        .detect(&view, Some((u, v)))
        .expect("found from a prediction at the ball");
    let e = (at.x_mm - truth.x_mm).hypot(at.y_mm - truth.y_mm);
    assert!(
        at.edge_points < 8 && e <= 3.0,
        "{} points, {e:.2} mm",
        at.edge_points
    );
    let off = det.detect(&view, Some((u + 1.5 * r, v)));
    assert!(
        off.is_none(),
        "found from a prediction 1.5 radii off: {off:?}"
    );
    assert!(
        det.detect(&view, None).is_none(),
        "found by the coarse scan"
    );
}

/// The detector around a prediction: a prediction a third of the ball's image radius off, and
/// one 1.5 radii off (the window around it still holds the ball), each give the ball's place
/// within a millimetre of the coarse scan's detection of the same frame.
#[test]
fn a_prediction_near_or_off_the_ball_finds_it_where_the_scan_does() {
    use rodtrack_core::ball::BallDetector;
    use rodtrack_core::FrameView;
    let mut sim = build_simulation("ball", Some(40), 3, false, "default").unwrap();
    let cal = sim.calibrated_camera_with_ball(0, 3).unwrap();
    let mut det = BallDetector::new(&cal).unwrap().unwrap();
    let mut buf = vec![0u8; sim.frame_bytes(0).unwrap()];
    let mut compared = 0;
    for f in (0..40).step_by(4) {
        let info = sim.render(f, 0, &mut buf).unwrap();
        let view = FrameView::new(&buf, info.width, info.height, info.stride, info.format).unwrap();
        let Some(scan) = det.detect(&view, None) else {
            continue;
        };
        let (u, v) = (scan.u_px, scan.v_px);
        let r = rodtrack_core::calib::ball::expected_radius_px(det.camera(), u, v, det.radius_mm())
            .unwrap();
        for (k, off) in [(0.33f64, 0.2f64), (1.5, 1.1)].into_iter().enumerate() {
            let (du, dv) = (off.0 * r * off.1.cos(), off.0 * r * off.1.sin());
            let near = det
                .detect(&view, Some((u + du, v + dv)))
                .unwrap_or_else(|| {
                    panic!("frame {f}: no ball from a prediction {} radii off", off.0)
                });
            let e = (near.x_mm - scan.x_mm).hypot(near.y_mm - scan.y_mm);
            assert!(
                e <= 1.0,
                "frame {f}, prediction {k}: {e:.2} mm from the scan's"
            );
        }
        compared += 1;
    }
    assert!(compared >= 8, "{compared} frames with a ball");
}

/// Every detection of the whole field's coarse scan over the ball scenario's first 60 frames on
/// two tables as built, both cameras: `each(label, detector, view, frame, detection)`.
fn for_each_whole_scan_detection(
    mut each: impl FnMut(
        &str,
        &mut rodtrack_core::ball::BallDetector,
        &rodtrack_core::FrameView,
        usize,
        rodtrack_core::ball::Detection,
    ),
) {
    use rodtrack_core::ball::BallDetector;
    use rodtrack_core::FrameView;
    for (seed, setup) in [(1, "asbuilt:1"), (2, "asbuilt:2")] {
        let frames = 60;
        let mut sim = build_simulation("ball", Some(frames), seed, false, setup).unwrap();
        for cam in 0..sim.cameras().len() {
            let cal = sim.calibrated_camera_with_ball(cam, seed).unwrap();
            let mut det = BallDetector::new(&cal).unwrap().unwrap();
            let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
            for f in 0..frames {
                let meta = sim.render(f, cam, &mut buf).unwrap();
                let view = FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format)
                    .unwrap();
                if let Some(whole) = det.detect(&view, None) {
                    each(&format!("{setup} camera {cam}"), &mut det, &view, f, whole);
                }
            }
        }
    }
}

/// The same detection, to the last bits of the blob's centre (a region's cells counted from its
/// own first row and column).
fn same_detection(a: &rodtrack_core::ball::Detection, b: &rodtrack_core::ball::Detection) -> bool {
    (a.u_px - b.u_px).abs() < 1e-9
        && (a.v_px - b.v_px).abs() < 1e-9
        && (a.x_mm - b.x_mm).abs() < 1e-9
        && (a.y_mm - b.y_mm).abs() < 1e-9
        && a.edge_points == b.edge_points
}

/// A ball the coarse scan of the whole field finds is found alike by the scan of at least one
/// of its bands (the tracker scans one band per frame while it predicts a hidden ball): the
/// same blob's cells on the same grid, so the same fit but for the last bits of the blob's
/// centre (a band's rows counted from its own first row). The bands overlap by a ball, so
/// that none cuts it in two. Over the ball scenario on tables as built, both cameras.
#[test]
fn every_ball_the_whole_scan_finds_a_band_finds_alike() {
    use rodtrack_core::ball::tuning::PREDICTED_SCAN_BANDS;
    let (mut compared, mut near_border) = (0usize, 0usize);
    for_each_whole_scan_detection(|label, det, view, f, whole| {
        let found: Vec<usize> = (0..PREDICTED_SCAN_BANDS)
            .filter(|&k| {
                det.detect_in_band(view, None, Some((k, PREDICTED_SCAN_BANDS)))
                    .is_some_and(|d| same_detection(&d, &whole))
            })
            .collect();
        assert!(
            !found.is_empty(),
            "{label} frame {f}: no band finds the ball at ({:.1}, {:.1}) px",
            whole.u_px,
            whole.v_px
        );
        compared += 1;
        near_border += (found.len() > 1) as usize;
    });
    eprintln!("{compared} detections, {near_border} found by two bands");
    assert!(compared > 100, "too few detections: {compared}");
}

/// A ball the coarse scan of the whole field finds is found alike by the scan of a reach that
/// holds its centre (the tracker's first scan after the window misses the ball: where it can
/// have gone since it was last seen), the reach's centre anywhere up to 95 % of its radius
/// from the ball, and that scan covers a small part of the field. Over the ball scenario on
/// tables as built, both cameras.
#[test]
fn every_ball_the_whole_scan_finds_a_reach_holding_it_finds_alike() {
    use rodtrack_core::ball::{Reach, ScanArea};
    let mut compared = 0usize;
    let (mut part_min, mut part_max) = (f64::INFINITY, 0.0f64);
    for_each_whole_scan_detection(|label, det, view, f, whole| {
        // A frame at 200 fps at 15 m/s, and a ball's radius: the tracker's first reach.
        let radius_mm = 75.0 + 17.5;
        let (a, d) = (2.4 * f as f64, 0.95 * radius_mm * (f % 5) as f64 / 4.0);
        let reach = Reach {
            centre_mm: [whole.x_mm + d * a.cos(), whole.y_mm + d * a.sin()],
            radius_mm,
        };
        let area = ScanArea {
            band: None,
            reach: Some(reach),
        };
        let (part, field) = (det.scan_quads(area), det.scan_quads(ScanArea::default()));
        assert!(
            5 * part < field,
            "{label} frame {f}: the reach covers {part} of {field} quads"
        );
        part_min = part_min.min(part as f64 / field as f64);
        part_max = part_max.max(part as f64 / field as f64);
        let found = det.detect_in_area(view, None, area);
        assert!(
            found.is_some_and(|d| same_detection(&d, &whole)),
            "{label} frame {f}: the reach around ({:.1}, {:.1}) mm finds {found:?}, the whole \
             scan the ball at ({:.1}, {:.1}) mm",
            reach.centre_mm[0],
            reach.centre_mm[1],
            whole.x_mm,
            whole.y_mm
        );
        compared += 1;
    });
    eprintln!("{compared} detections; the reach covers {part_min:.3}-{part_max:.3} of the field");
    assert!(compared > 100, "too few detections: {compared}");
}

/// Each camera's detector on its own (the coarse scan, no prediction) over the frames of
/// scenario `shots` (seed 3, the first 2400 frames) where the ball flies at 8 m/s or more and
/// the camera sees at least 90 % of it, on `setup`: (frames, found, errors in mm).
fn fast_shots_detected(setup: &str) -> (usize, usize, Vec<f64>) {
    use rodtrack_core::ball::BallDetector;
    use rodtrack_core::FrameView;
    let (seed, frames) = (3, 2400);
    let mut sim = build_simulation("shots", Some(frames), seed, false, setup).unwrap();
    let (mut seen, mut found, mut errs) = (0usize, 0usize, Vec::new());
    for cam in 0..sim.cameras().len() {
        let cal = sim.calibrated_camera_with_ball(cam, seed).unwrap();
        let mut det = BallDetector::new(&cal).unwrap().unwrap();
        let mut buf = vec![0u8; sim.frame_bytes(cam).unwrap()];
        for f in 0..frames {
            let Some(t) = sim.ball_truth(f) else { continue };
            if t.vx_mm_s.hypot(t.vy_mm_s) < 8000.0 || t.visible[cam] < 0.9 {
                continue;
            }
            let meta = sim.render(f, cam, &mut buf).unwrap();
            let view =
                FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
            seen += 1;
            if let Some(d) = det.detect(&view, None) {
                found += 1;
                errs.push((d.x_mm - t.x_mm).hypot(d.y_mm - t.y_mm));
            }
        }
    }
    errs.sort_by(f64::total_cmp);
    let rms = (errs.iter().map(|e| e * e).sum::<f64>() / errs.len().max(1) as f64).sqrt();
    eprintln!(
        "{setup}: {found} of {seen} found; error rms {rms:.2} mm, max {:.2} mm",
        errs.last().copied().unwrap_or(f64::NAN)
    );
    (seen, found, errs)
}

/// A hard shot smeared over a long exposure (2 ms: 16-30 mm at 8-15 m/s) is placed at its
/// centre at mid-exposure as well as a ball rolling at 2 m/s must be (max 3 mm): the smear's
/// faded ends make it a smeared ball, whose centre its symmetry gives. The sphere's fit alone
/// (before) placed it up to 4.32 mm off (error RMS 1.71 mm).
#[test]
fn a_ball_smeared_over_a_long_exposure_is_placed_at_its_mid_exposure_centre() {
    let (seen, found, errs) = fast_shots_detected("exposure:2000");
    assert!(seen >= 50 && found >= 50, "{found} of {seen}");
    let max = errs.last().copied().unwrap_or(f64::NAN);
    assert!(max <= 3.0, "error max {max:.2} mm");
}

/// The detection target on the same frames: found on 99 % of them. Not met yet at a
/// 2 ms exposure (67 of 69; at 0.5 ms, `RODTRACK_TEST_SETUP=default`: 69 of 69):
/// docs/ball.md, "A long exposure". Run by hand.
#[test]
#[ignore = "target not met yet: 67 of 69 found at a 2 ms exposure (docs/ball.md)"]
fn a_ball_smeared_over_a_long_exposure_is_found_on_99_percent_of_the_frames() {
    let (seen, found, _) = fast_shots_detected(
        &std::env::var("RODTRACK_TEST_SETUP").unwrap_or("exposure:2000".into()),
    );
    assert!(
        found as f64 >= 0.99 * seen as f64,
        "{found} of {seen} found"
    );
}

/// At the default exposure (0.5 ms: up to 7.5 mm of smear) the same frames meet the issue's
/// detection target: each camera's coarse scan finds 99 % of them (69 of 69).
#[test]
fn a_hard_shot_at_the_default_exposure_is_found_on_99_percent_of_the_frames() {
    let (seen, found, errs) = fast_shots_detected("default");
    assert!(seen >= 50, "{seen} frames");
    assert!(
        found as f64 >= 0.99 * seen as f64,
        "{found} of {seen} found"
    );
    let max = errs.last().copied().unwrap_or(f64::NAN);
    assert!(max <= 3.0, "error max {max:.2} mm");
}
