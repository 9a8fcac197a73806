//! `--mcap FILE`, `--mcap-frames N`, `--mcap-ros2` and `--mcap-compression` of `track` and
//! `fuse`: the run's rows, as joint states too, and optionally downscaled frames, in an MCAP
//! file that Foxglove and Rerun open, or a ROS 2 bag of joint states (docs/formats.md, "MCAP
//! recordings").

use anyhow::{Context, Result};
use rodtrack_core::Measurement;
use rodtrack_io::mcap::{Compression, McapRecorder, Profile, RecordOptions};
use rodtrack_io::{FrameBuffer, FrameMeta};
use rodtrack_sdk::{Hooks, Progress};
use std::path::PathBuf;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// The recorded frames' longer side, px.
const FRAME_MAX_SIDE_PX: usize = 480;

/// How the recording's chunks are compressed.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, clap::ValueEnum)]
pub enum CompressionArg {
    /// Not compressed.
    #[default]
    None,
    /// LZ4 frames.
    Lz4,
}

impl From<CompressionArg> for Compression {
    fn from(c: CompressionArg) -> Self {
        match c {
            CompressionArg::None => Compression::None,
            CompressionArg::Lz4 => Compression::Lz4,
        }
    }
}

/// The recording's options.
#[derive(Debug, Clone, Default, clap::Args)]
pub struct McapArgs {
    /// Also record the rows (each camera's and the fused ones), the rods as joints and the
    /// ball's rows when the ball is tracked to this MCAP file, for Foxglove or Rerun
    /// (docs/network.md).
    #[arg(long)]
    pub mcap: Option<PathBuf>,
    /// With --mcap: also record this many downscaled grey frames per second per camera
    /// (0: none).
    #[arg(long, default_value_t = 0.0, requires = "mcap")]
    pub mcap_frames: f64,
    /// With --mcap: write a ROS 2 bag instead (MCAP profile ros2, for rosbag2 and rosbags):
    /// the rods as sensor_msgs/msg/JointState in CDR, per camera and fused, and the ball as
    /// geometry_msgs/msg/PointStamped and Vector3Stamped; no rows, no frames.
    #[arg(long, requires = "mcap")]
    pub mcap_ros2: bool,
    /// With --mcap: how the file's chunks are compressed.
    #[arg(long, value_enum, default_value_t = CompressionArg::None, requires = "mcap")]
    pub mcap_compression: CompressionArg,
}

/// Opens the recording when `--mcap` was given; `cameras` are the calibration's (index,
/// name).
pub fn open(
    args: &McapArgs,
    table: &str,
    cameras: Vec<(u32, String)>,
) -> Result<Option<McapRecorder>> {
    let Some(path) = &args.mcap else {
        return Ok(None);
    };
    if !(args.mcap_frames.is_finite() && args.mcap_frames >= 0.0) {
        anyhow::bail!(
            "--mcap-frames {}: expected a number of frames per second, 0 or more",
            args.mcap_frames
        );
    }
    if args.mcap_ros2 && args.mcap_frames > 0.0 {
        anyhow::bail!(
            "--mcap-frames with --mcap-ros2: a ROS 2 bag of rodtrack holds joint states only"
        );
    }
    let options = RecordOptions {
        table: table.to_string(),
        cameras,
        frames_per_s: args.mcap_frames,
        profile: if args.mcap_ros2 {
            Profile::Ros2
        } else {
            Profile::Rodtrack
        },
        compression: args.mcap_compression.into(),
        ..RecordOptions::default()
    };
    let rec = McapRecorder::create(path, options)
        .with_context(|| format!("creating the recording {}", path.display()))?;
    Ok(Some(rec))
}

/// The recording's sink of ball rows, for the ball of the calibration's first camera with a
/// ball; `None` when no camera has one.
pub fn ball_sink(
    rec: &McapRecorder,
    cal: &rodtrack_core::calib::CalibrationFile,
) -> Option<Box<dyn rodtrack_io::BallSink>> {
    let ball = cal.cameras.iter().find_map(|c| c.ball.as_ref())?;
    Some(Box::new(rec.ball_sink(ball.diameter_mm)))
}

/// Ends the recording (its summary and footer) and says what it holds.
pub fn finish(rec: Option<&McapRecorder>) -> Result<()> {
    let Some(rec) = rec else {
        return Ok(());
    };
    let path = rec.path();
    let s = rec
        .finish()
        .with_context(|| format!("finishing the recording {}", path.display()))?;
    println!(
        "wrote {}: {} messages on {} channels, {:.3} s",
        path.display(),
        s.messages,
        s.channels,
        s.message_end_ns.saturating_sub(s.message_start_ns) as f64 * 1e-9
    );
    Ok(())
}

/// Hooks that record frames (when `--mcap-frames` asks for them), then call `inner`.
pub fn frame_hooks(rec: Option<&McapRecorder>, inner: Arc<dyn Hooks>) -> Arc<dyn Hooks> {
    match rec {
        Some(rec) if rec.wants_frames() => Arc::new(FrameHooks {
            rec: rec.clone(),
            inner,
            errors: AtomicU64::new(0),
        }),
        _ => inner,
    }
}

struct FrameHooks {
    rec: McapRecorder,
    inner: Arc<dyn Hooks>,
    errors: AtomicU64,
}

impl Hooks for FrameHooks {
    fn measured(
        &self,
        camera: u32,
        meta: &FrameMeta,
        rows: &[Measurement],
        pipe: &rodtrack_core::CameraPipeline,
    ) {
        self.inner.measured(camera, meta, rows, pipe);
    }
    fn camera_rows(&self, camera: u32, meta: &FrameMeta, rows: &[Measurement]) {
        self.inner.camera_rows(camera, meta, rows);
    }
    fn uses_frames(&self) -> bool {
        true
    }
    fn frame(&self, camera: u32, buf: &mut FrameBuffer) {
        let t = buf.meta.timestamp_ns.as_nanos();
        if self.rec.wants_frame(camera, t) {
            let r = match buf.try_view() {
                Ok(view) => self.rec.record_view(camera, t, &view, FRAME_MAX_SIDE_PX),
                Err(e) => Err(e),
            };
            if let Err(e) = r {
                if self.errors.fetch_add(1, Ordering::Relaxed) == 0 {
                    eprintln!("\nrecording a frame: {e} (further errors not printed)");
                }
            }
        }
        if self.inner.uses_frames() {
            self.inner.frame(camera, buf);
        }
    }
    fn bad_frame(&self, camera: &str, frame_id: u64, error: &str, count: u64) {
        self.inner.bad_frame(camera, frame_id, error, count);
    }
    fn warning(&self, text: &str, count: u64) {
        self.inner.warning(text, count);
    }
    fn progress(&self, p: &Progress) {
        self.inner.progress(p);
    }
}
