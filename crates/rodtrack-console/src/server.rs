//! The HTTP side: the page, the live WebSocket and the calibration API.
//!
//! | route | what |
//! |---|---|
//! | `GET /`, `/app.js`, `/style.css` | the page (embedded, no network) |
//! | `GET /ws` | live data: text messages `{"t":"rows",...}` (each row `[t, camera, rod, position_mm, angle_unwrapped_rad, angle_rad, quality, status, turns_known]`), `{"t":"stats",...}` (the status, with the ball's `events`: `score`, `count`, `last`), `{"t":"ball",...}` (when the ball is tracked: `field_mm`, `frame`, `camera`, `status`, `x_mm`, `y_mm`, `speed_mm_s`, `trail` of the last second, `[x, y]` or `null` where lost); binary frames |
//! | `GET /api/status` | cameras seen, pipeline counters, publish overhead, the ball's score and last events (`events`), the ball's last row and trail (`ball`, as the live view's `ball` message; `null` before the first), remote nodes (`remote`: their statuses, previews, malformed messages, see [`crate::remote`]; `null` when not fed from a network) |
//! | `GET /api/calib` | calibration state: per camera its inputs, frozen frame, outcomes |
//! | `POST /api/calib/{cam}/freeze` | freeze the camera's next frame |
//! | `GET /api/calib/{cam}/frame` | the frozen frame (binary, like the live frames) |
//! | `GET /api/calib/{cam}/inputs` | the camera's edited calibration inputs (JSON) |
//! | `POST /api/calib/{cam}/rods` `{rod, travel_mm?}` | add a rod (marker v1) |
//! | `POST /api/calib/{cam}/rods/{rod}/delete` | remove a rod |
//! | `POST /api/calib/{cam}/rods/{rod}/points` `{x, y}` | add a path point, px |
//! | `PUT /api/calib/{cam}/rods/{rod}/points` `{points}` | replace the path points |
//! | `POST /api/calib/{cam}/rods/{rod}/points/clear` | remove the path points |
//! | `POST /api/calib/{cam}/rods/{rod}/reference` `{position_mm, angle_rad, travel_mm?}` | the rod's known pose in the frozen frame |
//! | `POST /api/calib/{cam}/rods/{rod}/known_pose` `{stop: "left"\|"right"}` | the camera's next frame is the rod's known pose at that end of its travel |
//! | `POST /api/calib/{cam}/rods/{rod}/known_poses/clear` | forget the rod's known poses |
//! | `POST /api/calibrate` | calibrate every rod of every camera with a frozen frame |
//! | `POST /api/save` | write the calibration file (TOML) and the inputs beside it |
//! | `POST /api/reanchor` `{rod, turns, camera?}` | set a rod's turn count in the running session (409 without one) |
//!
//! Every request passes `guard`'s checks first (Host, Origin, session token).
//!
//! A binary frame message is `[u32 LE n][n bytes of JSON header][pixels]`; the header holds
//! `camera, frame_id, timestamp_s, width, height` (full resolution), `pw, ph, channels, factor`
//! (the preview) and `overlays` ([`crate::RodOverlay`]).

use crate::calib::{calibrate_camera, new_rod, save, CalibState, RodOutcome};
use crate::image::{preview, OwnedFrame};
use crate::rows::PlotRow;
use crate::{ConsoleError, RodOverlay, Shared};
use axum::body::Bytes;
use axum::extract::ws::{Message, WebSocket, WebSocketUpgrade};
use axum::extract::{Path, State};
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::routing::{get, post};
use axum::{Json, Router};
use serde::{Deserialize, Serialize};
use serde_json::json;
use std::fmt::Write as _;
use std::sync::atomic::Ordering;
use std::sync::{Arc, Mutex, MutexGuard};
use std::time::{Duration, Instant};

const INDEX_HTML: &str = include_str!("../assets/index.html");
const APP_JS: &str = include_str!("../assets/app.js");
const STYLE_CSS: &str = include_str!("../assets/style.css");

/// Widest live preview sent to the browser, px.
const LIVE_MAX_WIDTH: usize = 720;
/// How often a client is served, ms.
const TICK_MS: u64 = 40;
/// Most rows in one message.
const MAX_ROWS_PER_MESSAGE: usize = 20_000;

