//! The fusion node's status message (`rodtrack/<table>/fused/status`, once a second).

use super::Watch;
use rodtrack_io::runtime::PipelineCounters;
use std::sync::atomic::Ordering;

/// The fusion node's status message.
pub(super) fn status_json(table: &str, w: &Watch, c: &PipelineCounters) -> String {
    let cameras: Vec<serde_json::Value> = w
        .cameras
        .iter()
        .enumerate()
        .map(|(pos, cam)| {
            serde_json::json!({
                "index": cam.index,
                "name": cam.name,
                "state": cam.state().name(),
                "frame": cam.last_frame.load(Ordering::Relaxed),
                "losses": cam.losses.load(Ordering::Relaxed),
                "returns": cam.returns.load(Ordering::Relaxed),
                "frames_missed": cam.frames_missed.load(Ordering::Relaxed),
                "refused": cam.refused.load(Ordering::Relaxed),
                "missing_in_sets": c.cameras.get(pos).map_or(0, |x| x.missing_in_sets.load(Ordering::Relaxed)),
            })
        })
        .collect();
    serde_json::json!({
        "version": crate::layout::VERSION,
        "table": table,
        "sets_complete": c.sets_complete.load(Ordering::Relaxed),
        "sets_incomplete": c.sets_incomplete.load(Ordering::Relaxed),
        "rows_written": c.rows_written.load(Ordering::Relaxed),
        "uptime_s": w.started.elapsed().as_secs_f64(),
        "cameras": cameras,
    })
    .to_string()
}
