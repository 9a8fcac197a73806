//! Test helpers: a tiny HTTP client, a minimal DevTools-protocol client driving headless
//! Debian chromium, and the simulated demo (calibrated cameras and tracking) as a publisher.
#![allow(dead_code, clippy::unwrap_used)]

use rodtrack_console::{CameraOverlays, CameraSetup, ConsoleHandle, OwnedFrame, PipelineStats};
use rodtrack_core::calib::{calibrate_camera_from_view, CameraCalibration};
use rodtrack_core::{CameraId, CameraPipeline, FrameSetFilter, FrameView, Mode};
use rodtrack_sim::{default_cameras, RenderMode, Scenario, SceneConfig, Simulation};
use serde_json::{json, Value};
use std::io::{Read, Write};
use std::net::{SocketAddr, TcpStream};
use std::os::unix::process::CommandExt;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};

/// The session token the console gives its page (its `rodtrack-token` meta tag).
pub fn page_token(addr: SocketAddr) -> String {
    let (st, page) = http_with(addr, "GET", "/", None, &[]);
    assert_eq!(st, 200);
    let page = String::from_utf8_lossy(&page).into_owned();
    let at = page
        .find("name=\"rodtrack-token\" content=\"")
        .expect("the page carries its session token");
    let rest = &page[at + "name=\"rodtrack-token\" content=\"".len()..];
    rest[..rest.find('"').unwrap()].to_string()
}

/// One HTTP/1.1 request with `Connection: close`, as the console's page makes it (with the
/// page's session token on state-changing requests); returns (status, body).
pub fn http(addr: SocketAddr, method: &str, path: &str, body: Option<&Value>) -> (u16, Vec<u8>) {
    if method == "GET" {
        return http_with(addr, method, path, body, &[]);
    }
    let token = page_token(addr);
    http_with(
        addr,
        method,
        path,
        body,
        &[("X-Rodtrack-Token", token.as_str())],
    )
}

/// One HTTP/1.1 request with these extra headers (a `Host` among them replaces the
/// default); returns (status, body).
pub fn http_with(
    addr: SocketAddr,
    method: &str,
    path: &str,
    body: Option<&Value>,
    headers: &[(&str, &str)],
) -> (u16, Vec<u8>) {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    let body = body.map(|b| b.to_string()).unwrap_or_default();
    let mut extra = String::new();
    if !headers.iter().any(|(k, _)| k.eq_ignore_ascii_case("host")) {
        extra.push_str(&format!("Host: {addr}\r\n"));
    }
    for (k, v) in headers {
        extra.push_str(&format!("{k}: {v}\r\n"));
    }
    write!(
        s,
        "{method} {path} HTTP/1.1\r\n{extra}Connection: close\r\nContent-Type: application/json\r\nContent-Length: {}\r\n\r\n{body}",
        body.len()
    )
    .unwrap();
    // Read the head, then Content-Length bytes (chromium keeps the connection open).
    let mut out = Vec::new();
    let mut buf = [0u8; 65536];
    let split = loop {
        if let Some(p) = out.windows(4).position(|w| w == b"\r\n\r\n") {
            break p;
        }
        let n = s.read(&mut buf).unwrap();
        assert!(n > 0, "connection closed before the response head");
        out.extend_from_slice(&buf[..n]);
    };
    let head = String::from_utf8_lossy(&out[..split]).to_string();
    let status: u16 = head.split(' ').nth(1).unwrap().parse().unwrap();
    let lower = head.to_ascii_lowercase();
    let length = lower
        .lines()
        .find_map(|l| l.strip_prefix("content-length:"))
        .and_then(|v| v.trim().parse::<usize>().ok());
    let mut body = out[split + 4..].to_vec();
    match length {
        Some(len) => {
            while body.len() < len {
                let n = s.read(&mut buf).unwrap();
                assert!(n > 0, "connection closed before the body's end");
                body.extend_from_slice(&buf[..n]);
            }
            body.truncate(len);
        }
        None => {
            s.read_to_end(&mut body).unwrap();
            if lower.contains("transfer-encoding: chunked") {
                body = dechunk(&body);
            }
        }
    }
    (status, body)
}