#[derive(Clone)]
pub(crate) struct AppState {
    pub(crate) shared: Arc<Shared>,
    stop: tokio::sync::watch::Receiver<bool>,
}

/// Locks a mutex, recovering the data if a thread panicked while holding it.
pub(crate) fn lock<T>(m: &Mutex<T>) -> MutexGuard<'_, T> {
    m.lock().unwrap_or_else(|e| e.into_inner())
}

pub(crate) fn router(
    shared: Arc<Shared>,
    stop: tokio::sync::watch::Receiver<bool>,
    guard: Arc<crate::guard::GuardConfig>,
) -> Router {
    Router::new()
        .route("/", get(index))
        .route("/app.js", get(app_js))
        .route("/style.css", get(style_css))
        .route("/ws", get(ws))
        .route("/api/status", get(status))
        .route("/api/calib", get(calib_state))
        .route("/api/calib/{cam}/freeze", post(freeze))
        .route("/api/calib/{cam}/frame", get(frozen_frame))
        .route("/api/calib/{cam}/inputs", get(inputs))
        .route("/api/calib/{cam}/rods", post(add_rod))
        .route("/api/calib/{cam}/rods/{rod}/delete", post(delete_rod))
        .route(
            "/api/calib/{cam}/rods/{rod}/points",
            post(add_point).put(set_points),
        )
        .route(
            "/api/calib/{cam}/rods/{rod}/points/clear",
            post(clear_points),
        )
        .route("/api/calib/{cam}/rods/{rod}/reference", post(set_reference))
        .route(
            "/api/calib/{cam}/rods/{rod}/known_pose",
            post(crate::poses::capture),
        )
        .route(
            "/api/calib/{cam}/rods/{rod}/known_poses/clear",
            post(crate::poses::clear),
        )
        .route("/api/calibrate", post(calibrate))
        .route("/api/save", post(save_file))
        .route("/api/reanchor", post(crate::control::reanchor))
        .with_state(AppState { shared, stop })
        .layer(axum::middleware::from_fn_with_state(
            guard,
            crate::guard::guard,
        ))
}

/// An API error: 400 with `{"error": message}`.
struct ApiError(ConsoleError);

impl From<ConsoleError> for ApiError {
    fn from(e: ConsoleError) -> Self {
        ApiError(e)
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        (
            StatusCode::BAD_REQUEST,
            Json(json!({ "error": self.0.to_string() })),
        )
            .into_response()
    }
}

type ApiResult<T> = Result<T, ApiError>;

/// The page, with this console's session token in its `rodtrack-token` meta tag.
async fn index(State(st): State<AppState>) -> impl IntoResponse {
    (
        [
            (header::CONTENT_TYPE, "text/html; charset=utf-8"),
            (header::CACHE_CONTROL, "no-store"),
        ],
        INDEX_HTML.replace("__RODTRACK_TOKEN__", &st.shared.token),
    )
}
async fn app_js() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/javascript; charset=utf-8")],
        APP_JS,
    )
}
async fn style_css() -> impl IntoResponse {
    (
        [(header::CONTENT_TYPE, "text/css; charset=utf-8")],
        STYLE_CSS,
    )
}

fn status_json(sh: &Shared) -> serde_json::Value {
    let cameras: Vec<serde_json::Value> = sh
        .cameras
        .iter()
        .enumerate()
        .filter(|(i, _)| sh.counts.seen(*i))
        .map(|(i, _)| json!({ "index": i, "frames": sh.counts.frames(i) }))
        .collect();
    let stats = *lock(&sh.stats);
    json!({
        "cameras": cameras,
        "stats": stats,
        "overhead": sh.overhead(),
        "uptime_s": sh.started.elapsed().as_secs_f64(),
        "clients": sh.clients.load(Ordering::Relaxed),
        "session": lock(&sh.session).is_some(),
        "events": lock(&sh.events).json(),
        "ball": lock(&sh.ball).json(),
        "remote": lock(&sh.remote).json(),
    })
}

async fn status(State(st): State<AppState>) -> Json<serde_json::Value> {
    Json(status_json(&st.shared))
}

