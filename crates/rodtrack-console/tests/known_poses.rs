//! Known poses on the calibration page, on the simulator: the page asks "push rod k to its
//! left stop, click Capture"; the operator does (the simulated camera shows the rod at its
//! stop) and clicks, then the right stop; calibrating fits the travel to them; saving writes the
//! frames into the reference folder and `known_poses` into the inputs, which `rodtrack
//! calibrate`'s path (the SDK's `calibrate_files`) then uses.
#![allow(clippy::unwrap_used, missing_docs)]

mod common;

use common::{chromium, get_json, post_json, Browser, Demo, TempDir};
use rodtrack_console::{CalibrationContext, Console};
use rodtrack_core::calib::CalibrationInputs;
use rodtrack_core::FrameView;
use serde_json::json;
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::time::Duration;

#[test]
fn the_page_captures_a_rods_end_stops_and_calibration_uses_them() {
    let Some(exe) = chromium() else { return };
    let mut demo = Demo::new(4);
    let out = TempDir::new("poses");
    let toml_path = out.0.join("calibration.toml");
    let setup = demo.setups[0].clone();
    let rod_index = 2;
    let rod = setup.inputs.rods[rod_index].rod;
    let travel = setup.inputs.rods[rod_index].travel_mm;
    let console = Console::start(
        "127.0.0.1:0".parse().unwrap(),
        Some(CalibrationContext {
            out_path: Some(toml_path.clone()),
            cameras: vec![setup],
        }),
    )
    .unwrap();
    let addr = console.addr();
    // Before a camera has live frames a capture is refused, naming what is missing.
    let (code, body) = post_json(
        addr,
        &format!("/api/calib/0/rods/{rod}/known_pose"),
        json!({"stop": "left"}),
    );
    assert_eq!(code, 400, "{body}");
    assert!(
        body["error"].as_str().unwrap().contains("no live frames"),
        "{body}"
    );
    // Which stop the simulated operator holds the rod at: 0 left, 1 right.
    let stop_at = AtomicUsize::new(0);
    let done = AtomicBool::new(false);
    std::thread::scope(|s| {
        s.spawn(|| {
            let mut buf = vec![0u8; demo.sim.frame_bytes(0).unwrap()];
            let mut k = 1u64;
            while !done.load(Ordering::Relaxed) {
                let pos = travel[stop_at.load(Ordering::Relaxed)];
                let m = demo
                    .sim
                    .render_known_pose(0, rod_index, pos, &mut buf)
                    .unwrap();
                let v = FrameView::new(&buf, m.width, m.height, m.stride, m.format).unwrap();
                console.publish_frame(0, &v, k, k as f64 / 50.0, &[]);
                k += 1;
                std::thread::sleep(Duration::from_millis(20));
            }
        });
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let (code, body) = post_json(
                addr,
                &format!("/api/calib/0/rods/{rod}/known_pose"),
                json!({"stop": "middle"}),
            );
            assert_eq!(code, 400, "{body}");
            assert!(
                body["error"].as_str().unwrap().starts_with("stop:"),
                "{body}"
            );
            let mut b = Browser::start(&exe);
            b.open(&console.url());
            b.wait_for("window.rodtrack !== undefined", Duration::from_secs(30));
            b.eval("document.getElementById('tab-calib').click()");
            b.wait_for(
                "rodtrack.calib && rodtrack.calFrame",
                Duration::from_secs(20),
            );
            b.eval(&format!(
                "(() => {{ const s = document.getElementById('cal-rod'); s.value = '{rod}'; \
                 s.onchange(); return true; }})()"
            ));
            let hint = b.eval("document.getElementById('pose-hint').textContent");
            let hint = hint.as_str().unwrap();
            assert!(
                hint.starts_with(&format!(
                    "push rod {rod} to its left stop ({} mm)",
                    travel[0]
                )),
                "{hint}"
            );
            let click = |b: &mut Browser, id: &str| {
                let r = b.eval(&format!(
                    "(() => {{ const r = document.getElementById('{id}').getBoundingClientRect(); \
                     return [r.left + r.width / 2, r.top + r.height / 2]; }})()"
                ));
                b.click(r[0].as_f64().unwrap(), r[1].as_f64().unwrap());
            };
            let poses = format!(
                "(rodtrack.calib.cameras[0].inputs.rods.find((r) => r.rod === {rod}).known_poses || []).length"
            );
            click(&mut b, "cap-left");
            b.wait_for(&format!("{poses} === 1"), Duration::from_secs(20));
            stop_at.store(1, Ordering::Relaxed);
            std::thread::sleep(Duration::from_millis(200));
            click(&mut b, "cap-right");
            b.wait_for(&format!("{poses} === 2"), Duration::from_secs(20));
            let msg = b.eval("document.getElementById('cal-msg').textContent");
            assert!(
                msg.as_str().unwrap().contains("right stop captured"),
                "{msg}"
            );
            // The reference frame stayed the one the console started with.
            let st = get_json(addr, "/api/calib");
            assert_eq!(
                st["cameras"][0]["frozen"]["frame_id"],
                json!(0),
                "{}",
                st["cameras"][0]["frozen"]
            );
            assert_eq!(st["cameras"][0]["pose_frames"], json!(2));
            click(&mut b, "run-cal");
            b.wait_for(
                "document.getElementById('cal-msg').textContent.startsWith('calibrated')",
                Duration::from_secs(120),
            );
            let st = get_json(addr, "/api/calib");
            let outcome = st["cameras"][0]["outcomes"]
                .as_array()
                .unwrap()
                .iter()
                .find(|o| o["rod"] == json!(rod))
                .unwrap()
                .clone();
            let res = &outcome["residuals"];
            assert_eq!(res["travel_model"], json!("known_poses"), "{outcome}");
            let errors = res["known_pose_errors_mm"].as_array().unwrap();
            assert_eq!(errors.len(), 2, "{outcome}");
            eprintln!("console calibration, rod {rod}: known-pose errors {errors:?} mm");
            // The page shows them.
            let shown = b.eval("[...document.querySelectorAll('#residuals td.known-errors')].map((t) => t.textContent).join('|')");
            assert!(shown.as_str().unwrap().contains("frame 1:"), "{shown}");
            click(&mut b, "save");
            b.wait_for(
                "document.getElementById('cal-msg').textContent.startsWith('saved')",
                Duration::from_secs(30),
            );
        }));
        done.store(true, Ordering::Relaxed);
        if let Err(e) = result {
            std::panic::resume_unwind(e);
        }
    });
    // The inputs beside the file: the stops' frames in the reference folder, named by
    // `known_poses` with the travel limits as positions.
    let inputs_path = out.0.join("calibration.inputs/cam0.json");
    let inputs: CalibrationInputs =
        serde_json::from_str(&std::fs::read_to_string(&inputs_path).unwrap()).unwrap();
    let r = inputs.rods.iter().find(|r| r.rod == rod).unwrap();
    let got: Vec<(usize, f64)> = r
        .known_poses
        .iter()
        .map(|k| (k.frame, k.position_mm))
        .collect();
    assert_eq!(got, vec![(1, travel[0]), (2, travel[1])]);
    for name in ["000000.pgm", "000001.pgm", "000002.pgm"] {
        assert!(
            out.0.join("calibration.inputs/cam0").join(name).is_file(),
            "{name}"
        );
    }
    // `rodtrack calibrate`'s path reads them and fits the travel to them, as the console did.
    let file =
        rodtrack_sdk::calibrate_files(&[inputs_path.as_path()], &mut |w| eprintln!("{w}")).unwrap();
    let cal = file.cameras[0].rods.iter().find(|c| c.rod == rod).unwrap();
    assert_eq!(cal.residuals.travel_model, "known_poses");
    assert_eq!(cal.residuals.known_pose_errors_mm.len(), 2);
    let saved: rodtrack_core::calib::CalibrationFile =
        toml::from_str(&std::fs::read_to_string(&toml_path).unwrap()).unwrap();
    let console_rod = saved.cameras[0].rods.iter().find(|c| c.rod == rod).unwrap();
    // The same calibration, to rounding (the files' round trip moves the knots by 1e-8 px).
    assert_eq!(console_rod.residuals.travel_model, "known_poses");
    for (a, b) in console_rod
        .residuals
        .known_pose_errors_mm
        .iter()
        .zip(&cal.residuals.known_pose_errors_mm)
    {
        assert!(a[0] == b[0] && (a[1] - b[1]).abs() < 1e-6, "{a:?} vs {b:?}");
    }
    let (ka, kb) = (&console_rod.knots, &cal.knots);
    assert_eq!(ka.x_px.len(), kb.x_px.len());
    let worst = ka
        .x_px
        .iter()
        .zip(&kb.x_px)
        .chain(ka.y_px.iter().zip(&kb.y_px))
        .map(|(a, b)| (a - b).abs())
        .fold(0.0, f64::max);
    assert!(
        worst < 1e-6,
        "the console's and `calibrate`'s knots differ by {worst} px"
    );
}