fn dechunk(mut b: &[u8]) -> Vec<u8> {
    let mut out = Vec::new();
    loop {
        let Some(eol) = b.windows(2).position(|w| w == b"\r\n") else {
            return out;
        };
        let n = usize::from_str_radix(std::str::from_utf8(&b[..eol]).unwrap().trim(), 16).unwrap();
        if n == 0 {
            return out;
        }
        out.extend_from_slice(&b[eol + 2..eol + 2 + n]);
        b = &b[eol + 2 + n + 2..];
    }
}

/// GET returning JSON.
pub fn get_json(addr: SocketAddr, path: &str) -> Value {
    let (st, body) = http(addr, "GET", path, None);
    assert_eq!(st, 200, "{path}: {}", String::from_utf8_lossy(&body));
    serde_json::from_slice(&body).unwrap()
}

/// POST returning (status, JSON).
pub fn post_json(addr: SocketAddr, path: &str, body: Value) -> (u16, Value) {
    let (st, b) = http(addr, "POST", path, Some(&body));
    (st, serde_json::from_slice(&b).unwrap_or(Value::Null))
}

/// The chromium binary, or `None` (then the browser tests are skipped unless
/// `RODTRACK_REQUIRE_BROWSER=1`, which makes them fail).
pub fn chromium() -> Option<PathBuf> {
    let candidates = [
        std::env::var_os("RODTRACK_CHROMIUM").map(PathBuf::from),
        Some(PathBuf::from("/usr/bin/chromium")),
        Some(PathBuf::from("/usr/bin/chromium-browser")),
    ];
    let found = candidates.into_iter().flatten().find(|p| p.is_file());
    if found.is_none() {
        if std::env::var("RODTRACK_REQUIRE_BROWSER").as_deref() == Ok("1") {
            panic!("chromium not found (RODTRACK_REQUIRE_BROWSER=1): install Debian's `chromium` or set RODTRACK_CHROMIUM");
        }
        eprintln!("SKIPPED: chromium not found (apt-get install chromium, or set RODTRACK_CHROMIUM); set RODTRACK_REQUIRE_BROWSER=1 to make this a failure");
    }
    found
}

/// Headless chromium with a DevTools connection to one page.
pub struct Browser {
    child: Child,
    _profile: TempDir,
    ws: tungstenite::WebSocket<TcpStream>,
    next_id: u64,
}