// ------------------------------------------------------------------------ calibration API

#[derive(Serialize)]
struct FrozenInfo {
    frame_id: u64,
    timestamp_s: f64,
    width: usize,
    height: usize,
}

pub(crate) fn calib_json(sh: &Shared, cal: &CalibState) -> serde_json::Value {
    let cameras: Vec<serde_json::Value> = cal
        .cameras
        .iter()
        .map(|c| {
            let frozen = c.frozen.as_ref().map(|f| FrozenInfo {
                frame_id: f.frame_id(),
                timestamp_s: f.timestamp_s(),
                width: f.width(),
                height: f.height(),
            });
            let pending = sh.requests.freeze_pending(c.index as usize);
            json!({
                "index": c.index,
                "name": c.inputs.camera_name,
                "inputs": c.inputs,
                "frozen": frozen,
                "freeze_pending": pending,
                "outcomes": c.outcomes,
                "calibrated": c.calibration.is_some(),
                "pose_frames": c.pose_frames.len(),
            })
        })
        .collect();
    let live: Vec<usize> = sh
        .cameras
        .iter()
        .enumerate()
        .filter(|(i, _)| sh.counts.seen(*i))
        .map(|(i, _)| i)
        .collect();
    json!({
        "cameras": cameras,
        "live_cameras": live,
        "out_path": cal.out_path,
        "saved": cal.saved,
        "pending_pose": cal.pending_pose,
    })
}

async fn calib_state(State(st): State<AppState>) -> Json<serde_json::Value> {
    let cal = lock(&st.shared.calib);
    Json(calib_json(&st.shared, &cal))
}

async fn freeze(
    State(st): State<AppState>,
    Path(cam): Path<u32>,
) -> ApiResult<Json<serde_json::Value>> {
    if !st.shared.counts.seen(cam as usize) {
        return Err(ConsoleError::Camera {
            camera: cam,
            reason: "no live frames to freeze".into(),
        }
        .into());
    }
    st.shared.requests.request_freeze(cam as usize);
    Ok(Json(json!({ "freeze_pending": true })))
}

/// `decimation`: full-resolution pixels per pixel of `frame`; `full_size`: the camera's frame
/// size.
fn encode_frame(
    camera: u32,
    frame: &OwnedFrame,
    decimation: usize,
    full_size: (usize, usize),
    max_width: usize,
    overlays: &[RodOverlay],
) -> Option<Vec<u8>> {
    let view = frame.view().ok()?;
    let p = preview(&view, max_width);
    let header = json!({
        "camera": camera,
        "frame_id": frame.frame_id(),
        "timestamp_s": frame.timestamp_s(),
        "width": full_size.0,
        "height": full_size.1,
        "pw": p.width,
        "ph": p.height,
        "channels": p.channels,
        "factor": p.factor * decimation,
        "overlays": overlays,
    })
    .to_string();
    let mut out = Vec::with_capacity(4 + header.len() + p.pixels.len());
    out.extend_from_slice(&(header.len() as u32).to_le_bytes());
    out.extend_from_slice(header.as_bytes());
    out.extend_from_slice(&p.pixels);
    Some(out)
}

async fn frozen_frame(State(st): State<AppState>, Path(cam): Path<u32>) -> ApiResult<Response> {
    let frame = {
        let cal = lock(&st.shared.calib);
        cal.camera(cam).and_then(|c| c.frozen.clone())
    };
    let frame = frame.ok_or(ConsoleError::Camera {
        camera: cam,
        reason: "no frozen frame".into(),
    })?;
    let bytes = tokio::task::spawn_blocking(move || {
        let size = (frame.width(), frame.height());
        encode_frame(cam, &frame, 1, size, usize::MAX, &[])
    })
    .await
    .ok()
    .flatten()
    .ok_or(ConsoleError::Camera {
        camera: cam,
        reason: "the frozen frame cannot be shown".into(),
    })?;
    Ok((
        [(header::CONTENT_TYPE, "application/octet-stream")],
        Bytes::from(bytes),
    )
        .into_response())
}

