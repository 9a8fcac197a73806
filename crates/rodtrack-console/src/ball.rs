//! The ball on the page: its last position in the table frame, its speed and status, and its
//! trail, published by the tracking side's ball sink ([`crate::ConsoleHandle::publish_ball`],
//! one frame set's rows per call) and sent to the live view as `{"t":"ball",...}` messages when
//! a new frame set came (at most once per tick).
//!
//! One call per frame set on the ball writer's thread (not a camera's): a plain lock, held by
//! the console only to copy the trail. No allocation per call: the trail is a ring.

use rodtrack_core::ball::{BallRow, BallStatus};
use rodtrack_core::CameraId;

/// Frame sets kept in the trail (1 s at 200 frame sets/s).
pub(crate) const TRAIL_ROWS: usize = 200;
/// Most trail points sent per message (the trail is thinned evenly to this).
pub(crate) const TRAIL_POINTS: usize = 50;

/// The ball's last row and its trail.
#[derive(Debug, Clone)]
pub(crate) struct BallBoard {
    /// The field, mm (length along `x`, width along `y`), for the page's drawing.
    field_mm: [f64; 2],
    /// Frame sets published so far.
    count: u64,
    /// The row shown: the fused one, else the first camera's with a position.
    last: Option<BallRow>,
    /// Positions of the last [`TRAIL_ROWS`] frame sets (`None` where the ball was lost), a ring
    /// at `count % TRAIL_ROWS`.
    trail: [Option<[f64; 2]>; TRAIL_ROWS],
}

impl Default for BallBoard {
    fn default() -> Self {
        BallBoard {
            // The reference table's field (SPEC section 9); the CLI sets the configured one.
            field_mm: [1200.0, 680.0],
            count: 0,
            last: None,
            trail: [None; TRAIL_ROWS],
        }
    }
}

/// The row a frame set shows: the fused row when there is one (several cameras), else the
/// first camera row that is `ok`, else the first `predicted` one, else the first row.
fn shown(rows: &[BallRow]) -> Option<BallRow> {
    let fused = rows.iter().find(|r| r.camera == CameraId::Fused);
    fused
        .or_else(|| rows.iter().find(|r| r.status == BallStatus::Ok))
        .or_else(|| rows.iter().find(|r| r.status == BallStatus::Predicted))
        .or_else(|| rows.first())
        .copied()
}

impl BallBoard {
    /// Sets the field's size (mm); ignored unless both are finite and positive.
    pub(crate) fn set_field(&mut self, length_mm: f64, width_mm: f64) {
        if length_mm.is_finite() && width_mm.is_finite() && length_mm > 0.0 && width_mm > 0.0 {
            self.field_mm = [length_mm, width_mm];
        }
    }

    /// Takes the rows of one frame set (every camera's and the fused one).
    pub(crate) fn push(&mut self, rows: &[BallRow]) {
        let Some(row) = shown(rows).map(BallRow::sanitized) else {
            return;
        };
        let at = matches!(row.status, BallStatus::Ok | BallStatus::Predicted)
            .then_some([row.x_mm, row.y_mm]);
        self.trail[(self.count % TRAIL_ROWS as u64) as usize] = at;
        self.count += 1;
        self.last = Some(row);
    }

    /// Frame sets published so far.
    pub(crate) fn count(&self) -> u64 {
        self.count
    }

    /// `{"t":"ball","field_mm":[l,w],"frame":f,"camera":c,"status":s,"x_mm","y_mm",
    /// "speed_mm_s","trail":[[x,y] or null, ...]}`: the trail oldest first, thinned evenly to at
    /// most [`TRAIL_POINTS`] points (`null` where the ball was lost, a break in the line);
    /// `None` before the first row.
    pub(crate) fn json(&self) -> Option<serde_json::Value> {
        let r = self.last?;
        let n = self.count.min(TRAIL_ROWS as u64) as usize;
        let step = n.div_ceil(TRAIL_POINTS).max(1);
        let oldest = self.count - n as u64;
        // From the newest backwards so the newest point is always in, then oldest first.
        let mut trail: Vec<serde_json::Value> = (0..n)
            .rev()
            .step_by(step)
            .map(|k| {
                let i = ((oldest + k as u64) % TRAIL_ROWS as u64) as usize;
                self.trail[i].map_or(serde_json::Value::Null, |p| serde_json::json!(p))
            })
            .collect();
        trail.reverse();
        let camera = match r.camera {
            CameraId::Camera(c) => serde_json::json!(c),
            CameraId::Fused => serde_json::json!("fused"),
        };
        Some(serde_json::json!({
            "t": "ball",
            "field_mm": self.field_mm,
            "frame": r.frame,
            "camera": camera,
            "status": r.status,
            "x_mm": r.x_mm,
            "y_mm": r.y_mm,
            "speed_mm_s": r.vx_mm_s.hypot(r.vy_mm_s),
            "trail": trail,
        }))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use rodtrack_core::Timestamp;

    fn row(frame: u64, camera: CameraId, status: BallStatus, x_mm: f64) -> BallRow {
        BallRow {
            frame,
            timestamp_ns: Timestamp(frame * 5_000_000),
            camera,
            x_mm,
            y_mm: 10.0,
            vx_mm_s: 300.0,
            vy_mm_s: 400.0,
            quality: 0.9,
            status,
        }
    }

    /// The fused row is shown over the cameras'; a lost frame set breaks the trail; the trail
    /// keeps the last 200 frame sets, thinned to 50 points, the newest last; the speed is the
    /// velocity's length.
    #[test]
    fn the_board_shows_the_fused_row_and_a_thinned_trail() {
        let mut b = BallBoard::default();
        assert!(b.json().is_none());
        b.push(&[
            row(0, CameraId::Camera(0), BallStatus::Ok, 1.0),
            row(0, CameraId::Fused, BallStatus::Ok, 2.0),
        ]);
        let j = b.json().unwrap();
        assert_eq!(
            (j["camera"].as_str(), j["x_mm"].as_f64()),
            (Some("fused"), Some(2.0))
        );
        assert_eq!(j["speed_mm_s"].as_f64(), Some(500.0));
        b.push(&[row(1, CameraId::Camera(0), BallStatus::Lost, 0.0)]);
        let j = b.json().unwrap();
        assert_eq!(j["trail"], serde_json::json!([[2.0, 10.0], null]));
        for f in 2..1000u64 {
            b.push(&[row(f, CameraId::Camera(1), BallStatus::Ok, f as f64)]);
        }
        let j = b.json().unwrap();
        let trail = j["trail"].as_array().unwrap();
        assert_eq!(trail.len(), TRAIL_POINTS);
        assert_eq!(trail.last().unwrap()[0].as_f64(), Some(999.0));
        assert_eq!(trail[0][0].as_f64(), Some(803.0));
        assert_eq!(j["camera"], 1);
        assert_eq!(b.count(), 1000);
    }
}