/// A temporary folder removed on drop.
pub struct TempDir(pub PathBuf);
impl TempDir {
    pub fn new(tag: &str) -> TempDir {
        let p = std::env::temp_dir().join(format!(
            "rodtrack-console-{tag}-{}-{}",
            std::process::id(),
            Instant::now().elapsed().as_nanos()
        ));
        let _ = std::fs::remove_dir_all(&p);
        std::fs::create_dir_all(&p).unwrap();
        TempDir(p)
    }
}
impl Drop for TempDir {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

impl Browser {
    /// Starts chromium headless (the flags of shared/RECIPES.md) and attaches to its page.
    pub fn start(exe: &PathBuf) -> Browser {
        let profile = TempDir::new("chromium");
        let child = Command::new(exe)
            .process_group(0)
            .args([
                "--headless",
                "--no-sandbox",
                "--disable-gpu",
                "--disable-background-networking",
                "--disable-component-update",
                "--no-first-run",
                "--remote-debugging-port=0",
                "--window-size=1500,1000",
            ])
            .arg(format!("--user-data-dir={}", profile.0.display()))
            .arg("about:blank")
            .stdout(Stdio::null())
            .stderr(Stdio::null())
            .spawn()
            .unwrap();
        // Chromium writes its port into DevToolsActivePort.
        let port_file = profile.0.join("DevToolsActivePort");
        let t0 = Instant::now();
        let port: u16 = loop {
            if let Ok(s) = std::fs::read_to_string(&port_file) {
                if let Some(p) = s.lines().next().and_then(|l| l.trim().parse().ok()) {
                    break p;
                }
            }
            assert!(
                t0.elapsed() < Duration::from_secs(60),
                "chromium did not start"
            );
            std::thread::sleep(Duration::from_millis(100));
        };
        let dev: SocketAddr = format!("127.0.0.1:{port}").parse().unwrap();
        let ws_url = loop {
            let list = get_json(dev, "/json/list");
            let page = list
                .as_array()
                .unwrap()
                .iter()
                .find(|t| t["type"] == "page")
                .and_then(|t| t["webSocketDebuggerUrl"].as_str().map(str::to_string));
            if let Some(u) = page {
                break u;
            }
            assert!(t0.elapsed() < Duration::from_secs(60), "no page target");
            std::thread::sleep(Duration::from_millis(100));
        };
        let stream = TcpStream::connect(dev).unwrap();
        stream
            .set_read_timeout(Some(Duration::from_secs(60)))
            .unwrap();
        let (ws, _) = tungstenite::client::client(ws_url.as_str(), stream).unwrap();
        let mut b = Browser {
            child,
            _profile: profile,
            ws,
            next_id: 1,
        };
        b.call("Page.enable", json!({}));
        b.call("Runtime.enable", json!({}));
        b.call(
            "Emulation.setDeviceMetricsOverride",
            json!({"width": 1500, "height": 1000, "deviceScaleFactor": 1, "mobile": false}),
        );
        b
    }

    /// Sends one command and waits for its answer (events in between are dropped).
    pub fn call(&mut self, method: &str, params: Value) -> Value {
        let id = self.next_id;
        self.next_id += 1;
        let msg = json!({"id": id, "method": method, "params": params}).to_string();
        self.ws
            .send(tungstenite::Message::Text(msg.into()))
            .unwrap();
        loop {
            let m = self.ws.read().unwrap();
            if let tungstenite::Message::Text(t) = m {
                let v: Value = serde_json::from_str(t.as_str()).unwrap();
                if v["id"] == id {
                    assert!(v.get("error").is_none(), "{method}: {v}");
                    return v["result"].clone();
                }
            }
        }
    }

    /// Evaluates a JavaScript expression in the page and returns its value.
    pub fn eval(&mut self, expr: &str) -> Value {
        let r = self.call(
            "Runtime.evaluate",
            json!({"expression": expr, "returnByValue": true, "awaitPromise": true}),
        );
        assert!(r.get("exceptionDetails").is_none(), "{expr}: {r}");
        r["result"]["value"].clone()
    }

    /// Waits until a JavaScript expression is true.
    pub fn wait_for(&mut self, expr: &str, timeout: Duration) {
        let t0 = Instant::now();
        while self.eval(&format!("!!({expr})")) != json!(true) {
            assert!(t0.elapsed() < timeout, "timed out waiting for {expr}");
            std::thread::sleep(Duration::from_millis(100));
        }
    }

    /// Opens a URL and waits for the page's load event.
    pub fn open(&mut self, url: &str) {
        self.call("Page.navigate", json!({"url": url}));
        self.wait_for(
            "document.readyState === 'complete'",
            Duration::from_secs(30),
        );
    }

    /// A left click at page coordinates.
    pub fn click(&mut self, x: f64, y: f64) {
        for kind in ["mousePressed", "mouseReleased"] {
            self.call(
                "Input.dispatchMouseEvent",
                json!({"type": kind, "x": x, "y": y, "button": "left", "clickCount": 1}),
            );
        }
    }