async fn inputs(
    State(st): State<AppState>,
    Path(cam): Path<u32>,
) -> ApiResult<Json<rodtrack_core::calib::CalibrationInputs>> {
    let cal = lock(&st.shared.calib);
    let c = cal.camera(cam).ok_or(ConsoleError::Camera {
        camera: cam,
        reason: "not in the calibration".into(),
    })?;
    Ok(Json(c.inputs.clone()))
}

#[derive(Deserialize)]
struct AddRod {
    rod: u32,
    #[serde(default)]
    travel_mm: Option<[f64; 2]>,
}

fn check_travel(t: [f64; 2]) -> Result<(), ConsoleError> {
    if t[0].is_finite() && t[1].is_finite() && t[0] <= t[1] {
        Ok(())
    } else {
        Err(ConsoleError::BadRequest {
            field: "travel_mm",
            reason: format!("must be [min, max], got {t:?}"),
        })
    }
}

async fn add_rod(
    State(st): State<AppState>,
    Path(cam): Path<u32>,
    Json(req): Json<AddRod>,
) -> ApiResult<Json<serde_json::Value>> {
    let travel = req.travel_mm.unwrap_or([-100.0, 100.0]);
    check_travel(travel)?;
    let mut cal = lock(&st.shared.calib);
    let c = cal.camera_mut(cam).ok_or(ConsoleError::Camera {
        camera: cam,
        reason: "not in the calibration (freeze a frame first)".into(),
    })?;
    if c.inputs.rods.iter().any(|r| r.rod == req.rod) {
        return Err(ConsoleError::BadRequest {
            field: "rod",
            reason: format!("rod {} exists already", req.rod),
        }
        .into());
    }
    c.inputs.rods.push(new_rod(req.rod, travel));
    c.inputs.rods.sort_by_key(|r| r.rod);
    c.calibration = None;
    Ok(Json(calib_json(&st.shared, &cal)))
}

async fn delete_rod(
    State(st): State<AppState>,
    Path((cam, rod)): Path<(u32, u32)>,
) -> ApiResult<Json<serde_json::Value>> {
    let mut cal = lock(&st.shared.calib);
    cal.rod_mut(cam, rod)?;
    if let Some(c) = cal.camera_mut(cam) {
        c.inputs.rods.retain(|r| r.rod != rod);
        c.outcomes.retain(|o| o.rod != rod);
    }
    Ok(Json(calib_json(&st.shared, &cal)))
}

#[derive(Deserialize)]
struct Point {
    x: f64,
    y: f64,
}

fn check_point(cal: &CalibState, cam: u32, x: f64, y: f64) -> Result<(), ConsoleError> {
    let inside = cal
        .camera(cam)
        .and_then(|c| c.frozen.as_ref())
        .map(|f| (f.width() as f64, f.height() as f64))
        .is_none_or(|(w, h)| x >= 0.0 && y >= 0.0 && x <= w - 1.0 && y <= h - 1.0);
    if x.is_finite() && y.is_finite() && inside {
        Ok(())
    } else {
        Err(ConsoleError::BadRequest {
            field: "point",
            reason: format!("({x}, {y}) is not a point inside the frame"),
        })
    }
}

async fn add_point(
    State(st): State<AppState>,
    Path((cam, rod)): Path<(u32, u32)>,
    Json(p): Json<Point>,
) -> ApiResult<Json<serde_json::Value>> {
    let mut cal = lock(&st.shared.calib);
    check_point(&cal, cam, p.x, p.y)?;
    cal.rod_mut(cam, rod)?.path_points_px.push([p.x, p.y]);
    Ok(Json(calib_json(&st.shared, &cal)))
}

#[derive(Deserialize)]
struct Points {
    points: Vec<[f64; 2]>,
}

async fn set_points(
    State(st): State<AppState>,
    Path((cam, rod)): Path<(u32, u32)>,
    Json(p): Json<Points>,
) -> ApiResult<Json<serde_json::Value>> {
    let mut cal = lock(&st.shared.calib);
    for q in &p.points {
        check_point(&cal, cam, q[0], q[1])?;
    }
    cal.rod_mut(cam, rod)?.path_points_px = p.points;
    Ok(Json(calib_json(&st.shared, &cal)))
}

