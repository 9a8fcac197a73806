//! Recovery by construction: no learnt state may keep a measurable rod from being measured.
//!
//! Everything the enhanced mode learns over frames (the centre line and radius with their
//! gates, the phase's radius correction, the edges' bias, the reused shading, where the
//! marker was) helps a measurement but also decides it: a learner that took bad samples can
//! gate out the good ones and keep the rod `occluded` for ever. So a rod that is not `ok`
//! while its marker may be in view gets, on a schedule, a fresh search of the same frame from
//! its calibration alone, with nothing learnt. If the fresh search measures the rod `ok`,
//! the learnt state disagreed with a good measurement: it is dropped for the fresh one and
//! the reset is counted ([`super::RodTracker::learnt_resets`]). Otherwise the learnt state
//! is kept as it was.
//!
//! The learnt mm scale along the line ([`super::ScaleFit`]) is kept through a fresh search
//! and a reset: it only turns a position found into true mm and decides nothing.

use super::learners::CentreFit;
use super::state::{EnhancedState, Intermediate};
use super::tuning::FRESH_SEARCH_EVERY;
use crate::measurement::Status;

/// What a fresh search sets aside (preallocated: a fresh search allocates nothing).
#[derive(Debug, Clone, Default)]
pub(super) struct Learnt {
    centre: CentreFit,
    edge_bias_mm: f64,
    eps_acc: Vec<f64>,
    eps_best: usize,
    frames_seen: u64,
    white_rel: Vec<f64>,
    black_rel: Vec<f64>,
    shading_at_mm: f64,
    shading_age: u32,
    last_k: Option<usize>,
    predicted_mm: Option<f64>,
    inter: Option<Intermediate>,
}

impl Learnt {
    /// Room for a rod's state.
    pub(super) fn with_sizes(n_eps: usize, n_phase: usize) -> Learnt {
        Learnt {
            eps_acc: vec![0.0; n_eps],
            white_rel: vec![0.0; n_phase],
            black_rel: vec![0.0; n_phase],
            ..Default::default()
        }
    }
}

impl EnhancedState {
    /// Whether this frame's result `status`, after `not_ok_run` frames in a row not `ok`
    /// (this one included), calls for a fresh search: the marker may be in view and the rod
    /// was not measured, on the first such frame and every [`FRESH_SEARCH_EVERY`]th after.
    pub(super) fn fresh_search_due(&self, status: Status) -> bool {
        !matches!(status, Status::Ok | Status::OutOfView)
            && self.not_ok_run % FRESH_SEARCH_EVERY == 1
    }

    /// Exchanges the learnt state with the one set aside (no allocation: the buffers swap).
    fn swap_learnt(&mut self) {
        let b = &mut self.backup;
        std::mem::swap(&mut b.centre, &mut self.centre);
        std::mem::swap(&mut b.edge_bias_mm, &mut self.edge_bias_mm);
        std::mem::swap(&mut b.eps_acc, &mut self.eps_acc);
        std::mem::swap(&mut b.eps_best, &mut self.eps_best);
        std::mem::swap(&mut b.frames_seen, &mut self.frames_seen);
        std::mem::swap(&mut b.white_rel, &mut self.white_rel);
        std::mem::swap(&mut b.black_rel, &mut self.black_rel);
        std::mem::swap(&mut b.shading_at_mm, &mut self.shading_at_mm);
        std::mem::swap(&mut b.shading_age, &mut self.shading_age);
        std::mem::swap(&mut b.last_k, &mut self.last_k);
        std::mem::swap(&mut b.predicted_mm, &mut self.predicted_mm);
        std::mem::swap(&mut b.inter, &mut self.inter);
    }

    /// Sets the learnt state aside and starts from the calibration alone.
    pub(super) fn forget(&mut self) {
        self.swap_learnt();
        self.centre = CentreFit::default();
        self.edge_bias_mm = 0.0;
        self.eps_acc.fill(0.0);
        self.eps_best = self.eps_acc.len() / 2;
        self.frames_seen = 0;
        // The shading reference is kept as it was.
        self.white_rel.copy_from_slice(&self.backup.white_rel);
        self.black_rel.copy_from_slice(&self.backup.black_rel);
        self.shading_at_mm = f64::NAN;
        self.shading_age = 0;
        self.last_k = None;
        self.predicted_mm = None;
        self.inter = None;
        // Nothing learnt: the fresh reading is checked across the rod.
        self.last_ok_theta = None;
    }

    /// Takes the learnt state set aside by [`EnhancedState::forget`] back.
    pub(super) fn restore(&mut self) {
        self.swap_learnt();
    }
}
