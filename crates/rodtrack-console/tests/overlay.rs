//! The live view's overlays from `CameraOverlays` (the rods' constant parts computed once)
//! are those computed from scratch from the trackers' knots, frame after frame of the simulated
//! demo, and serialise to the JSON the page reads (plain lists of points and bits).
#![allow(clippy::unwrap_used)]

mod common;

use common::Demo;
use rodtrack_console::RodOverlay;
use rodtrack_core::{gray, FrameView, RodResult, RodTracker, Status};

/// The overlay's JSON as computed before the constant parts were cached: straight from the
/// tracker's knots ([`rodtrack_core::Knots::at`]) with vectors.
fn reference(tracker: &RodTracker, result: &RodResult) -> serde_json::Value {
    let pt = |x: f64, y: f64| [x as f32, y as f32];
    let knots = tracker.knots();
    let n = knots.len();
    let step = n.div_ceil(48).max(1);
    let mut line: Vec<[f32; 2]> = (0..n)
        .step_by(step)
        .map(|i| pt(knots.x_px[i], knots.y_px[i]))
        .collect();
    if n > 0 && (n - 1) % step != 0 {
        line.push(pt(knots.x_px[n - 1], knots.y_px[n - 1]));
    }
    let placed = result.position_mm.is_finite()
        && n >= 2
        && (result.status == Status::Ok
            || (result.status == Status::Occluded && result.position_mm != 0.0));
    let marker = placed.then(|| {
        let m = tracker.marker();
        let pos = result.position_mm;
        let at = |u: f64| {
            let p = knots.at(pos + u);
            pt(p.x, p.y)
        };
        let code = gray(result.gray_step);
        let bits: Vec<serde_json::Value> = (0..m.bits())
            .map(|k| {
                serde_json::json!({
                    "centre_px": at(m.bit_space_centre_mm(k)),
                    "black": (code >> k) & 1 == 1,
                })
            })
            .collect();
        let lp = knots.at(pos + m.bit_space_centre_mm(0));
        let half = lp.radius_px * 70f64.to_radians().sin();
        let (ax, ay) = lp.offset(0.0, -half);
        let (bx, by) = lp.offset(0.0, half);
        serde_json::json!({
            "marker_px": [at(0.0), at(m.length_mm())],
            "barcode_px": [
                at(m.barcode_start_mm()),
                at(m.barcode_start_mm() + m.barcode_len_mm()),
            ],
            "bits": bits,
            "phase_window_px": [pt(ax, ay), pt(bx, by)],
            "radius_px": lp.radius_px as f32,
        })
    });
    let finite = |v: f64| if v.is_finite() { v } else { 0.0 };
    serde_json::json!({
        "rod": tracker.rod(),
        "status": result.status,
        "reason": result.reason,
        "line_px": line,
        "marker": marker,
        "position_mm": finite(result.position_mm),
        "angle_rad": finite(result.angle_rad),
        "quality": finite(result.quality),
        "ncc": finite(result.ncc),
    })
}

#[test]
fn cached_overlays_equal_the_ones_computed_from_the_knots() {
    let frames = 60;
    let mut demo = Demo::new(frames);
    let (mut pipes, geometry, mut bufs) = demo.pipelines();
    let mut overlays: Vec<Vec<RodOverlay>> = vec![Vec::new(); pipes.len()];
    let (mut rows, mut markers) = (Vec::new(), 0usize);
    for f in 0..frames {
        for (c, pipe) in pipes.iter_mut().enumerate() {
            let m = demo.sim.render(f, c, &mut bufs[c]).unwrap();
            let view = FrameView::new(&bufs[c], m.width, m.height, m.stride, m.format).unwrap();
            pipe.process(
                &view,
                f as u64,
                rodtrack_core::Timestamp::from_frame(f as u64, 200.0),
                &mut rows,
            )
            .unwrap();
            // Every other frame into the same vector (entries reused), else into a new one.
            if f % 2 == 1 {
                overlays[c] = Vec::new();
            }
            geometry[c].fill(pipe.last_results(), &mut overlays[c]);
            assert_eq!(overlays[c].len(), pipe.rods().len());
            for ((o, tr), r) in overlays[c].iter().zip(pipe.rods()).zip(pipe.last_results()) {
                let want = reference(tr, r);
                assert_eq!(
                    serde_json::to_value(o).unwrap(),
                    want,
                    "frame {f} camera {c}"
                );
                assert_eq!(
                    serde_json::to_value(rodtrack_console::overlays_for(tr, r)).unwrap(),
                    want
                );
                markers += usize::from(o.marker().is_some());
            }
            // The console's copy: equal, sharing the geometry.
            let mut copy = overlays[c].clone();
            overlays[c].clone_into(&mut copy);
            assert_eq!(copy, overlays[c]);
            for (a, b) in copy.iter().zip(&overlays[c]) {
                assert!(std::sync::Arc::ptr_eq(a.geometry(), b.geometry()));
                assert!(a.line_px().len() >= 2);
            }
        }
    }
    assert!(markers > frames, "too few markers placed: {markers}");
}