async fn clear_points(
    State(st): State<AppState>,
    Path((cam, rod)): Path<(u32, u32)>,
) -> ApiResult<Json<serde_json::Value>> {
    let mut cal = lock(&st.shared.calib);
    cal.rod_mut(cam, rod)?.path_points_px.clear();
    Ok(Json(calib_json(&st.shared, &cal)))
}

#[derive(Deserialize)]
struct Reference {
    position_mm: f64,
    angle_rad: f64,
    #[serde(default)]
    travel_mm: Option<[f64; 2]>,
}

async fn set_reference(
    State(st): State<AppState>,
    Path((cam, rod)): Path<(u32, u32)>,
    Json(r): Json<Reference>,
) -> ApiResult<Json<serde_json::Value>> {
    if !(r.position_mm.is_finite() && r.angle_rad.is_finite()) {
        return Err(ConsoleError::BadRequest {
            field: "reference",
            reason: "position_mm and angle_rad must be numbers".into(),
        }
        .into());
    }
    if let Some(t) = r.travel_mm {
        check_travel(t)?;
    }
    let mut cal = lock(&st.shared.calib);
    let inputs = cal.rod_mut(cam, rod)?;
    inputs.reference.position_mm = r.position_mm;
    inputs.reference.angle_rad = r.angle_rad;
    inputs.reference.frame = 0;
    if let Some(t) = r.travel_mm {
        inputs.travel_mm = t;
    }
    Ok(Json(calib_json(&st.shared, &cal)))
}

async fn calibrate(State(st): State<AppState>) -> ApiResult<Json<serde_json::Value>> {
    let cameras: Vec<_> = lock(&st.shared.calib)
        .cameras
        .iter()
        .filter(|c| c.frozen.is_some())
        .cloned()
        .collect();
    if cameras.is_empty() {
        return Err(ConsoleError::BadRequest {
            field: "cameras",
            reason: "no camera has a frozen frame".into(),
        }
        .into());
    }
    let results = tokio::task::spawn_blocking(move || {
        cameras
            .iter()
            .map(|c| (c.index, calibrate_camera(c)))
            .collect::<Vec<_>>()
    })
    .await
    .map_err(|e| ConsoleError::BadRequest {
        field: "calibrate",
        reason: format!("calibration stopped: {e}"),
    })?;
    let mut cal = lock(&st.shared.calib);
    for (index, r) in results {
        let Some(c) = cal.camera_mut(index) else {
            continue;
        };
        match r {
            Ok((outcomes, calibration)) => {
                c.outcomes = outcomes;
                c.calibration = calibration;
            }
            Err(e) => {
                c.outcomes = vec![RodOutcome {
                    rod: u32::MAX,
                    residuals: None,
                    error: Some(e.to_string()),
                }];
                c.calibration = None;
            }
        }
    }
    Ok(Json(calib_json(&st.shared, &cal)))
}

async fn save_file(State(st): State<AppState>) -> ApiResult<Json<serde_json::Value>> {
    let (out, cameras) = {
        let cal = lock(&st.shared.calib);
        (cal.out_path.clone(), cal.cameras.clone())
    };
    let out = out.ok_or(ConsoleError::NoOutputPath)?;
    let saved = tokio::task::spawn_blocking(move || save(&out, &cameras))
        .await
        .map_err(|e| ConsoleError::BadRequest {
            field: "save",
            reason: format!("saving stopped: {e}"),
        })??;
    let mut cal = lock(&st.shared.calib);
    cal.saved = Some(saved.calibration.display().to_string());
    Ok(Json(json!({ "saved": saved })))
}

// ------------------------------------------------------------------------------ live data

async fn ws(State(st): State<AppState>, upgrade: WebSocketUpgrade) -> Response {
    upgrade.on_upgrade(move |socket| client(socket, st))
}

/// Decrements the client count when a connection ends, however it ends.
struct ClientGuard(Arc<Shared>);
impl Drop for ClientGuard {
    fn drop(&mut self) {
        if self.0.clients.fetch_sub(1, Ordering::Relaxed) == 1 {
            self.0.cancel_live_frames();
        }
    }
}

