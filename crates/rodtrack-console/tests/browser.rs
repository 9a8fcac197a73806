//! The console in a real browser: headless Debian chromium driven over the DevTools protocol.
//! Skipped with a message when chromium is absent, unless `RODTRACK_REQUIRE_BROWSER=1`.
//! `RODTRACK_UPDATE_SCREENSHOT=1` rewrites docs/console.png from the simulated demo.
#![allow(clippy::unwrap_used)]

mod common;

use common::{chromium, get_json, http, post_json, Browser, Demo, TempDir};
use rodtrack_console::{
    calib::default_inputs, calib::new_rod, CalibrationContext, CameraSetup, Console, OwnedFrame,
    PipelineStats, RodGeometry, RodOverlay,
};
use rodtrack_core::calib::CalibrationFile;
use rodtrack_core::{CameraId, FrameView, Measurement, PixelFormat, RodResult, Status};
use serde_json::json;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// One browser at a time (two chromiums on 2 cores are slow).
static BROWSER: Mutex<()> = Mutex::new(());

const W: usize = 640;
const H: usize = 480;

fn synthetic_frame(k: u64) -> Vec<u8> {
    let mut d = vec![0u8; W * H];
    for y in 0..H {
        for x in 0..W {
            let stripe = ((x as u64 + 3 * k) / 16) % 2 == 0;
            d[y * W + x] = if stripe { 180 } else { 60 } + (y / 16) as u8;
        }
    }
    d
}

