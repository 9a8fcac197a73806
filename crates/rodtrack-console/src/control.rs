//! Commands from the page to the running tracking session: re-anchoring a rod's turn count
//! (`POST /api/reanchor`).
//!
//! The console does not run the session; whoever does attaches it with
//! [`crate::ConsoleHandle::attach_session`] (an implementation of [`SessionCommands`], e.g. over
//! `rodtrack_sdk::SessionControl`). The handler validates the request, names the field that
//! is wrong, and hands the command over; the session applies it on its next frame.

use crate::server::AppState;
use axum::body::Bytes;
use axum::extract::State;
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::{json, Value};
use std::sync::Arc;

/// What the console may ask of a running tracking session.
pub trait SessionCommands: Send + Sync + std::fmt::Debug {
    /// Sets rod `rod`'s turn count to `turns` from the next frame on (`angle_unwrapped_rad =
    /// 2 pi turns + angle_rad`, `turns_known` true), in camera `camera`'s filter or, with
    /// `None`, in every camera's and the fused rows'. An error says what is wrong (an unknown
    /// rod or camera).
    fn reanchor(&self, camera: Option<u32>, rod: u32, turns: i64) -> Result<(), String>;
}

/// The attached session, if any (the console's side only: the tracking side never looks).
pub(crate) type Attached = Option<Arc<dyn SessionCommands>>;

fn error(code: StatusCode, message: String) -> Response {
    (code, Json(json!({ "error": message }))).into_response()
}

/// A field of `body` as a whole number within `lo..=hi`; `Ok(None)` when absent or null.
fn whole(body: &Value, field: &str, lo: i64, hi: i64, what: &str) -> Result<Option<i64>, String> {
    let v = match body.get(field) {
        None | Some(Value::Null) => return Ok(None),
        Some(v) => v,
    };
    let n = match v {
        Value::Number(n) => n.as_i64().or_else(|| {
            n.as_f64()
                .filter(|f| f.fract() == 0.0 && f.abs() < 9e15)
                .map(|f| f as i64)
        }),
        _ => None,
    };
    match n {
        Some(n) if (lo..=hi).contains(&n) => Ok(Some(n)),
        _ => Err(format!("{field}: expected {what}, got {v}")),
    }
}

/// The request `{rod, turns, camera?}`: (camera, rod, turns), or the message naming the field.
pub(crate) fn parse_reanchor(body: &[u8]) -> Result<(Option<u32>, u32, i64), String> {
    let v: Value = serde_json::from_slice(body)
        .map_err(|e| format!("body: expected JSON {{\"rod\": ID, \"turns\": N}}: {e}"))?;
    if !v.is_object() {
        return Err(format!(
            "body: expected a JSON object {{\"rod\": ID, \"turns\": N}}, got {v}"
        ));
    }
    let rod = whole(
        &v,
        "rod",
        0,
        u32::MAX as i64,
        "a rod id (a whole number >= 0)",
    )?
    .ok_or("rod: missing (the rod whose turn count to set)")?;
    let turns = whole(
        &v,
        "turns",
        -1_000_000_000,
        1_000_000_000,
        "a whole number of turns",
    )?
    .ok_or("turns: missing (the rod's whole turn, e.g. 0)")?;
    let camera = whole(&v, "camera", 0, u32::MAX as i64, "a camera index or null")?;
    Ok((camera.map(|c| c as u32), rod as u32, turns))
}

/// `POST /api/reanchor` `{rod, turns, camera?}`.
pub(crate) async fn reanchor(State(st): State<AppState>, body: Bytes) -> Response {
    let (camera, rod, turns) = match parse_reanchor(&body) {
        Ok(r) => r,
        Err(e) => return error(StatusCode::BAD_REQUEST, e),
    };
    let session = crate::server::lock(&st.shared.session).clone();
    let Some(session) = session else {
        return error(
            StatusCode::CONFLICT,
            "no tracking session is attached to this console: re-anchoring needs a running \
             session (`rodtrack track --console ADDR`)"
                .into(),
        );
    };
    match session.reanchor(camera, rod, turns) {
        Ok(()) => Json(json!({ "ok": true, "camera": camera, "rod": rod, "turns": turns }))
            .into_response(),
        Err(e) => error(StatusCode::BAD_REQUEST, e),
    }
}

#[cfg(test)]
mod tests {
    use super::parse_reanchor;

    #[test]
    fn requests_are_checked_field_by_field() {
        assert_eq!(
            parse_reanchor(br#"{"rod": 3, "turns": -2}"#),
            Ok((None, 3, -2))
        );
        assert_eq!(
            parse_reanchor(br#"{"rod": 3, "turns": 4.0, "camera": 1}"#),
            Ok((Some(1), 3, 4))
        );
        let err = |b: &[u8]| parse_reanchor(b).err().unwrap_or_default();
        assert!(err(br#"{"rod": 3, "turns": 1.5}"#).starts_with("turns:"));
        assert!(err(br#"{"rod": 3, "turns": "2"}"#).starts_with("turns:"));
        assert!(err(br#"{"rod": 3}"#).starts_with("turns: missing"));
        assert!(err(br#"{"turns": 3}"#).starts_with("rod: missing"));
        assert!(err(br#"{"rod": -1, "turns": 3}"#).starts_with("rod:"));
        assert!(err(br#"{"rod": 1, "turns": 3, "camera": "a"}"#).starts_with("camera:"));
        assert!(err(br#"{"rod": 1, "turns": 1e300}"#).starts_with("turns:"));
        assert!(err(b"[1, 2]").starts_with("body:"));
        assert!(err(b"rod=1").starts_with("body:"));
    }
}