/// Rows from sequence `cursor` on, as one compact JSON message; returns the new cursor. The
/// rows are copied out of the ring (no lock: the tracking side never waits for the console)
/// and formatted after.
fn rows_message(sh: &Shared, cursor: u64, scratch: &mut Vec<PlotRow>) -> (Option<String>, u64) {
    scratch.clear();
    let to = sh.rows.read(cursor, MAX_ROWS_PER_MESSAGE, scratch);
    if scratch.is_empty() {
        return (None, to);
    }
    let mut s = String::with_capacity(scratch.len() * 48 + 32);
    s.push_str("{\"t\":\"rows\",\"rows\":[");
    for (i, m) in scratch.iter().enumerate() {
        push_row(&mut s, m, i > 0);
    }
    s.push_str("]}");
    (Some(s), to)
}

fn push_row(s: &mut String, m: &PlotRow, comma: bool) {
    if comma {
        s.push(',');
    }
    let _ = write!(
        s,
        "[{:.5},{},{},{:.3},{:.4},{:.4},{:.2},{},{}]",
        m.timestamp_s,
        m.camera,
        m.rod,
        m.position_mm,
        m.angle_unwrapped_rad,
        m.angle_rad,
        m.quality,
        m.status,
        u8::from(m.turns_known)
    );
}

async fn client(mut socket: WebSocket, st: AppState) {
    let sh = st.shared.clone();
    sh.clients.fetch_add(1, Ordering::Relaxed);
    let _guard = ClientGuard(sh.clone());
    let mut stop = st.stop.clone();
    let mut tick = tokio::time::interval(Duration::from_millis(TICK_MS));
    tick.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let mut cursor = 0u64;
    let mut scratch = Vec::new();
    let mut sent_seq = vec![0u64; sh.cameras.len()];
    let mut last_stats = Instant::now() - Duration::from_secs(1);
    let mut ball_sent = 0u64;
    loop {
        tokio::select! {
            _ = tick.tick() => {}
            _ = stop.wait_for(|s| *s) => break,
            msg = socket.recv() => match msg {
                None | Some(Err(_)) | Some(Ok(Message::Close(_))) => break,
                _ => continue,
            },
        }
        // The tracking side copies a live frame only when asked (a few times per second).
        sh.request_live_frames();
        let (rows, next) = rows_message(&sh, cursor, &mut scratch);
        cursor = next;
        if let Some(text) = rows {
            if socket.send(Message::Text(text.into())).await.is_err() {
                break;
            }
        }
        // The ball, when a frame set came since the last message.
        let ball = {
            let board = lock(&sh.ball);
            (board.count() != ball_sent).then(|| (board.count(), board.json()))
        };
        if let Some((count, Some(v))) = ball {
            ball_sent = count;
            if socket
                .send(Message::Text(v.to_string().into()))
                .await
                .is_err()
            {
                break;
            }
        }
        if last_stats.elapsed() >= Duration::from_millis(250) {
            last_stats = Instant::now();
            let mut v = status_json(&sh);
            v["t"] = json!("stats");
            if socket
                .send(Message::Text(v.to_string().into()))
                .await
                .is_err()
            {
                break;
            }
        }
        for (cam, slot) in sh.cameras.iter().enumerate() {
            if !sh.counts.seen(cam) {
                continue;
            }
            let msg = {
                let mut live = lock(&slot.live);
                if live.seq == 0 || live.seq == sent_seq[cam] {
                    None
                } else {
                    let seq = live.seq;
                    let cached = live
                        .encoded
                        .as_ref()
                        .filter(|(s, _)| *s == seq)
                        .map(|(_, b)| b.clone());
                    let bytes = match cached {
                        Some(b) => Some(b),
                        None => {
                            let enc = encode_frame(
                                cam as u32,
                                &live.raw,
                                live.decimation.max(1),
                                live.full_size,
                                LIVE_MAX_WIDTH,
                                &live.overlays,
                            )
                            .map(Bytes::from);
                            if let Some(b) = &enc {
                                live.encoded = Some((seq, b.clone()));
                            }
                            enc
                        }
                    };
                    sent_seq[cam] = seq;
                    bytes
                }
            };
            if let Some(b) = msg {
                if socket.send(Message::Binary(b)).await.is_err() {
                    return;
                }
            }
        }
    }
}