#[test]
fn page_shows_frames_and_plots_and_clicks_become_calibration_points() {
    let Some(exe) = chromium() else { return };
    let _one = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let reference = synthetic_frame(0);
    let view = FrameView::packed(&reference, W, H, PixelFormat::Mono8).unwrap();
    let owned = OwnedFrame::from_view(&view, 0, 0.0);
    let mut inputs = default_inputs(0, &owned);
    inputs.rods.push(new_rod(0, [-50.0, 50.0]));
    let console = Console::start(
        "127.0.0.1:0".parse().unwrap(),
        Some(CalibrationContext {
            out_path: None,
            cameras: vec![CameraSetup {
                index: 0,
                inputs,
                reference: Some(owned),
            }],
        }),
    )
    .unwrap();
    let addr = console.addr();
    let stop = AtomicBool::new(false);
    std::thread::scope(|s| {
        // The tracking side: 100 frames/s with one overlay (a line, no marker), rows for 3 rods.
        s.spawn(|| {
            let line = Arc::new(RodGeometry::line_only(
                0,
                vec![[100.0, 20.0], [120.0, 460.0]],
            ));
            let mut k = 1u64;
            while !stop.load(Ordering::Relaxed) {
                let d = synthetic_frame(k);
                let v = FrameView::packed(&d, W, H, PixelFormat::Mono8).unwrap();
                let t = k as f64 / 100.0;
                let overlay = RodOverlay::new(
                    line.clone(),
                    &RodResult {
                        status: Status::Ok,
                        position_mm: 1.0,
                        angle_rad: 0.5,
                        quality: 1.0,
                        ncc: 0.9,
                        ..RodResult::default()
                    },
                );
                console.publish_frame(0, &v, k, t, &[overlay]);
                let rows: Vec<Measurement> = (0..3)
                    .map(|rod| {
                        let mut m = Measurement::empty(
                            k,
                            rodtrack_core::Timestamp::from_secs_f64(t),
                            CameraId::Camera(0),
                            rod,
                            Status::Ok,
                        );
                        m.position_mm = 50.0 * (t + rod as f64).sin();
                        m.angle_unwrapped_rad = t * (rod as f64 + 1.0);
                        m.quality = 1.0;
                        m
                    })
                    .collect();
                console.publish_rows(&rows);
                console.publish_stats(&PipelineStats {
                    frames: k,
                    fps: 100.0,
                    frame_time_us: 300.0,
                    dropped_frames: 0,
                    bad_frames: 0,
                });
                k += 1;
                std::thread::sleep(Duration::from_millis(10));
            }
        });
        let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            let mut b = Browser::start(&exe);
            b.open(&console.url());
            b.wait_for(
                "window.rodtrack && rodtrack.frames > 1",
                Duration::from_secs(30),
            );
            // The live frame is drawn: most pixels are not black.
            let lit = b.eval(
                "(() => { const c = document.getElementById('cam-0'); \
                 const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; \
                 let n = 0; for (let i = 0; i < d.length; i += 4) if (d[i] + d[i+1] + d[i+2] > 60) n++; \
                 return n / (d.length / 4); })()",
            );
            assert!(
                lit.as_f64().unwrap() > 0.5,
                "frame canvas mostly empty: {lit}"
            );
            // The plots advance.
            b.wait_for(
                "rodtrack.rows > 30 && rodtrack.plotDraws > 2",
                Duration::from_secs(10),
            );
            let t1 = b.eval("rodtrack.lastT").as_f64().unwrap();
            let d1 = b.eval("rodtrack.plotDraws").as_f64().unwrap();
            std::thread::sleep(Duration::from_millis(1200));
            let t2 = b.eval("rodtrack.lastT").as_f64().unwrap();
            let d2 = b.eval("rodtrack.plotDraws").as_f64().unwrap();
            assert!(t2 > t1 + 0.5, "plot time did not advance: {t1} -> {t2}");
            assert!(d2 > d1, "plots not redrawn");
            let traced = b.eval(
                "(() => { const c = document.getElementById('plot-pos'); \
                 const d = c.getContext('2d').getImageData(0, 0, c.width, c.height).data; \
                 let n = 0; for (let i = 0; i < d.length; i += 4) if (d[i] > 150 || d[i+1] > 150) n++; return n; })()",
            );
            assert!(
                traced.as_f64().unwrap() > 200.0,
                "no traces drawn: {traced}"
            );
            // Calibration: clicks on the frozen frame become path points.
            b.eval("document.getElementById('tab-calib').click()");
            b.wait_for(
                "rodtrack.calFrame && rodtrack.calib",
                Duration::from_secs(10),
            );
            let targets = [[100.0, 50.0], [110.0, 240.0], [120.0, 430.0]];
            for t in targets {
                // The canvas' place on the page, read before every click.
                let rect = b.eval(
                    "(() => { const r = document.getElementById('cal-canvas').getBoundingClientRect(); \
                     return [r.left, r.top, r.width, r.height, rodtrack.calFrame.header.pw, rodtrack.calFrame.header.factor]; })()",
                );
                let r: Vec<f64> = rect
                    .as_array()
                    .unwrap()
                    .iter()
                    .map(|v| v.as_f64().unwrap())
                    .collect();
                let scale = r[2] / r[4] / r[5]; // page px per frame px
                let before =
                    b.eval("rodtrack.calib.cameras[0].inputs.rods[0].path_points_px.length");
                b.click(r[0] + (t[0] + 0.5) * scale, r[1] + (t[1] + 0.5) * scale);
                b.wait_for(
                    &format!(
                        "rodtrack.calib.cameras[0].inputs.rods[0].path_points_px.length > {before}"
                    ),
                    Duration::from_secs(10),
                );
            }
            let st = get_json(addr, "/api/calib");
            let pts = st["cameras"][0]["inputs"]["rods"][0]["path_points_px"]
                .as_array()
                .unwrap()
                .clone();
            assert_eq!(pts.len(), 3, "points: {pts:?}");
            for (p, t) in pts.iter().zip(targets) {
                let (x, y) = (p[0].as_f64().unwrap(), p[1].as_f64().unwrap());
                assert!(
                    (x - t[0]).abs() < 1.0 && (y - t[1]).abs() < 1.0,
                    "clicked {t:?}, got ({x}, {y})"
                );
            }
            // Freezing takes the next live frame.
            let (code, _) = post_json(addr, "/api/calib/0/freeze", json!({}));
            assert_eq!(code, 200);
            let mut frozen = 0;
            for _ in 0..50 {
                std::thread::sleep(Duration::from_millis(100));
                frozen = get_json(addr, "/api/calib")["cameras"][0]["frozen"]["frame_id"]
                    .as_u64()
                    .unwrap();
                if frozen > 0 {
                    break;
                }
            }
            assert!(frozen > 0, "freeze did not take a live frame");
            // Calibrating this synthetic frame fails with a message, not a crash.
            let (code, st) = post_json(addr, "/api/calibrate", json!({}));
            assert_eq!(code, 200);
            assert!(st["cameras"][0]["outcomes"][0]["error"].is_string(), "{st}");
            let (code, st) = post_json(addr, "/api/save", json!({}));
            assert_eq!(code, 400, "{st}");
        }));
        stop.store(true, Ordering::Relaxed);
        if let Err(e) = result {
            std::panic::resume_unwind(e);
        }
    });
    let (code, body) = http(addr, "GET", "/api/status", None);
    assert_eq!(code, 200, "{}", String::from_utf8_lossy(&body));
}

