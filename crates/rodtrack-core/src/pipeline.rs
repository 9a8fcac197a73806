//! One camera, one frame, every rod: the per-camera pipeline that turns a frame into rows.

use crate::angle::wrap_pi_fold;
use crate::calib::CameraCalibration;
use crate::filter::{FilterBank, FilterConfig, TurnStats};
use crate::frame::FrameView;
use crate::fusion::{Disagreement, Fuser, FusionConfig, OutOfSync};
use crate::measurement::{CameraId, Measurement, Status};
use crate::time::Timestamp;
use crate::track::{Mode, RodResult, RodTracker};
use crate::CoreError;

/// Per-rod state kept across frames: the multi-turn count of the raw rows.
///
/// Consecutive `ok` rows are unwrapped by the shortest way (`|step| <= pi`). That is exact
/// when the rod cannot turn half a turn between them: `max_angular_velocity * dt < pi`, with
/// the filter's speed bound ([`FilterConfig::max_angular_velocity_rad_s`]). A longer step (a
/// frame not `ok` in between, a slow frame rate) makes the count unknown; it is re-anchored
/// after [`FilterConfig::reanchor_frames`] consecutive short steps, as in the filter.
#[derive(Debug, Clone, Copy, Default)]
struct TurnState {
    last_angle: Option<f64>,
    last_t: Timestamp,
    unwrapped: f64,
    known: bool,
    steady: u32,
}

impl TurnState {
    /// Takes the angle of an `ok` row at time `t`; returns (unwrapped angle, count known).
    fn take(&mut self, angle_rad: f64, t: Timestamp, cfg: &FilterConfig) -> (f64, bool) {
        match self.last_angle {
            None => {
                self.unwrapped = angle_rad;
                self.known = true;
            }
            Some(prev) => {
                self.unwrapped += wrap_pi_fold(angle_rad - prev);
                let dt = t.seconds_since(self.last_t);
                if dt > 0.0 && cfg.max_angular_velocity_rad_s * dt < std::f64::consts::PI {
                    if !self.known {
                        self.steady += 1;
                        if self.steady >= cfg.reanchor_frames {
                            self.known = true;
                            self.steady = 0;
                        }
                    }
                } else {
                    self.known = false;
                    self.steady = 0;
                }
            }
        }
        self.last_angle = Some(angle_rad);
        self.last_t = t;
        (self.unwrapped, self.known)
    }
}

/// Every rod of one camera.
#[derive(Debug, Clone)]
pub struct CameraPipeline {
    index: u32,
    rods: Vec<RodTracker>,
    turns: Vec<TurnState>,
    last: Vec<RodResult>,
    turn_cfg: FilterConfig,
}

impl CameraPipeline {
    /// Builds the trackers of every rod of a camera's calibration.
    pub fn new(cal: &CameraCalibration, mode: Mode) -> Result<CameraPipeline, CoreError> {
        let rods = cal
            .rods
            .iter()
            .map(|r| RodTracker::new(r, cal.image_width, cal.image_height, mode))
            .collect::<Result<Vec<_>, _>>()?;
        let n = rods.len();
        Ok(CameraPipeline {
            index: cal.index,
            rods,
            turns: vec![TurnState::default(); n],
            last: vec![RodResult::default(); n],
            turn_cfg: filter_config(mode),
        })
    }

    /// The camera index written in rows.
    pub fn index(&self) -> u32 {
        self.index
    }
    /// The rod trackers.
    pub fn rods(&self) -> &[RodTracker] {
        &self.rods
    }
    /// The last frame's raw results, one per rod.
    pub fn last_results(&self) -> &[RodResult] {
        &self.last
    }

    /// Measures every rod in `frame` and appends one row per rod to `out`. A frame that does
    /// not fit gives an error and no rows; use [`CameraPipeline::bad_frame`] to mark it.
    pub fn process(
        &mut self,
        frame: &FrameView,
        frame_id: u64,
        timestamp_ns: Timestamp,
        out: &mut Vec<Measurement>,
    ) -> Result<(), CoreError> {
        // Ask for every rod's strips of the new frame at once: the reads overlap with each
        // other and with the measuring (asking a rod or two ahead of the one measured instead
        // measured the same here).
        let mut touched = 0u8;
        for tr in &self.rods {
            touched ^= tr.prefetch(frame);
        }
        std::hint::black_box(touched);
        let turn_cfg = self.turn_cfg;
        for ((tr, turn), last) in self
            .rods
            .iter_mut()
            .zip(&mut self.turns)
            .zip(&mut self.last)
        {
            let r = tr.process(frame)?;
            *last = r;
            let mut m = Measurement::empty(
                frame_id,
                timestamp_ns,
                CameraId::Camera(self.index),
                tr.rod(),
                r.status,
            );
            if r.status == Status::Ok {
                m.position_mm = r.position_mm;
                m.angle_rad = r.angle_rad;
                // Multi-turn count: the absolute angle needs no history, the turn count does.
                let (unwrapped, known) = turn.take(r.angle_rad, timestamp_ns, &turn_cfg);
                m.angle_unwrapped_rad = unwrapped;
                m.turns_known = known;
            } else {
                m.angle_unwrapped_rad = turn.unwrapped;
            }
            m.quality = r.quality;
            out.push(m.sanitized());
        }
        Ok(())
    }

