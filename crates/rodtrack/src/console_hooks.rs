//! The web console fed by a session's hooks: a camera's frame, with the overlays of its rods,
//! when the console asks for one; nothing to do on the other frames (two atomic loads).

use rodtrack_console::{CameraOverlays, ConsoleHandle, RodOverlay};
use rodtrack_core::{CameraPipeline, Measurement};
use rodtrack_io::{FrameBuffer, FrameMeta};
use rodtrack_sdk::{Hooks, Progress, SessionCamera, SessionControl};
use std::sync::{Arc, Mutex};

/// The console's commands to a running session (its "Re-anchor" control).
#[derive(Debug)]
pub struct SessionCommands(pub SessionControl);

impl rodtrack_console::SessionCommands for SessionCommands {
    fn reanchor(&self, camera: Option<u32>, rod: u32, turns: i64) -> Result<(), String> {
        self.0
            .reanchor(camera, rod, turns)
            .map_err(|e| e.to_string())
    }
}

/// A live frame's overlays between a camera's tracker and its frame hook: made for the frame
/// `frame_id` (None when no frame waits for the hook).
#[derive(Default)]
struct LiveOverlays {
    frame_id: Option<u64>,
    overlays: Vec<RodOverlay>,
}

/// One camera's part.
struct Camera {
    index: u32,
    /// The overlays' constant parts (the rods' lines), made once: a live frame then only
    /// places the markers.
    geometry: CameraOverlays,
    live: Mutex<LiveOverlays>,
}

/// Feeds the console from a session (see [`crate::track::CliHooks`]).
pub struct ConsoleHooks {
    console: Arc<ConsoleHandle>,
    cameras: Vec<Camera>,
}

impl ConsoleHooks {
    /// Hooks for the session's `cameras`, showing them in `console`.
    pub fn new(console: Arc<ConsoleHandle>, cameras: &[SessionCamera]) -> ConsoleHooks {
        ConsoleHooks {
            console,
            cameras: cameras
                .iter()
                .map(|c| Camera {
                    index: c.pipe.index(),
                    geometry: CameraOverlays::new(c.pipe.rods()),
                    live: Mutex::new(LiveOverlays::default()),
                })
                .collect(),
        }
    }

    /// Shows a session's counters in the console's status line.
    pub fn publish_progress(&self, p: &rodtrack_sdk::Progress) {
        let secs = p.elapsed.as_secs_f64().max(1e-9);
        self.console
            .publish_stats(&rodtrack_console::PipelineStats {
                frames: p.sets,
                fps: p.sets as f64 / secs,
                frame_time_us: p.tracker_time.as_secs_f64() * 1e6 / p.measured.max(1) as f64
                    * p.cameras.max(1) as f64,
                dropped_frames: p.dropped,
                bad_frames: p.bad,
            });
    }

    fn camera(&self, index: u32) -> Option<&Camera> {
        self.cameras.iter().find(|c| c.index == index)
    }

    /// After the tracker: the overlays, when the console asks for this camera's frame.
    pub fn measured(
        &self,
        camera: u32,
        meta: &FrameMeta,
        _rows: &[Measurement],
        pipe: &CameraPipeline,
    ) {
        if !self.console.wants_frame(camera) {
            return;
        }
        let Some(cam) = self.camera(camera) else {
            return;
        };
        if let Ok(mut l) = cam.live.lock() {
            cam.geometry.fill(pipe.last_results(), &mut l.overlays);
            l.frame_id = Some(meta.frame_id);
        }
    }

    /// The frame itself: the console takes its buffer instead of a copy (swapped with the one
    /// it held, which goes back to the session's pool).
    pub fn frame(&self, camera: u32, buf: &mut FrameBuffer) {
        if !self.console.wants_frame(camera) {
            return;
        }
        let Some(cam) = self.camera(camera) else {
            return;
        };
        let Ok(mut l) = cam.live.lock() else {
            return;
        };
        if l.frame_id.take() != Some(buf.meta.frame_id) {
            return;
        }
        let m = buf.meta;
        self.console.publish_frame_buffer(
            camera,
            &mut buf.data,
            m.width,
            m.height,
            m.stride,
            m.format,
            m.frame_id,
            m.timestamp_ns.as_secs_f64(),
            &l.overlays,
        );
    }
}

/// The console's live view and status line, from a session's hooks.
pub struct LiveHooks(pub ConsoleHooks);

impl Hooks for LiveHooks {
    fn measured(
        &self,
        camera: u32,
        meta: &rodtrack_io::FrameMeta,
        rows: &[Measurement],
        pipe: &CameraPipeline,
    ) {
        self.0.measured(camera, meta, rows, pipe);
    }
    fn uses_frames(&self) -> bool {
        true
    }
    fn frame(&self, camera: u32, buf: &mut FrameBuffer) {
        self.0.frame(camera, buf);
    }
    fn progress(&self, p: &Progress) {
        self.0.publish_progress(p);
    }
}

/// The session's ball events to the web console too: the page shows the running score and
/// the last events.
pub struct ConsoleEvents(pub Arc<ConsoleHandle>);

/// The ball's rows to the web console (its top view of the field: position, trail, speed).
pub struct ConsoleBall(pub Arc<ConsoleHandle>);

impl rodtrack_io::BallSink for ConsoleBall {
    fn write(&mut self, rows: &[rodtrack_core::ball::BallRow]) -> Result<(), rodtrack_io::IoError> {
        self.0.publish_ball(rows);
        Ok(())
    }
    fn flush(&mut self) -> Result<(), rodtrack_io::IoError> {
        Ok(())
    }
}

impl rodtrack_io::EventSink for ConsoleEvents {
    fn write(
        &mut self,
        events: &[rodtrack_core::ball::events::BallEvent],
    ) -> Result<(), rodtrack_io::IoError> {
        self.0.publish_events(events);
        Ok(())
    }
    fn flush(&mut self) -> Result<(), rodtrack_io::IoError> {
        Ok(())
    }
}