#[test]
fn demo_in_the_browser_screenshot_and_calibration_equal_to_the_cli() {
    let Some(exe) = chromium() else { return };
    let _one = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let mut demo = Demo::new(600);
    let out = TempDir::new("save");
    let toml_path = out.0.join("calibration.toml");
    let console = Console::start(
        "127.0.0.1:0".parse().unwrap(),
        Some(CalibrationContext {
            out_path: Some(toml_path.clone()),
            cameras: demo.setups.clone(),
        }),
    )
    .unwrap();
    let addr = console.addr();
    let mut b = Browser::start(&exe);
    b.open(&console.url());
    b.wait_for(
        "window.rodtrack && rodtrack.connected",
        Duration::from_secs(30),
    );
    let done = Arc::new(AtomicBool::new(false));
    std::thread::scope(|s| {
        let runner = s.spawn(|| {
            let r = demo.run(&console, 900, true, true);
            done.store(true, Ordering::Relaxed);
            r
        });
        b.wait_for(
            "rodtrack.frames >= 4 && rodtrack.lastT > 3 && rodtrack.cams.size == 2",
            Duration::from_secs(120),
        );
        std::thread::sleep(Duration::from_millis(300));
        let png = b.screenshot();
        assert!(png.starts_with(b"\x89PNG"), "not a PNG");
        let target =
            std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../target/console-demo.png");
        if let Some(dir) = target.parent() {
            std::fs::create_dir_all(dir).unwrap();
        }
        std::fs::write(&target, &png).unwrap();
        eprintln!("screenshot: {} ({} bytes)", target.display(), png.len());
        if std::env::var("RODTRACK_UPDATE_SCREENSHOT").as_deref() == Ok("1") {
            let docs =
                std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../../docs/console.png");
            std::fs::create_dir_all(docs.parent().unwrap()).unwrap();
            let small = common::shrink_png(&png, 1200);
            assert!(
                small.len() < 300_000,
                "docs/console.png would be {} bytes",
                small.len()
            );
            std::fs::write(&docs, &small).unwrap();
            eprintln!("wrote {}", docs.display());
        }
        let tm = runner.join().unwrap();
        eprintln!(
            "demo in the browser: console {:.2} % of the tracking time at 200 fps (medians)",
            100.0 * tm.share_at(200.0, 2.0, 2.0 * rodtrack_console::LIVE_FPS)
        );
    });
    // The copy path (`publish_frame`, for borrowed frames): decimated live frames (a 1440x1080 Bayer
    // frame copied as 720x540, shown as 360x270), drawn enlarged under sharp overlays.
    std::thread::scope(|s| {
        let runner = s.spawn(|| demo.run(&console, 600, true, false));
        b.wait_for(
            "rodtrack.cams.get(0) && rodtrack.cams.get(0).header.factor === 4",
            Duration::from_secs(120),
        );
        let shown = b.eval(
            "(() => { const p = rodtrack.cams.get(0), h = p.header; \
             const d = p.ctx.getImageData(0, 0, p.canvas.width, p.canvas.height).data; \
             let n = 0; for (let i = 0; i < d.length; i += 4) if (d[i] + d[i+1] + d[i+2] > 60) n++; \
             return [h.width, h.height, h.pw, h.ph, p.canvas.width, p.canvas.height, n / (d.length / 4)]; })()",
        );
        let v: Vec<f64> = shown
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert_eq!(
            &v[..6],
            &[1440.0, 1080.0, 360.0, 270.0, 720.0, 540.0],
            "{shown}"
        );
        assert!(v[6] > 0.5, "decimated frame mostly dark: {shown}");
        // The overlays the page draws: every rod's line, and markers with their Gray bits.
        let drawn = b.eval(
            "(() => { const o = rodtrack.cams.get(0).header.overlays; \
             return [o.length, Math.min(...o.map((r) => r.line_px.length)), \
             o.filter((r) => r.marker && r.marker.bits.length >= 3).length]; })()",
        );
        let d: Vec<f64> = drawn
            .as_array()
            .unwrap()
            .iter()
            .map(|x| x.as_f64().unwrap())
            .collect();
        assert!(
            d[0] >= 1.0 && d[1] >= 2.0 && d[2] >= 1.0,
            "overlays not drawn: {drawn}"
        );
        let target = std::path::Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("../../target/console-demo-copy.png");
        std::fs::write(&target, b.screenshot()).unwrap();
        eprintln!("screenshot of the copy path: {}", target.display());
        runner.join().unwrap();
    });
    // Calibrate in the console with the simulator's clicks: the same file as `rodtrack
    // calibrate` (calibrate_rod on the same inputs and reference frames) makes.
    let (code, st) = post_json(addr, "/api/calibrate", json!({}));
    assert_eq!(code, 200, "{st}");
    for cam in st["cameras"].as_array().unwrap() {
        assert_eq!(cam["calibrated"], json!(true), "{cam}");
    }
    let (code, saved) = post_json(addr, "/api/save", json!({}));
    assert_eq!(code, 200, "{saved}");
    let text = std::fs::read_to_string(&toml_path).unwrap();
    let file: CalibrationFile = toml::from_str(&text).unwrap();
    file.validate().unwrap();
    // The console's calibration page does not place the table frame or the ball yet (no
    // clicks for them): the rods' calibration is the CLI's, the table and ball are absent.
    let rods_only: Vec<_> = demo
        .cals
        .iter()
        .cloned()
        .map(|mut c| {
            c.table = None;
            c.ball = None;
            c
        })
        .collect();
    assert_eq!(file.cameras, rods_only);
    // The inputs written beside it hold the reference frame and the same points.
    let inputs_json = out.0.join("calibration.inputs/cam0.json");
    let inputs: rodtrack_core::calib::CalibrationInputs =
        serde_json::from_str(&std::fs::read_to_string(inputs_json).unwrap()).unwrap();
    let want = &demo.setups[0].inputs.rods;
    assert_eq!(inputs.rods.len(), want.len());
    for (a, b) in inputs.rods.iter().zip(want) {
        assert_eq!(
            (a.rod, a.travel_mm, &a.marker),
            (b.rod, b.travel_mm, &b.marker)
        );
        for (p, q) in a.path_points_px.iter().zip(&b.path_points_px) {
            assert!((p[0] - q[0]).abs() < 1e-9 && (p[1] - q[1]).abs() < 1e-9);
        }
    }
    assert!(out.0.join("calibration.inputs/cam0/000000.pgm").is_file());
}

