//! Remote nodes on the page: the statuses of the nodes of a camera network (a console fed from
//! the network, `rodtrack console --subscribe zenoh`), the previews received and the messages
//! that could not be used. Sent with the status (`/api/status`, the live view's `stats`
//! messages: key `remote`, `null` until something came).
//!
//! Statuses come about once a second per node, off any tracking thread: a plain lock, held by
//! the console only to format them. A node whose last status is older than
//! [`SILENT_AFTER`] is shown as silent.

use std::collections::BTreeMap;
use std::time::{Duration, Instant};

/// A node whose last status is older than this is silent (its statuses come once a second).
pub const SILENT_AFTER: Duration = Duration::from_secs(3);
/// Malformed messages whose text is kept (the first ones).
const KEPT_ERRORS: usize = 5;

#[derive(Debug, Clone)]
struct NodeEntry {
    status: serde_json::Value,
    received: Instant,
    statuses: u64,
}

#[derive(Debug, Clone, Copy)]
struct PreviewEntry {
    frame_id: u64,
    width_px: usize,
    height_px: usize,
    channels: usize,
    source_px: (usize, usize),
    received: Instant,
    count: u64,
}

/// The remote nodes' board.
#[derive(Debug, Default)]
pub(crate) struct RemoteBoard {
    used: bool,
    nodes: BTreeMap<String, NodeEntry>,
    previews: BTreeMap<u32, PreviewEntry>,
    malformed: u64,
    first_errors: Vec<String>,
}

impl RemoteBoard {
    pub(crate) fn status(&mut self, node: &str, status: serde_json::Value) {
        self.used = true;
        let e = self
            .nodes
            .entry(node.to_string())
            .or_insert_with(|| NodeEntry {
                status: serde_json::Value::Null,
                received: Instant::now(),
                statuses: 0,
            });
        e.status = status;
        e.received = Instant::now();
        e.statuses += 1;
    }

    pub(crate) fn preview(
        &mut self,
        camera: u32,
        frame_id: u64,
        size_px: (usize, usize),
        channels: usize,
        source_px: (usize, usize),
    ) {
        self.used = true;
        let count = self.previews.get(&camera).map_or(0, |p| p.count) + 1;
        self.previews.insert(
            camera,
            PreviewEntry {
                frame_id,
                width_px: size_px.0,
                height_px: size_px.1,
                channels,
                source_px,
                received: Instant::now(),
                count,
            },
        );
    }

    pub(crate) fn malformed(&mut self, key: &str, error: &str) {
        self.used = true;
        self.malformed += 1;
        if self.first_errors.len() < KEPT_ERRORS {
            self.first_errors.push(format!("{key}: {error}"));
        }
    }

    /// `{"nodes": [{"node", "silent", "age_s", "statuses", "status"}], "previews": [{"camera",
    /// "frame_id", "width", "height", "channels", "source_width", "source_height", "age_s",
    /// "count"}], "malformed": n, "first_errors": [..]}`, or `null` when nothing came.
    pub(crate) fn json(&self) -> serde_json::Value {
        if !self.used {
            return serde_json::Value::Null;
        }
        let nodes: Vec<serde_json::Value> = self
            .nodes
            .iter()
            .map(|(node, e)| {
                let age = e.received.elapsed();
                serde_json::json!({
                    "node": node,
                    "silent": age > SILENT_AFTER,
                    "age_s": age.as_secs_f64(),
                    "statuses": e.statuses,
                    "status": e.status,
                })
            })
            .collect();
        let previews: Vec<serde_json::Value> = self
            .previews
            .iter()
            .map(|(camera, p)| {
                serde_json::json!({
                    "camera": camera,
                    "frame_id": p.frame_id,
                    "width": p.width_px,
                    "height": p.height_px,
                    "channels": p.channels,
                    "source_width": p.source_px.0,
                    "source_height": p.source_px.1,
                    "age_s": p.received.elapsed().as_secs_f64(),
                    "count": p.count,
                })
            })
            .collect();
        serde_json::json!({
            "nodes": nodes,
            "previews": previews,
            "malformed": self.malformed,
            "first_errors": self.first_errors,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_board_shows_nodes_previews_and_errors() {
        let mut b = RemoteBoard::default();
        assert!(b.json().is_null());
        b.status("cam/cam0", serde_json::json!({"state": "running"}));
        b.status("cam/cam0", serde_json::json!({"state": "ended"}));
        b.preview(1, 9, (360, 270), 3, (1440, 1080));
        for i in 0..7 {
            b.malformed("rodtrack/t/fused/rows", &format!("bad {i}"));
        }
        let v = b.json();
        assert_eq!(v["nodes"][0]["node"], "cam/cam0");
        assert_eq!(v["nodes"][0]["statuses"], 2);
        assert_eq!(v["nodes"][0]["status"]["state"], "ended");
        assert_eq!(v["nodes"][0]["silent"], false);
        assert_eq!(v["previews"][0]["width"], 360);
        assert_eq!(v["previews"][0]["source_height"], 1080);
        assert_eq!(v["malformed"], 7);
        assert_eq!(
            v["first_errors"].as_array().map(Vec::len),
            Some(KEPT_ERRORS)
        );
        assert_eq!(v["first_errors"][0], "rodtrack/t/fused/rows: bad 0");
        if let Some(e) = b.nodes.get_mut("cam/cam0") {
            e.received -= SILENT_AFTER + Duration::from_millis(10);
        }
        assert_eq!(b.json()["nodes"][0]["silent"], true);
    }
}
