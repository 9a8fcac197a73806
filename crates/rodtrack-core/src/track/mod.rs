//! One rod, one frame: the measurement (SPEC section 4, steps 1-5), in the paper's mode and in
//! rodtrack's enhanced mode.
//!
//! A [`RodTracker`] is built once from a rod's calibration: it precomputes the line tables and
//! owns its scratch buffers, so that [`RodTracker::process`] allocates nothing.
//!
//! The module tree follows the stages: [`RodTracker`] here drives them; `paper` is the paper's
//! mode; the enhanced mode's `state` (tables, scratch, the records between stages) is worked
//! on by `locate` (steps 1-2), `edges` (step 3), `centre` (the rings' silhouettes), `shading`,
//! `gray` (step 4), `phase` (step 5) and `judge` (step 6), with `prefetch` ahead of them. The
//! stages use `tuning` (the constants), `learners` (what is learnt over frames), and the
//! helpers `silhouette` and `linalg`, which use no stage.

mod agree;
mod centre;
mod edges;
mod fresh;
mod gray;
mod judge;
mod learners;
mod linalg;
mod locate;
mod paper;
mod phase;
mod prefetch;
mod quality;
mod refine;
mod result;
mod shading;
mod silhouette;
mod state;
mod tuning;

pub use agree::min_wrong_share;
pub use judge::fuse_steps;
pub use learners::{CentreFit, ScaleFit, Silhouette};
pub use result::RodResult;
pub use silhouette::{
    ring_rows, ring_silhouette, ring_silhouette_measure, ring_silhouette_scan, silhouette_rings,
    RingSilhouette, SilhouetteScan, BLACK_RING_SCAN, WHITE_RING_SCAN,
};
pub use tuning::MAX_RINGS;

use crate::calib::RodCalibration;
use crate::frame::FrameView;
use crate::line::Knots;
use crate::marker::Marker;
use crate::measurement::Status;
use crate::CoreError;
use paper::PaperState;
use serde::{Deserialize, Serialize};
use state::{EnhancedState, Intermediate};
use tuning::MAX_MOTION_MM;

/// Which algorithm measures a rod.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, Serialize, Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    /// The paper's algorithm, exactly (the baseline).
    Paper,
    /// rodtrack's algorithm.
    #[default]
    Enhanced,
}

impl Mode {
    /// Parses `paper` or `enhanced`.
    pub fn from_name(s: &str) -> Option<Mode> {
        match s {
            "paper" => Some(Mode::Paper),
            "enhanced" => Some(Mode::Enhanced),
            _ => None,
        }
    }
}

/// Measures one rod in frames of one camera.
#[derive(Debug, Clone)]
pub struct RodTracker {
    calib: RodCalibration,
    marker: Marker,
    width: usize,
    height: usize,
    mode: Mode,
    paper: Option<PaperState>,
    enhanced: EnhancedState,
}

impl RodTracker {
    /// Builds the tracker: validates the calibration and precomputes the tables.
    pub fn new(
        calib: &RodCalibration,
        width: usize,
        height: usize,
        mode: Mode,
    ) -> Result<RodTracker, CoreError> {
        let marker = calib.validate(width, height)?;
        if mode == Mode::Paper && calib.paper.is_none() {
            return Err(CoreError::Calibration {
                rod: calib.rod,
                field: "paper".into(),
                reason: "paper mode needs the paper parameters (the rod must run along image rows)"
                    .into(),
            });
        }
        let paper = calib
            .paper
            .as_ref()
            .map(|p| PaperState::new(p, &marker, height));
        let enhanced = EnhancedState::new(calib, &marker, width, height);
        Ok(RodTracker {
            calib: calib.clone(),
            marker,
            width,
            height,
            mode,
            paper,
            enhanced,
        })
    }

    /// What the enhanced mode has learnt (diagnostics): the centre line's offset across the
    /// calibrated line at `s_mm` (px) and the radius ratio, and the phase's radius correction
    /// `eps` in use.
    pub fn learnt(&self, s_mm: f64) -> (f64, f64, f64) {
        let st = &self.enhanced;
        let (offset, ratio) = st.centre.at(s_mm);
        (
            offset,
            ratio,
            st.eps_values.get(st.eps_best).copied().unwrap_or(0.0),
        )
    }