#[test]
fn a_rod_at_zero_is_labelled_0_degrees_not_360() {
    let Some(exe) = chromium() else { return };
    let _one = BROWSER.lock().unwrap_or_else(|e| e.into_inner());
    let console = Console::start("127.0.0.1:0".parse().unwrap(), None).unwrap();
    let mut b = Browser::start(&exe);
    b.open(&console.url());
    b.wait_for("window.rodtrack !== undefined", Duration::from_secs(30));
    // The live view's text beside a rod, for angles around 0 rad (2 pi - 0.001 reads 0).
    let label = |b: &mut Browser, angle_rad: f64| -> String {
        b.eval(&format!(
            "rodtrack.overlayText({{rod: 1, status: 'ok', position_mm: 0.04, angle_rad: {angle_rad}}})"
        ))
        .as_str()
        .unwrap_or("(no text)")
        .to_string()
    };
    assert_eq!(label(&mut b, 6.282_174), "rod 1 ok 0.0 mm 0°");
    assert_eq!(label(&mut b, 0.001_291), "rod 1 ok 0.0 mm 0°");
    assert_eq!(label(&mut b, std::f64::consts::PI), "rod 1 ok 0.0 mm 180°");
    assert_eq!(label(&mut b, 4.712_389), "rod 1 ok 0.0 mm -90°");
    assert_eq!(label(&mut b, 1.6), "rod 1 ok 0.0 mm 92°");
    drop(b);
    console.shutdown();
}