    /// A PNG screenshot of the viewport.
    pub fn screenshot(&mut self) -> Vec<u8> {
        let r = self.call("Page.captureScreenshot", json!({"format": "png"}));
        base64_decode(r["data"].as_str().unwrap())
    }
}

impl Drop for Browser {
    fn drop(&mut self) {
        // Debian's chromium is a launcher script: end its whole process group.
        let _ = Command::new("kill")
            .args(["-KILL", "--", &format!("-{}", self.child.id())])
            .status();
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// Standard base64 (the screenshot's encoding).
pub fn base64_decode(s: &str) -> Vec<u8> {
    let val = |c: u8| -> Option<u32> {
        Some(match c {
            b'A'..=b'Z' => c - b'A',
            b'a'..=b'z' => c - b'a' + 26,
            b'0'..=b'9' => c - b'0' + 52,
            b'+' => 62,
            b'/' => 63,
            _ => return None,
        } as u32)
    };
    let mut out = Vec::with_capacity(s.len() * 3 / 4);
    let (mut acc, mut bits) = (0u32, 0);
    for c in s.bytes() {
        let Some(v) = val(c) else { continue };
        acc = (acc << 6) | v;
        bits += 6;
        if bits >= 8 {
            bits -= 8;
            out.push((acc >> bits) as u8);
        }
    }
    out
}

/// The simulated table, calibrated as `rodtrack demo` does.
pub struct Demo {
    pub sim: Simulation,
    pub cals: Vec<CameraCalibration>,
    pub setups: Vec<CameraSetup>,
}

impl Demo {
    pub fn new(frames: usize) -> Demo {
        let scene = SceneConfig::default();
        let sc = Scenario::by_name("gameplay", &scene, 7)
            .unwrap()
            .with_frames(frames);
        let mut sim = Simulation::new(scene, default_cameras(), sc, RenderMode::Fast)
            .unwrap()
            .with_seed(7);
        let mut cals = Vec::new();
        let mut setups = Vec::new();
        for c in 0..sim.cameras().len() {
            let inputs = sim.calibration_inputs(c, 7).unwrap();
            let mut buf = vec![0u8; sim.frame_bytes(c).unwrap()];
            let meta = sim.render_reference(c, &mut buf).unwrap();
            let view =
                FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
            // Every rod of the camera together, as `rodtrack calibrate` and the console do.
            cals.push(calibrate_camera_from_view(&inputs, &view, c as u32, 200.0).unwrap());
            setups.push(CameraSetup {
                index: c as u32,
                inputs,
                reference: Some(OwnedFrame::from_view(&view, meta.frame_id, 0.0)),
            });
        }
        Demo { sim, cals, setups }
    }

    /// Each camera's enhanced-mode pipeline, its overlays' constant parts (once per camera, as
    /// `rodtrack demo` and `rodtrack track --console` compute them) and a frame buffer.
    pub fn pipelines(&self) -> (Vec<CameraPipeline>, Vec<CameraOverlays>, Vec<Vec<u8>>) {
        let pipes: Vec<CameraPipeline> = self
            .cals
            .iter()
            .map(|c| CameraPipeline::new(c, Mode::Enhanced).unwrap())
            .collect();
        let geometry = pipes
            .iter()
            .map(|p| CameraOverlays::new(p.rods()))
            .collect();
        let bufs = (0..pipes.len())
            .map(|c| vec![0u8; self.sim.frame_bytes(c).unwrap()])
            .collect();
        (pipes, geometry, bufs)
    }

    /// Renders, tracks and publishes `frames` frame sets (`paced`: no faster than 200 fps).
    /// Returns the times of every step, rendering excluded.
    pub fn run(
        &mut self,
        console: &ConsoleHandle,
        frames: usize,
        paced: bool,
        swap: bool,
    ) -> Timings {
        let mut tm = Timings::default();
        let ncam = self.cals.len();
        let (mut pipes, geometry, mut bufs) = self.pipelines();
        let mut filter = FrameSetFilter::new(Mode::Enhanced, ncam > 1);
        let (mut rows, mut filtered, mut overlays) = (Vec::new(), Vec::new(), Vec::new());
        let (mut track_s, mut publish_s) = (0.0, 0.0);
        let n = self.sim.frame_count();
        let t_start = Instant::now();
        for k in 0..frames {
            let f = k % n;
            let mut metas = Vec::new();
            for (c, buf) in bufs.iter_mut().enumerate() {
                metas.push(self.sim.render(f, c, buf).unwrap());
            }
            if paced {
                let due = Duration::from_secs_f64(k as f64 / 200.0);
                if let Some(w) = due.checked_sub(t_start.elapsed()) {
                    std::thread::sleep(w);
                }
            }
            let ts = k as f64 / 200.0;
            let mut frame_track = 0.0;
            rows.clear();
            for c in 0..ncam {
                let m = metas[c];
                let view = FrameView::new(&bufs[c], m.width, m.height, m.stride, m.format).unwrap();
                let t0 = Instant::now();
                pipes[c]
                    .process(
                        &view,
                        k as u64,
                        rodtrack_core::Timestamp::from_secs_f64(ts),
                        &mut rows,
                    )
                    .unwrap();
                let dt = t0.elapsed().as_secs_f64();
                track_s += dt;
                frame_track += dt;
                // As `rodtrack demo` and `rodtrack track --console` do: overlays and the
                // publish call only when the console wants the frame.
                let t1 = Instant::now();
                let copy = console.wants_frame(c as u32);
                if copy {
                    geometry[c].fill(pipes[c].last_results(), &mut overlays);
                    if swap {
                        console.publish_frame_buffer(
                            c as u32,
                            &mut bufs[c],
                            m.width,
                            m.height,
                            m.stride,
                            m.format,
                            k as u64,
                            ts,
                            &overlays,
                        );
                    } else {
                        console.publish_frame(c as u32, &view, k as u64, ts, &overlays);
                    }
                }
                let dt = t1.elapsed().as_secs_f64();
                publish_s += dt;
                if copy {
                    tm.frame_copy_s.push(dt);
                } else {
                    tm.frame_skip_s.push(dt);
                    tm.frame_skip_camera.push(c);
                }
                // The clock's own cost, in place: an empty interval.
                let te = Instant::now();
                tm.empty_s.push(te.elapsed().as_secs_f64());
            }
            let t0 = Instant::now();
            filtered.clear();
            filter.process(&rows, &mut filtered);
            filtered.retain(|m: &rodtrack_core::Measurement| m.camera == CameraId::Fused);
            let dt = t0.elapsed().as_secs_f64();
            track_s += dt;
            tm.track_s.push(frame_track + dt);
            // Each camera's rows and the fused ones, in one call (gathering them is the demo's
            // doing, not the console's: the pipelines hand their rows over as they are).
            rows.extend_from_slice(&filtered);
            let t1 = Instant::now();
            console.publish_rows(&rows);
            tm.rows_s.push(t1.elapsed().as_secs_f64());
            if k % 50 == 0 {
                console.publish_stats(&PipelineStats {
                    frames: k as u64 + 1,
                    fps: (k + 1) as f64 / t_start.elapsed().as_secs_f64(),
                    frame_time_us: 1e6 * track_s / (k + 1) as f64,
                    dropped_frames: 0,
                    bad_frames: 0,
                });
            }
            publish_s += t1.elapsed().as_secs_f64();
        }
        tm.track_intervals = ncam + 1;
        tm.total_track_s = track_s;
        tm.total_publish_s = publish_s;
        tm
    }
}

/// Times of the demo's steps, s.
#[derive(Debug, Default, Clone)]
pub struct Timings {
    /// Tracking per frame set (every camera, filter and fusion).
    pub track_s: Vec<f64>,
    /// Frames the console wanted: the overlays' computation and the publish call (copy or swap).
    pub frame_copy_s: Vec<f64>,
    /// Frames it did not want: the `wants_frame` check only.
    pub frame_skip_s: Vec<f64>,
    /// The camera of each `frame_skip_s`.
    pub frame_skip_camera: Vec<usize>,
    /// `publish_rows` per frame set (each camera's rows and the fused ones).
    pub rows_s: Vec<f64>,
    /// Empty intervals timed like the others (right after each frame's publish call): the
    /// clock's own cost, which every interval above includes once.
    pub empty_s: Vec<f64>,
    /// Intervals summed into one frame set's `track_s` (each camera's and the filter's).
    pub track_intervals: usize,
    /// Wall-clock totals.
    pub total_track_s: f64,
    /// Wall-clock totals of every publish call.
    pub total_publish_s: f64,
}

/// Median of a sample.
pub fn median(v: &[f64]) -> f64 {
    let mut v = v.to_vec();
    v.sort_by(|a, b| a.total_cmp(b));
    v.get(v.len() / 2).copied().unwrap_or(0.0)
}

impl Timings {
    /// The clock's cost in one timed interval (median empty interval), s.
    pub fn clock_s(&self) -> f64 {
        median(&self.empty_s)
    }

    /// Median of one kind of call with the clock's cost taken out, s.
    pub fn net(&self, v: &[f64]) -> f64 {
        (median(v) - self.clock_s()).max(0.0)
    }

    /// A skipped frame's cost: the mean over the cameras of each camera's median skip, net of
    /// the clock's cost, s. (The cameras' checks differ: the first of a frame set may find
    /// the console's lines out of the cache, the next ones in it; one median over all of them
    /// would pick one kind or the other.)
    pub fn skip_net(&self) -> f64 {
        let cameras = self.frame_skip_camera.iter().max().map_or(0, |c| c + 1);
        let per_camera: Vec<f64> = (0..cameras)
            .map(|c| {
                let v: Vec<f64> = self
                    .frame_skip_s
                    .iter()
                    .zip(&self.frame_skip_camera)
                    .filter(|(_, k)| **k == c)
                    .map(|(s, _)| *s)
                    .collect();
                (median(&v) - self.clock_s()).max(0.0)
            })
            .collect();
        per_camera.iter().sum::<f64>() / per_camera.len().max(1) as f64
    }

    /// Median tracking time per frame set with the clock's cost of its intervals taken out, s.
    pub fn track_net(&self) -> f64 {
        (median(&self.track_s) - self.track_intervals as f64 * self.clock_s()).max(0.0)
    }

    /// The console's share of the tracking time at the camera rate, from the medians of each
    /// kind of call (robust to the preemption a loaded machine adds to single calls; skipped
    /// frames: [`Timings::skip_net`]), each
    /// with the clock's cost ([`Timings::clock_s`]) taken out of every interval, the tracking's
    /// included: (copies/s x copy + (frames/s - copies/s) x skip + sets/s x rows) /
    /// (sets/s x track).
    pub fn share_at(&self, sets_per_s: f64, cameras: f64, copies_per_s: f64) -> f64 {
        let frames_per_s = sets_per_s * cameras;
        let publish = copies_per_s * self.net(&self.frame_copy_s)
            + (frames_per_s - copies_per_s).max(0.0) * self.skip_net()
            + sets_per_s * self.net(&self.rows_s);
        publish / (sets_per_s * self.track_net())
    }
}

/// A screenshot made small enough for the repository: resized to `width` px, colours
/// posterised to 5 bits (the camera images' sensor noise is what makes PNG large), PNG with
/// the best compression.
pub fn shrink_png(png: &[u8], width: u32) -> Vec<u8> {
    use image::ImageEncoder;
    let img = image::load_from_memory_with_format(png, image::ImageFormat::Png)
        .unwrap()
        .to_rgb8();
    let h = (img.height() as u64 * width as u64 / img.width() as u64) as u32;
    let mut small = image::imageops::resize(&img, width, h, image::imageops::FilterType::Triangle);
    for p in small.pixels_mut() {
        for c in p.0.iter_mut() {
            *c = (*c & 0xF8) | (*c >> 5);
        }
    }
    let mut out = Vec::new();
    image::codecs::png::PngEncoder::new_with_quality(
        &mut out,
        image::codecs::png::CompressionType::Best,
        image::codecs::png::FilterType::Adaptive,
    )
    .write_image(&small, width, h, image::ExtendedColorType::Rgb8)
    .unwrap();
    out
}
