//! Known poses on the calibration page: "push rod k to its left stop, click Capture". The
//! capture freezes the camera's next frame as that pose's frame (not the reference frame); the
//! rod's `known_poses` then name it with the stop's position from the rod's travel limits, and
//! calibration fits the scale along the travel to it (see [`crate::calib`]).

use crate::calib::{PoseCapture, Stop};
use crate::server::{calib_json, lock, AppState};
use crate::ConsoleError;
use axum::body::Bytes;
use axum::extract::{Path, State};
use axum::http::StatusCode;
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::{json, Value};

fn bad(field: &str, reason: String) -> Response {
    (
        StatusCode::BAD_REQUEST,
        Json(json!({ "error": format!("{field}: {reason}") })),
    )
        .into_response()
}

/// The request `{stop: "left" | "right"}`.
pub(crate) fn parse_stop(body: &[u8]) -> Result<Stop, String> {
    let v: Value = serde_json::from_slice(body)
        .map_err(|e| format!("body: expected JSON {{\"stop\": \"left\"}}: {e}"))?;
    match v.get("stop") {
        None | Some(Value::Null) => Err("stop: missing (\"left\" or \"right\")".into()),
        Some(s) => serde_json::from_value(s.clone())
            .map_err(|_| format!("stop: expected \"left\" or \"right\", got {s}")),
    }
}

/// `POST /api/calib/{cam}/rods/{rod}/known_pose` `{stop}`: the camera's next frame is rod
/// `rod`'s known pose at that stop.
pub(crate) async fn capture(
    State(st): State<AppState>,
    Path((cam, rod)): Path<(u32, u32)>,
    body: Bytes,
) -> Response {
    let stop = match parse_stop(&body) {
        Ok(s) => s,
        Err(e) => return (StatusCode::BAD_REQUEST, Json(json!({ "error": e }))).into_response(),
    };
    if !st.shared.counts.seen(cam as usize) {
        return bad("camera", format!("camera {cam}: no live frames to capture"));
    }
    let mut cal = lock(&st.shared.calib);
    let exists = cal
        .camera(cam)
        .is_some_and(|c| c.inputs.rods.iter().any(|r| r.rod == rod));
    if !exists {
        return bad(
            "rod",
            ConsoleError::NoSuchRod { camera: cam, rod }.to_string(),
        );
    }
    cal.pending_pose = Some(PoseCapture {
        camera: cam,
        rod,
        stop,
    });
    st.shared.requests.request_freeze(cam as usize);
    Json(calib_json(&st.shared, &cal)).into_response()
}

/// `POST /api/calib/{cam}/rods/{rod}/known_poses/clear`: forgets the rod's known poses.
pub(crate) async fn clear(
    State(st): State<AppState>,
    Path((cam, rod)): Path<(u32, u32)>,
) -> Response {
    let mut cal = lock(&st.shared.calib);
    match cal.rod_mut(cam, rod) {
        Ok(r) => r.known_poses.clear(),
        Err(e) => return bad("rod", e.to_string()),
    }
    Json(calib_json(&st.shared, &cal)).into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_stop_is_named_and_checked() {
        assert_eq!(parse_stop(br#"{"stop": "left"}"#), Ok(Stop::Left));
        assert_eq!(parse_stop(br#"{"stop": "right"}"#), Ok(Stop::Right));
        let err = |b: &[u8]| parse_stop(b).err().unwrap_or_default();
        assert!(err(br#"{"stop": "up"}"#).starts_with("stop: expected"));
        assert!(err(br#"{}"#).starts_with("stop: missing"));
        assert!(err(b"x").starts_with("body:"));
    }
}