    /// Rows marking every rod of an unusable frame.
    pub fn bad_frame(&self, frame_id: u64, timestamp_ns: Timestamp, out: &mut Vec<Measurement>) {
        for tr in &self.rods {
            out.push(Measurement::empty(
                frame_id,
                timestamp_ns,
                CameraId::Camera(self.index),
                tr.rod(),
                Status::BadFrame,
            ));
        }
    }
}

/// Marks `bad_frame` (quality 0) each fused row whose rod has rows in `raw` that are all
/// `bad_frame`: every camera's frame was unusable.
pub fn mark_fused_bad_frames(raw: &[Measurement], fused: &mut [Measurement]) {
    for f in fused {
        let mut rows = raw
            .iter()
            .filter(|m| m.rod == f.rod && matches!(m.camera, CameraId::Camera(_)))
            .peekable();
        if rows.peek().is_some() && rows.all(|m| m.status == crate::Status::BadFrame) {
            f.status = crate::Status::BadFrame;
            f.quality = 0.0;
        }
    }
}

/// The temporal filter tuned to the measurement noise of `mode`: the one tuning that
/// [`CameraFilter`], [`SetFusion`] and [`FrameSetFilter`] use.
///
/// ```
/// use rodtrack_core::{pipeline::filter_config, Mode};
/// assert!(filter_config(Mode::Paper).angle_noise_rad > filter_config(Mode::Enhanced).angle_noise_rad);
/// ```
pub fn filter_config(mode: Mode) -> FilterConfig {
    let mut config = FilterConfig::default();
    if mode == Mode::Paper {
        // The paper's resolution: about 1 px (0.6-0.9 mm) and 0.013 rad.
        config.position_noise_mm = 0.3;
        config.angle_noise_rad = 0.013;
    }
    config
}

/// The quality at which a lone camera's first measurement of a rod is confirmed at once
/// ([`FilterConfig::confirm_quality`] of [`filter_config_alone`]). Every factor of a row's
/// quality (`track::quality`, see `docs/quality.md`) is then at least 0.9: the error the
/// frame's evidence predicts is within 1/0.9 of the best the marker allows, and less than a
/// tenth of the evidence a wrong Gray code leaves in the print is present. Over the quality
/// relation's tables no row of that quality was grossly wrong (`docs/quality.md`).
pub const CONFIRM_ALONE_QUALITY: f64 = 0.9;

/// [`filter_config`] for a camera that no other camera can corroborate or contradict: in
/// enhanced mode its first measurement of a rod is `ok` at once when its quality is at least
/// [`CONFIRM_ALONE_QUALITY`] (with several cameras, the fused row is confirmed at once by the
/// cameras' agreement instead). Paper mode keeps the published baseline's confirmation.
///
/// ```
/// use rodtrack_core::{pipeline::{filter_config_alone, CONFIRM_ALONE_QUALITY}, Mode};
/// assert_eq!(filter_config_alone(Mode::Enhanced).confirm_quality, Some(CONFIRM_ALONE_QUALITY));
/// assert_eq!(filter_config_alone(Mode::Paper).confirm_quality, None);
/// ```
pub fn filter_config_alone(mode: Mode) -> FilterConfig {
    let mut config = filter_config(mode);
    if mode == Mode::Enhanced {
        config.confirm_quality = Some(CONFIRM_ALONE_QUALITY);
    }
    config
}

/// A turn count given by the user: at frame `frame`, rod `rod` is at whole turn `turns`
/// (`angle_unwrapped_rad = 2 pi turns + angle_rad` from that frame on, and the count is known).
/// See [`crate::filter::RodFilter::reanchor_turns`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TurnAnchor {
    /// Frame id at which the count is set.
    pub frame: u64,
    /// Rod id.
    pub rod: u32,
    /// The rod's whole turn at that frame.
    pub turns: i64,
}

