//! A frame source, a tracker and a sink for testing the runtime pipeline, shared by its unit
//! tests (`src/runtime/tests.rs`) and the integration tests (`tests/runtime.rs`).

use rodtrack_core::{CameraId, Measurement, PixelFormat, Status};
use rodtrack_io::runtime::ProcessFn;
use rodtrack_io::{FrameBuffer, FrameSource, IoError, MeasurementSink, SourceInfo, Timestamp};
use std::collections::HashSet;
use std::time::Duration;

/// Generates 8x6 mono8 frames filled with `frame_id % 256`, 5 ms apart; bad frames, delays and
/// a clock offset on demand.
pub struct Fake {
    pub ids: Box<dyn Iterator<Item = u64> + Send>,
    /// Sleep this long before delivering each frame.
    pub delay: Duration,
    pub bad: HashSet<u64>,
    /// Added to `id * 5 ms` for the timestamp.
    pub ts_offset_ns: u64,
    /// Sleep this long before delivering frame `.0`.
    pub stall: Option<(u64, Duration)>,
    /// Bad frames do not report their id.
    pub hide_bad_ids: bool,
}

impl Fake {
    pub fn new(ids: impl Iterator<Item = u64> + Send + 'static) -> Self {
        Fake {
            ids: Box::new(ids),
            delay: Duration::ZERO,
            bad: HashSet::new(),
            ts_offset_ns: 0,
            stall: None,
            hide_bad_ids: false,
        }
    }
}

impl FrameSource for Fake {
    fn info(&self) -> SourceInfo {
        SourceInfo {
            name: "fake".into(),
            width: 8,
            height: 6,
            format: PixelFormat::Mono8,
            fps: Some(200.0),
            frame_count: None,
            live: true,
        }
    }
    fn next_frame(&mut self, buf: &mut FrameBuffer) -> Result<Option<()>, IoError> {
        let Some(id) = self.ids.next() else {
            return Ok(None);
        };
        if let Some((at, d)) = self.stall {
            if at == id {
                std::thread::sleep(d);
            }
        }
        std::thread::sleep(self.delay);
        if self.bad.contains(&id) && self.hide_bad_ids {
            return Err(IoError::Decode {
                path: "stream".into(),
                reason: format!("lost frame {id}"),
            });
        }
        buf.meta.frame_id = id;
        buf.meta.timestamp_ns = Timestamp(id * 5_000_000 + self.ts_offset_ns);
        if self.bad.contains(&id) {
            return Err(IoError::Decode {
                path: format!("fake{id}.png").into(),
                reason: "simulated".into(),
            });
        }
        buf.reshape_packed(8, 6, PixelFormat::Mono8);
        buf.data.fill((id % 256) as u8);
        Ok(Some(()))
    }
}

/// Two rows per frame: rods 0 and 1 with the pixel value plus the rod id as position, quality 1;
/// one `bad_frame` row for a bad frame. Sleeps `work` per frame.
pub fn tracker(work: Duration) -> ProcessFn {
    Box::new(move |meta, view, out| {
        std::thread::sleep(work);
        let ts = meta.timestamp_ns;
        let cam = CameraId::Camera(meta.camera);
        match view {
            Ok(v) => {
                for rod in 0..2 {
                    let mut m = Measurement::empty(meta.frame_id, ts, cam, rod, Status::Ok);
                    m.position_mm = f64::from(v.luma_node(3, 3)) + f64::from(rod);
                    m.quality = 1.0;
                    out.push(m);
                }
            }
            Err(_) => out.push(Measurement::empty(
                meta.frame_id,
                ts,
                cam,
                0,
                Status::BadFrame,
            )),
        }
    })
}

/// Keeps each `write` call's rows.
#[derive(Default)]
pub struct Writes(pub Vec<Vec<Measurement>>);

impl MeasurementSink for Writes {
    fn write(&mut self, rows: &[Measurement]) -> Result<(), IoError> {
        self.0.push(rows.to_vec());
        Ok(())
    }
    fn flush(&mut self) -> Result<(), IoError> {
        Ok(())
    }
}