    /// The centre line learnt so far (diagnostics).
    pub fn centre_fit(&self) -> &CentreFit {
        &self.enhanced.centre
    }

    /// The rod id.
    pub fn rod(&self) -> u32 {
        self.calib.rod
    }
    /// The calibration this tracker was built from.
    pub fn calibration(&self) -> &RodCalibration {
        &self.calib
    }
    /// The mode.
    pub fn mode(&self) -> Mode {
        self.mode
    }
    /// The marker.
    pub fn marker(&self) -> &Marker {
        &self.marker
    }
    /// The enhanced line.
    pub fn knots(&self) -> &Knots {
        &self.calib.knots
    }
    /// Frames in which enhanced mode searched the whole travel for the marker (the first, and
    /// any after the marker was lost or jumped); the others searched only around where the
    /// last frame's motion put it.
    pub fn full_searches(&self) -> u64 {
        self.enhanced.full_searches
    }

    /// Measures the rod in one frame. Allocates nothing.
    pub fn process(&mut self, frame: &FrameView) -> Result<RodResult, CoreError> {
        if frame.width() != self.width || frame.height() != self.height {
            return Err(CoreError::FrameMismatch {
                field: "size",
                expected: format!("{}x{}", self.width, self.height),
                got: format!("{}x{}", frame.width(), frame.height()),
            });
        }
        Ok(match self.mode {
            Mode::Paper => self.process_paper(frame),
            Mode::Enhanced => self.process_enhanced(frame),
        })
    }

    /// Fresh searches from the calibration alone (a rod not measured `ok` while its marker
    /// may be in view gets one on a schedule; see [`RodTracker::learnt_resets`]).
    pub fn fresh_searches(&self) -> u64 {
        self.enhanced.fresh_searches
    }

    /// Fresh searches that measured the rod `ok` where the learnt state did not: each reset
    /// the learnt state (the centre line, the phase's radius correction, the edges' bias, the
    /// shading reused, where the marker was) to what the fresh search learnt.
    pub fn learnt_resets(&self) -> u64 {
        self.enhanced.learnt_resets
    }

    /// The learnt centre line, to set a state by hand (tests of recovery from a learnt state
    /// gone wrong).
    #[doc(hidden)]
    pub fn centre_fit_mut(&mut self) -> &mut CentreFit {
        &mut self.enhanced.centre
    }

    /// The enhanced mode with its recovery: a rod not measured `ok` while its marker may be
    /// in view is searched afresh on a schedule (see `fresh`).
    fn process_enhanced(&mut self, frame: &FrameView) -> RodResult {
        let r = self.measure_enhanced(frame);
        let st = &mut self.enhanced;
        if r.status == Status::Ok {
            st.not_ok_run = 0;
            return r;
        }
        st.not_ok_run += 1;
        // Whatever stage gave up, the next reading is not continued from an old one.
        st.last_ok_theta = None;
        if !st.fresh_search_due(r.status) {
            return r;
        }
        st.fresh_searches += 1;
        st.forget();
        let fresh = self.measure_enhanced(frame);
        let st = &mut self.enhanced;
        if fresh.status == Status::Ok {
            st.learnt_resets += 1;
            st.not_ok_run = 0;
            fresh
        } else {
            st.restore();
            r
        }
    }

    fn measure_enhanced(&mut self, frame: &FrameView) -> RodResult {
        let m = &self.marker;
        let calib = &self.calib;
        let st = &mut self.enhanced;
        let last_mm = st.inter.map(|i| i.edges.position_mm);
        st.inter = None;
        let loc = st.locate(m, frame);
        st.predicted_mm = None;
        let loc = match loc {
            Ok(loc) => loc,
            Err(r) => return r,
        };
        let edges = match st.fit_edges(m, calib.reference_position_mm, frame, &loc) {
            Ok(e) => e,
            Err(r) => return r,
        };
        let p = edges.position_mm;
        st.predicted_mm = Some(match last_mm {
            Some(l) if (p - l).abs() < MAX_MOTION_MM => 2.0 * p - l,
            _ => p,
        });
        st.frames_seen = st.frames_seen.wrapping_add(1);
        if st.learns_centre(p, st.frames_seen) {
            st.learn_centre(frame, edges.position_mm);
        }
        let inter = Intermediate { loc, edges };
        st.inter = Some(inter);
        st.shading(m, calib.reference_position_mm, frame, &inter, false);
        let ph = st.phase(m, calib.reference_position_mm, frame, &inter);
        let gray = st.gray_code(m, frame, &inter, ph.mean);
        let check = st.code_check(m, calib, frame, &inter, &gray, &ph);
        let check = st.refine(m, calib, frame, &inter, &gray, check);
        st.judge(m, calib, &inter, &gray, &ph, &check)
    }