/// Applies the anchors of `anchors` that fall on `row`'s frame and rod, after `row` was
/// filtered by `bank`: the filter's count and the row's unwrapped angle.
fn apply_anchors(anchors: &[TurnAnchor], bank: &mut FilterBank, row: &mut Measurement) {
    for a in anchors {
        if a.frame == row.frame && a.rod == row.rod {
            bank.reanchor_turns(a.rod, a.turns);
            if matches!(row.status, Status::Ok | Status::Predicted) {
                row.angle_unwrapped_rad = std::f64::consts::TAU * a.turns as f64 + row.angle_rad;
                row.turns_known = true;
            }
        }
    }
}

/// One camera's part of the temporal filter: its rows through its per-rod filters (a runtime
/// runs it in the camera's own thread).
#[derive(Debug, Clone)]
pub struct CameraFilter {
    bank: FilterBank,
    anchors: Vec<TurnAnchor>,
}

impl CameraFilter {
    /// Filters tuned for `mode` ([`filter_config`]).
    pub fn new(mode: Mode) -> Self {
        CameraFilter {
            bank: FilterBank::new(filter_config(mode)),
            anchors: Vec::new(),
        }
    }

    /// Filters for a camera with no other camera beside it ([`filter_config_alone`]: a
    /// rod's first measurement of high quality is `ok` at once).
    pub fn alone(mode: Mode) -> Self {
        CameraFilter {
            bank: FilterBank::new(filter_config_alone(mode)),
            anchors: Vec::new(),
        }
    }

    /// Turn counts to set at given frames ([`TurnAnchor`]).
    pub fn set_turn_anchors(&mut self, anchors: &[TurnAnchor]) {
        self.anchors = anchors.to_vec();
    }

    /// Re-anchors `rod`'s turn count by hand (see
    /// [`crate::filter::RodFilter::reanchor_turns`]).
    pub fn reanchor_turns(&mut self, rod: u32, turns: i64) {
        self.bank.reanchor_turns(rod, turns);
    }

    /// The turn-count counters of this camera's filters, every rod together.
    pub fn turn_stats(&self) -> TurnStats {
        self.bank.turn_stats()
    }

    /// The turn-count counters of `rod`'s filter (zero for a rod not filtered yet).
    pub fn rod_turn_stats(&self, rod: u32) -> TurnStats {
        self.bank
            .filter(rod)
            .map(|f| f.turn_stats())
            .unwrap_or_default()
    }

    /// Appends the filtered row of each camera row of `rows` (fused rows are not a camera's
    /// and are skipped).
    pub fn process(&mut self, rows: &[Measurement], out: &mut Vec<Measurement>) {
        for m in rows {
            if let CameraId::Camera(_) = m.camera {
                let mut row = self.bank.update(m).sanitized();
                apply_anchors(&self.anchors, &mut self.bank, &mut row);
                out.push(row);
            }
        }
    }
}

/// The fusion part of the temporal filter: the measured rows of a frame set fused per rod
/// (camera [`CameraId::Fused`]) and filtered again.
#[derive(Debug, Clone)]
pub struct SetFusion {
    fuser: Fuser,
    bank: FilterBank,
    anchors: Vec<TurnAnchor>,
    /// Whether overruled camera rows are flagged (not in paper mode: its camera rows stay the
    /// published baseline's).
    flags_cameras: bool,
}

impl SetFusion {
    /// Fusion and filters tuned for `mode` ([`filter_config`]).
    pub fn new(mode: Mode) -> Self {
        SetFusion {
            fuser: Fuser::new(FusionConfig::default()),
            bank: FilterBank::new(filter_config(mode)),
            anchors: Vec::new(),
            flags_cameras: mode != Mode::Paper,
        }
    }

    /// Turn counts to set at given frames ([`TurnAnchor`]).
    pub fn set_turn_anchors(&mut self, anchors: &[TurnAnchor]) {
        self.anchors = anchors.to_vec();
    }

    /// Appends the fused rows of the set's measured (unfiltered) rows `raw`.
    pub fn process(&mut self, raw: &[Measurement], out: &mut Vec<Measurement>) {
        let start = out.len();
        self.fuser.process(raw, &mut self.bank, out);
        for m in &mut out[start..] {
            *m = m.sanitized();
            apply_anchors(&self.anchors, &mut self.bank, m);
        }
        mark_fused_bad_frames(raw, &mut out[start..]);
    }

    /// Marks `conflict` the camera rows the last frame set's fusion overruled (see
    /// [`Fuser::flag_overruled`]): pass the set's filtered camera rows.
    pub fn flag_overruled(&self, camera_rows: &mut [Measurement]) {
        crate::fusion::flag_overruled_rows(self.overruled(), camera_rows);
    }

    /// Re-anchors `rod`'s turn count in the fused rows' filter (see
    /// [`crate::filter::RodFilter::reanchor_turns`]).
    pub fn reanchor_turns(&mut self, rod: u32, turns: i64) {
        self.bank.reanchor_turns(rod, turns);
    }

    /// The fused rows' turn-count counters, every rod together.
    pub fn turn_stats(&self) -> TurnStats {
        self.bank.turn_stats()
    }

    /// The turn-count counters of the fused rows' filter of `rod` (zero for a rod not
    /// filtered yet).
    pub fn rod_turn_stats(&self, rod: u32) -> TurnStats {
        self.bank
            .filter(rod)
            .map(|f| f.turn_stats())
            .unwrap_or_default()
    }

    /// The camera rows the last frame set's fusion overruled, as (camera, rod); none in paper
    /// mode (its camera rows stay the published method's).
    pub fn overruled(&self) -> &[(CameraId, u32)] {
        if self.flags_cameras {
            self.fuser.overruled()
        } else {
            &[]
        }
    }

    /// Cameras that disagreed in the last frame set.
    pub fn disagreements(&self) -> &[Disagreement] {
        self.fuser.disagreements()
    }

    /// Cameras out of sync in the last frame set.
    pub fn out_of_sync(&self) -> &[OutOfSync] {
        self.fuser.out_of_sync()
    }
}

/// The temporal filter and the fusion over one frame set (all cameras of one trigger): every
/// camera's rows go through that camera's [`CameraFilter`], and, with several cameras, the
/// rows of one rod are fused by [`SetFusion`]. No added delay: the rows for frame n use
/// frame n. A runtime that filters each camera in its own thread runs the two parts apart and
/// gets the same rows.
#[derive(Debug, Clone)]
pub struct FrameSetFilter {
    mode: Mode,
    per_camera: Vec<CameraFilter>,
    fusion: Option<SetFusion>,
}

impl FrameSetFilter {
    /// Filters tuned to the measurement noise of `mode`; `fuse` adds fused rows. Without
    /// fusion each camera is filtered alone ([`CameraFilter::alone`]).
    pub fn new(mode: Mode, fuse: bool) -> FrameSetFilter {
        FrameSetFilter {
            mode,
            per_camera: Vec::new(),
            fusion: fuse.then(|| SetFusion::new(mode)),
        }
    }

    /// Appends the filtered rows of every camera, then the fused rows; the camera rows the
    /// fusion overruled are marked `conflict` ([`SetFusion::flag_overruled`]).
    pub fn process(&mut self, raw: &[Measurement], out: &mut Vec<Measurement>) {
        let start = out.len();
        for m in raw {
            let CameraId::Camera(c) = m.camera else {
                continue;
            };
            let c = c as usize;
            while self.per_camera.len() <= c {
                self.per_camera.push(if self.fusion.is_some() {
                    CameraFilter::new(self.mode)
                } else {
                    CameraFilter::alone(self.mode)
                });
            }
            self.per_camera[c].process(std::slice::from_ref(m), out);
        }
        if let Some(f) = self.fusion.as_mut() {
            let cameras_end = out.len();
            f.process(raw, out);
            f.flag_overruled(&mut out[start..cameras_end]);
        }
    }

    /// Re-anchors `rod`'s turn count by hand in every camera's filter and the fusion's (see
    /// [`crate::filter::RodFilter::reanchor_turns`]).
    pub fn reanchor_turns(&mut self, rod: u32, turns: i64) {
        for c in &mut self.per_camera {
            c.reanchor_turns(rod, turns);
        }
        if let Some(f) = self.fusion.as_mut() {
            f.reanchor_turns(rod, turns);
        }
    }

    /// Cameras that disagreed in the last frame set.
    pub fn disagreements(&self) -> &[Disagreement] {
        self.fusion.as_ref().map_or(&[], |f| f.disagreements())
    }
    /// Cameras out of sync in the last frame set.
    pub fn out_of_sync(&self) -> &[OutOfSync] {
        self.fusion.as_ref().map_or(&[], |f| f.out_of_sync())
    }
}