    /// The paper mode: [`PaperState::process`] on this rod's paper parameters.
    fn process_paper(&mut self, frame: &FrameView) -> RodResult {
        let (Some(st), Some(p)) = (self.paper.as_mut(), self.calib.paper.as_ref()) else {
            return RodResult {
                status: Status::NotFound,
                ..Default::default()
            };
        };
        st.process(p, &self.marker, self.calib.reference_position_mm, frame)
    }

    /// Asks for the frame's cache lines that measuring this rod will read (enhanced mode, when
    /// the last frame found it), where the marker is expected: a narrow strip along the line
    /// for the barcode's correlation and edges and the Gray bits, the full width across the
    /// rod over bit space 0's phase rows, and the shading's and the rings' rows on the frames
    /// that measure them; see [`FrameView::touch_rect`]. Call it for every rod of a frame
    /// before measuring any: the misses then overlap instead of stalling each read in turn.
    /// Returns a mix of bytes of the strips (to keep the work from being optimised away).
    pub fn prefetch(&self, frame: &FrameView) -> u8 {
        if self.mode != Mode::Enhanced {
            return 0;
        }
        self.enhanced.prefetch(&self.marker, frame)
    }

    /// Runs one stage of the enhanced mode on `frame`, on the intermediate results of the last
    /// [`RodTracker::process`] call (for per-stage benchmarks and diagnostics). Returns `false`
    /// (and does nothing) when the last call did not get that far.
    pub fn run_stage(&mut self, frame: &FrameView, stage: Stage) -> bool {
        let m = &self.marker;
        let calib = &self.calib;
        let st = &mut self.enhanced;
        let Some(inter) = st.inter else {
            return false;
        };
        match stage {
            Stage::Locate => {
                let last_k = st.last_k;
                let _ = st.locate(m, frame);
                st.last_k = last_k;
            }
            Stage::Edges => {
                let _ = st.fit_edges(m, calib.reference_position_mm, frame, &inter.loc);
            }
            Stage::Centre => st.learn_centre(frame, inter.edges.position_mm),
            Stage::Gray => {
                std::hint::black_box(st.gray_code(m, frame, &inter, 0.5));
            }
            Stage::Shading => st.shading(m, calib.reference_position_mm, frame, &inter, true),
            Stage::Phase => {
                std::hint::black_box(st.phase(m, calib.reference_position_mm, frame, &inter));
            }
        }
        st.inter = Some(inter);
        true
    }
}

/// The stages of the enhanced mode, in order (see [`RodTracker::run_stage`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Stage {
    /// Coarse line and barcode correlation (steps 1-2).
    Locate,
    /// Sub-pixel position from the barcode's 12 edges (step 3).
    Edges,
    /// The white rings' silhouettes feeding the learnt centre line.
    Centre,
    /// The Gray bits (step 4).
    Gray,
    /// The print's shading across the rod, from the barcode's runs.
    Shading,
    /// The phase over bit space 0 (step 5).
    Phase,
}

impl Stage {
    /// Every stage, in order.
    pub const ALL: [Stage; 6] = [
        Stage::Locate,
        Stage::Edges,
        Stage::Centre,
        Stage::Gray,
        Stage::Shading,
        Stage::Phase,
    ];

    /// Short name.
    pub fn name(self) -> &'static str {
        match self {
            Stage::Locate => "locate",
            Stage::Edges => "edges",
            Stage::Centre => "centre",
            Stage::Gray => "gray",
            Stage::Shading => "shading",
            Stage::Phase => "phase",
        }
    }
}
