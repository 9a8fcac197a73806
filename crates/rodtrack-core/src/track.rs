//! One rod, one frame: the measurement (SPEC section 4, steps 1-5), in the paper's mode and in
//! rodtrack's enhanced mode.
//!
//! A [`RodTracker`] is built once from a rod's calibration: it precomputes the line tables and
//! owns its scratch buffers, so that [`RodTracker::process`] allocates nothing.

use crate::calib::RodCalibration;
use crate::decode::{decode_bits, paper_fuse, paper_phase, paper_threshold};
use crate::frame::FrameView;
use crate::line::{Knots, LinePoint, PaperLine, PreparedKnots};
use crate::marker::Marker;
use crate::measurement::Status;
use crate::signal::{
    argmax, argmax_sq, hysteresis, ncc_cells_prefix, ncc_direct, paper_bandpass, parabolic_offset,
    prefix_sums, PAPER_HYSTERESIS,
};
use crate::CoreError;
use serde::{Deserialize, Serialize};
use std::f64::consts::TAU;

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

/// What one rod's processing found in one frame.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct RodResult {
    /// Position along `u`, mm.
    pub position_mm: f64,
    /// Angle in `[0, 2 pi)`.
    pub angle_rad: f64,
    /// Confidence in `[0, 1]`.
    pub quality: f64,
    /// Trust.
    pub status: Status,
    /// Diagnostics: the decoded Gray step.
    pub gray_step: u32,
    /// Diagnostics: the angle in Gray steps before the offset, `[0, steps)`.
    pub theta_steps: f64,
    /// Diagnostics: the correlation peak.
    pub ncc: f64,
    /// Diagnostics: why the status is not `ok` (empty when it is).
    pub reason: &'static str,
    /// Diagnostics: phase amplitude over the expected one.
    pub amp_ratio: f64,
    /// Diagnostics: the share of the stripes' variation across the rod (over bit space 0)
    /// that their fundamental explains.
    pub stripe_share: f64,
    /// Diagnostics: spread of the barcode's edges around their fit, mm.
    pub edge_std_mm: f64,
}

/// Candidate search margin beyond the travel, mm.
const SEARCH_MARGIN_MM: f64 = 10.0;
/// Fine-profile half length around an edge, in cells.
const EDGE_HALF_CELLS: f64 = 0.5;
/// Half widths of the search windows around where the marker is expected (the last frame's
/// position plus its motion), mm, tried in turn: a change of speed of 0.8 m/s, then of
/// 2.4 m/s, from one frame to the next at 200 fps. Beyond them, the whole travel is searched.
/// The prediction is usually right to a fraction of a mm, so the narrow window nearly always
/// holds the peak, at a third of the wide one's cost.
const SEARCH_WINDOWS_MM: [f64; 2] = [4.0, 12.0];
/// Largest motion from one frame to the next taken as motion (not a jump), mm.
const MAX_MOTION_MM: f64 = 40.0;
/// Fine-profile samples per cell.
const EDGE_SAMPLES_PER_CELL: usize = 10;
/// Frames over which the radius correction `eps` is scored every frame; then every
/// [`EPS_RESCORE_EVERY`]th frame.
const EPS_LEARN_FRAMES: u64 = 64;
const EPS_RESCORE_EVERY: u64 = 8;
/// The phase's grid of radius corrections `eps`: `EPS_GRID` values from -0.08 by 0.01.
const EPS_GRID: usize = 21;
fn eps_of(i: usize) -> f64 {
    (i as f64 - 8.0) * 0.01
}
/// Per-frame forgetting factor of the `eps` scores.
const EPS_FORGET: f64 = 0.995;
/// Where a Gray bit is read, around its bit space's centre: (along the rod in bit spaces,
/// across it in radii).
const GRAY_SAMPLES: [(f64, f64); 5] = [
    (0.0, 0.0),
    (-0.2, 0.0),
    (0.2, 0.0),
    (0.0, -0.15),
    (0.0, 0.15),
];
/// Most rings whose silhouettes one frame adds to the learnt centre line.
pub const MAX_RINGS: usize = 32;
/// Shortest quiet zone after the Gray code that serves as the white reference of the Gray
/// bits' threshold, mm.
/// Where the quiet zone is read, around its middle: (along the rod in quiet-zone lengths,
/// across it in radii). Plain white: two samples are enough.
const QUIET_SAMPLES: [(f64, f64); 2] = [(0.0, -0.15), (0.0, 0.15)];
const QUIET_REFERENCE_MIN_MM: f64 = 2.0;
/// How far the marker may move from where the print's shading was measured before it is
/// measured again, mm.
const SHADING_REUSE_MM: f64 = 5.0;
/// For how many frames a shading measurement is reused at most.
const SHADING_REUSE_FRAMES: u32 = 8;
/// Phase samples per stripe period.
const PHASE_SAMPLES_PER_PERIOD: usize = 8;
/// The stripes' fundamental over a square wave's between the print's black and white, above
/// which bit space 0 is not (only) the print: 1 at most for the print itself, with room for
/// the error of the shading it is normalised by.
const MAX_STRIPE_AMP_RATIO: f64 = 1.2;
/// The least share of the stripes' variation across the rod that their fundamental must
/// explain: 0.81 for sharp stripes (8/pi^2), more when blurred; below this, noise alone
/// would have to be a third of the variation.
const MIN_STRIPE_SHARE: f64 = 0.6;

#[derive(Debug, Clone)]
struct PaperState {
    line: PaperLine,
    kernel_px: Vec<f32>,
    raw: Vec<f32>,
    filtered: Vec<f32>,
    binary: Vec<f32>,
    corr: Vec<f32>,
    d: Vec<f32>,
}

#[derive(Debug, Clone)]
struct EnhancedState {
    knots: PreparedKnots,
    /// Coarse candidate of the last frame that was measured `ok` (search window centre).
    last_k: Option<usize>,
    /// Axis coordinate of coarse sample 0, mm.
    coarse_s0: f64,
    coarse_step: f64,
    /// Nearest luma node per coarse sample; `None` outside the frame.
    coarse_nodes: Vec<Option<(isize, isize)>>,
    /// `coarse_nodes` on the luma grid of frames whose node offset is `coarse_grid_offset`
    /// (converted on the first frame, again only if the pixel format changes).
    coarse_grid: Vec<Option<(isize, isize)>>,
    coarse_grid_offset: f64,
    coarse: Vec<f32>,
    prefix: Vec<f64>,
    prefix2: Vec<f64>,
    corr: Vec<f32>,
    /// Candidate is usable (its whole window is inside the frame).
    valid: Vec<bool>,
    cells: Vec<f32>,
    cell_len: usize,
    edges: Vec<(f64, bool)>,
    edge_offsets: Vec<(f64, f64)>,
    /// Usual offset of the edges from the coarse peak, mm (learnt; centres the profiles).
    edge_bias_mm: f64,
    /// The mm scale along the rod learnt from the barcode's length over all frames.
    scale: ScaleFit,
    profile: Vec<f32>,
    /// Phase sample angles `delta` (rad from the facing line): (delta, weight cos delta,
    /// sin delta).
    phase_delta: Vec<(f64, f64, f64)>,
    /// Per radius correction `eps`: (weight, cos, sin) of `cycles * asin(sin(delta) / (1 + eps))`.
    eps_tables: Vec<Vec<(f64, f64, f64)>>,
    /// Per `eps`: the inverse of the weighted normal matrix of the fit `v = m + a cos + b sin`
    /// over the samples (the samples need not hold whole periods, nor be evenly spread in the
    /// print's angle, for the fit to keep the phase unbiased).
    eps_ginv: Vec<[[f64; 3]; 3]>,
    /// Matched-filter energy per `eps`, accumulated over frames.
    eps_acc: Vec<f64>,
    /// This frame's DFT per `eps` (scratch).
    eps_z: Vec<(f64, f64)>,
    /// The best `eps` so far (index into `eps_tables`).
    eps_best: usize,
    /// Phase samples summed over the rows (scratch).
    phase_v: Vec<f64>,
    /// Marker `u` of the rows across white and black rings used to measure the shading.
    white_u: Vec<f64>,
    black_u: Vec<f64>,
    /// Shading of white and black print at each phase sample angle (scratch).
    white: Vec<f64>,
    black: Vec<f64>,
    /// The last measured shading, relative to that frame's barcode levels (0 black, 1 white),
    /// where it was measured, and how many frames ago.
    white_rel: Vec<f64>,
    black_rel: Vec<f64>,
    shading_at_mm: f64,
    shading_age: u32,
    /// Marker `u` of the full rings whose silhouettes give the rod's centre and radius, white
    /// (`true`) or black, and their mean `u`.
    ring_u: Vec<(f64, bool)>,
    ring_u_mid: f64,
    /// The rod's centre line learnt from the rings' silhouettes over all frames so far.
    centre: CentreFit,
    /// Frames processed (for decimating the learning).
    frames_seen: u64,
    /// Frames in which the whole travel was searched (diagnostics).
    full_searches: u64,
    /// The last frame's results between stages, when it got past the edges.
    inter: Option<Intermediate>,
    /// Where the marker is expected in the next frame (last position plus last motion), mm on
    /// the calibrated line; `None` when the last frame did not find it.
    predicted_mm: Option<f64>,
}

/// The mm scale of the calibrated line, learnt over frames: each frame's barcode gives the
/// relative scale error `b` at its place `s` (its 12 edges spread over 64 mm); a line
/// `b(s) = b0 + b1 (s - mean s)` is fitted to all of them, and a position on the calibrated line
/// is turned into true mm by integrating `1 - b(s)` from the reference. This removes what a
/// single reference frame cannot see, e.g. a camera pitched along the rods (depth changing along
/// the rod makes the image scale change along it).
#[derive(Debug, Clone, Copy, Default)]
pub struct ScaleFit {
    line: LineFit,
}

/// A running least-squares line `v(s) = a + b (s - mean s)` over samples `(s, v)`, slowly
/// forgetting old samples once `MAX_N` are in (to follow slow drift).
#[derive(Debug, Clone, Copy, Default)]
struct LineFit {
    n: f64,
    s: f64,
    ss: f64,
    v: f64,
    sv: f64,
}

impl LineFit {
    const MAX_N: f64 = 5000.0;

    /// (mean v, slope, mean s); the slope is 0 until at least 20 samples spread over 10 mm
    /// (std) are in. `None` before 5 samples.
    fn coeffs(&self) -> Option<(f64, f64, f64)> {
        if self.n < 5.0 {
            return None;
        }
        let ms = self.s / self.n;
        let mv = self.v / self.n;
        let var = self.ss / self.n - ms * ms;
        if self.n >= 20.0 && var > 100.0 {
            Some((mv, (self.sv / self.n - ms * mv) / var, ms))
        } else {
            Some((mv, 0.0, ms))
        }
    }

    /// The line's value at `s_mm` (the mean before 5 samples); `None`-safe: 0 with no sample.
    fn value(&self, s_mm: f64) -> f64 {
        match self.coeffs() {
            Some((mv, b, ms)) => mv + b * (s_mm - ms),
            None => self.v / self.n.max(1e-12),
        }
    }

    /// [`LineFit::coeffs`] of the samples and `weight` more samples `(s_mm, v)`; `None`
    /// before the first sample.
    fn coeffs_with(&self, s_mm: f64, v: f64, weight: f64) -> Option<(f64, f64, f64)> {
        if self.n < 1.0 {
            return None;
        }
        LineFit {
            n: self.n + weight,
            s: self.s + weight * s_mm,
            ss: self.ss + weight * s_mm * s_mm,
            v: self.v + weight * v,
            sv: self.sv + weight * s_mm * v,
        }
        .coeffs()
    }

    /// Adds a sample; returns the factor old sums were scaled by (for companions).
    fn add(&mut self, s_mm: f64, v: f64) -> f64 {
        let mut k = 1.0;
        if self.n >= Self::MAX_N {
            k = (Self::MAX_N - 1.0) / self.n;
            self.n *= k;
            self.s *= k;
            self.ss *= k;
            self.v *= k;
            self.sv *= k;
        }
        self.n += 1.0;
        self.s += s_mm;
        self.ss += s_mm * s_mm;
        self.v += v;
        self.sv += s_mm * v;
        k
    }
}

impl ScaleFit {
    fn coeffs(&self) -> Option<(f64, f64, f64)> {
        self.line.coeffs()
    }

    /// Adds one frame's scale error `b` at `s`; refuses outliers.
    pub fn add(&mut self, s_mm: f64, b: f64) -> bool {
        if !(b.is_finite() && b.abs() < 0.05) {
            return false;
        }
        if let Some((b0, b1, ms)) = self.coeffs() {
            if (b - (b0 + b1 * (s_mm - ms))).abs() > 0.01 {
                return false;
            }
        }
        self.line.add(s_mm, b);
        true
    }

    /// Calibration measured the scale at the reference (the barcode's edges there set the mm
    /// scale): the scale error there is 0, worth this many frames' measurements. Without it a
    /// rod that never moves would have its local scale error applied over the whole way from
    /// the reference (twice the correction where the scale changes steadily along the rod).
    const REFERENCE_WEIGHT: f64 = 50.0;

    /// Calibrated-line coordinate `s` to true mm, keeping `s_ref` (the barcode's middle at
    /// the reference pose, where calibration measured the scale) fixed.
    pub fn to_true(&self, s_mm: f64, s_ref_mm: f64) -> f64 {
        match self.line.coeffs_with(s_ref_mm, 0.0, Self::REFERENCE_WEIGHT) {
            None => s_mm,
            Some((b0, b1, ms)) => {
                // integral of b from s_ref to s
                let int = b0 * (s_mm - s_ref_mm)
                    + 0.5 * b1 * ((s_mm - ms).powi(2) - (s_ref_mm - ms).powi(2));
                s_mm - int
            }
        }
    }
}

/// The rod's centre line `offset(s) = a + b s` (px across the calibrated line, as a function
/// of the axis coordinate in mm), and its apparent radius, learnt from the silhouettes of the
/// marker's full rings over frames. The rod's axis does not move in the image, so every frame's
/// silhouettes add to the same line: their noise averages out while the marker travels, and no
/// single frame's noise reaches the phase.
///
/// Each ring is a witness of its own: a ring's silhouette carries a bias that the marker takes
/// along (the print's shading fades a white ring's edges into a dark limb on one side more
/// than on the other; a black ring's neighbours in the print blur into it), so each ring gets
/// its own line, and only how the offsets run along the travel, the slope, is shared. Where
/// something beside the rod (a figure's legs at some angles, a line on the table, a lamp's
/// reflection) bends one ring's offsets as the marker travels, the other rings do not follow
/// it: the slope is the median of the rings' slopes. The witnesses are the rings of the
/// polarity (white or black print) that stands out more from the background, as measured
/// (the less contrast, the more noise and anything beside the rod move an edge), and of
/// those the ones whose silhouettes are about as wide as the widest (see
/// [`CentreFit::WIDEST_WITHIN`]).
///
/// A silhouette is only as good as the background beside the rod: something bright next to
/// one side (a figure, the table's wall, a reflection) moves that edge alone, and a gate on
/// the centre lets such samples in and drag the line away little by little. Such a sample
/// shows as a half width off the ring's learnt one (by half the edge's move), whereas a place
/// where the line itself runs elsewhere (not learnt yet) moves both edges alike and keeps the
/// half width. So the half width must agree with the ring's within a few times its own
/// scatter (learnt from the accepted samples).
#[derive(Debug, Clone, Copy, Default)]
pub struct CentreFit {
    rings: [RingFit; MAX_RINGS],
    /// The half width over the calibrated radius, as a line in `s` (the calibrated radius may
    /// run off the apparent one along the travel), over the witnesses' accepted samples (every
    /// ring's before the witnesses are chosen).
    ratio: LineFit,
    /// The shared slope (median of the rings'), px per mm, worked out after each frame that
    /// adds samples.
    slope: f64,
    /// Rings `0..used` have been given silhouettes.
    used: usize,
    /// The witnesses' polarity (white: true) once chosen (see [`CentreFit::scans`]).
    witnesses: Option<bool>,
    /// Frames that added at least one silhouette.
    frames: f64,
    /// The span of the axis covered by accepted samples, mm.
    s_lo: f64,
    s_hi: f64,
    /// Frames in a row whose silhouettes were all refused.
    refused_frames: u32,
}

/// One ring's silhouettes over frames: its centre offset and half width as lines in `s`, and
/// the scatter of its half width.
#[derive(Debug, Clone, Copy, Default)]
struct RingFit {
    /// A white ring (else black), and the sum of its accepted samples' contrast with the
    /// background (forgotten as the line's samples are), DN.
    white: bool,
    contrast: f64,
    line: LineFit,
    ratio: LineFit,
    /// Sum of the accepted samples' squared half-width deviations, px^2, and their count
    /// (forgotten as the line's samples are).
    width_dev2: f64,
    width_n: f64,
}

impl RingFit {
    /// Samples after which the ring's own offset and half width gate its new samples.
    const OWN_AFTER: f64 = 3.0;

    fn mean_s_v(&self) -> Option<(f64, f64)> {
        (self.line.n >= 1.0).then(|| (self.line.s / self.line.n, self.line.v / self.line.n))
    }
}

impl CentreFit {
    /// The fitted offset at `s` and the radius ratio; (0, 1) before any sample.
    pub fn at(&self, s_mm: f64) -> (f64, f64) {
        if self.frames < 1.0 {
            return (0.0, 1.0);
        }
        // The pooled offset at `s = 0`: each ring's mean offset brought there along the
        // shared slope, weighted by its samples.
        let (mut sum_a, mut sum_w) = (0.0, 0.0);
        for r in &self.rings[..self.used] {
            if let Some((ms, mv)) = r.mean_s_v() {
                sum_a += r.line.n * (mv - self.slope * ms);
                sum_w += r.line.n;
            }
        }
        let intercept_px = sum_a / sum_w.max(1e-12);
        (intercept_px + self.slope * s_mm, self.ratio.value(s_mm))
    }

    /// How far the centre runs across the calibrated line from `from_mm` to `to_mm` along the
    /// axis, px, and the radius ratio at `to_mm`: what the phase needs, cheaper than two
    /// [`CentreFit::at`].
    pub fn run_between(&self, from_mm: f64, to_mm: f64) -> (f64, f64) {
        if self.frames < 1.0 {
            return (0.0, 1.0);
        }
        (self.slope * (to_mm - from_mm), self.ratio.value(to_mm))
    }

    /// The line's slope, px per mm: how far the centre runs across the calibrated line per mm
    /// along the axis.
    pub fn slope(&self) -> f64 {
        self.slope
    }

    /// Samples before the half width's scatter gates new ones.
    const WIDTH_GATE_AFTER: f64 = 20.0;
    /// The half-width gate, in its scatters, and its floor, px.
    const WIDTH_GATE_SIGMAS: f64 = 4.0;
    const WIDTH_GATE_MIN_PX: f64 = 0.15;

    /// Adds one silhouette sample of ring 0 (centre offset, half width over the calibrated
    /// radius `radius_px`); refuses one far from the current fit (hands, figures, a bright
    /// background on one side).
    pub fn add(&mut self, s_mm: f64, offset_px: f64, ratio: f64, radius_px: f64) -> bool {
        self.add_frame(&[Silhouette {
            ring: 0,
            white: true,
            contrast_dn: 100.0,
            s_mm,
            offset_px,
            ratio,
            radius_px,
        }]) > 0
    }

    /// Adds one frame's silhouettes (at most one per ring), each to its ring, over those the
    /// gates let in. The slope then comes from where each ring was over frames, never from the
    /// spread of the rings along one marker (each ring's own bias would make a slope over the
    /// marker's 30 mm, carried far along the travel). Returns how many were let in.
    pub fn add_frame(&mut self, rings: &[Silhouette]) -> usize {
        let (mut n, mut n_r, mut sum_s, mut sum_r) = (0usize, 0usize, 0.0, 0.0);
        for r in rings {
            if r.ring >= MAX_RINGS {
                continue;
            }
            let Ok(dev) = self.gate(r) else {
                continue;
            };
            if self.frames < 1.0 && n == 0 {
                (self.s_lo, self.s_hi) = (r.s_mm, r.s_mm);
            } else {
                self.s_lo = self.s_lo.min(r.s_mm);
                self.s_hi = self.s_hi.max(r.s_mm);
            }
            self.used = self.used.max(r.ring + 1);
            let ring = &mut self.rings[r.ring];
            let k = ring.line.add(r.s_mm, r.offset_px);
            ring.ratio.add(r.s_mm, r.ratio);
            ring.white = r.white;
            ring.contrast = ring.contrast * k + r.contrast_dn;
            ring.width_dev2 *= k;
            ring.width_n *= k;
            if let Some(d) = dev {
                ring.width_dev2 += d * d;
                ring.width_n += 1.0;
            }
            n += 1;
            // The radius from the witnesses once chosen (the polarities' half widths differ).
            if self.witnesses.is_none_or(|w| w == r.white) {
                n_r += 1;
                sum_s += r.s_mm;
                sum_r += r.ratio;
            }
        }
        if n == 0 {
            // Where every silhouette is refused (a hand, a bright background), the place
            // counts as covered after a while: looking again every frame is of no use there.
            self.refused_frames += 1;
            if self.refused_frames >= Self::REFUSED_FRAMES_COVER && self.frames >= 1.0 {
                for r in rings {
                    self.s_lo = self.s_lo.min(r.s_mm);
                    self.s_hi = self.s_hi.max(r.s_mm);
                }
            }
            return 0;
        }
        self.refused_frames = 0;
        if n_r > 0 {
            let inv = 1.0 / n_r as f64;
            self.ratio.add(sum_s * inv, sum_r * inv);
        }
        self.frames = (self.frames + 1.0).min(LineFit::MAX_N);
        self.refit();
        n
    }

    /// The shared slope: the median of the witnesses' own slopes (over the rings whose samples
    /// spread far enough along the axis to have one; 0 before any has).
    fn refit(&mut self) {
        // The witnesses: the rings of the polarity that stands out more from the background
        // (its edges are the least moved by noise and by what lies beside the rod), when at
        // least 3 of them have slopes; else every ring with one.
        let contrast = |white: bool| {
            let (sum, n) = self.rings[..self.used]
                .iter()
                .filter(|r| r.white == white && r.line.n >= 1.0)
                .fold((0.0, 0.0), |a, r| (a.0 + r.contrast, a.1 + r.line.n));
            sum / n.max(1e-12)
        };
        let white = contrast(true) >= contrast(false);
        if self.frames >= Self::CHOOSE_AFTER {
            self.witnesses = Some(white);
        }
        let mut slopes = [0.0f64; MAX_RINGS];
        let mut n = self.ring_slopes(Some(white), Self::WIDEST_WITHIN, &mut slopes);
        if n < 3 {
            n = self.ring_slopes(Some(white), f64::INFINITY, &mut slopes);
        }
        if n < 3 {
            n = self.ring_slopes(None, f64::INFINITY, &mut slopes);
        }
        self.slope = median(&mut slopes[..n]);
    }

    /// Writes the slopes of the rings (of one polarity, or all) whose samples spread far
    /// enough along the axis to have one, and whose mean half width is within `within` (over
    /// the radius) of the widest such ring's, into `out`; returns how many.
    fn ring_slopes(&self, white: Option<bool>, within: f64, out: &mut [f64; MAX_RINGS]) -> usize {
        let rings = &self.rings[..self.used];
        let of = |r: &&RingFit| white.is_none_or(|w| w == r.white) && r.ratio.n >= 1.0;
        let width = |r: &RingFit| r.ratio.v / r.ratio.n;
        let widest = rings.iter().filter(of).map(width).fold(f64::MIN, f64::max);
        let mut n = 0;
        for r in rings.iter().filter(of) {
            if width(r) < widest - within {
                continue;
            }
            if let Some((_, b, _)) = r.line.coeffs().filter(|c| c.1 != 0.0) {
                out[n] = b;
                n += 1;
            }
        }
        n
    }

    /// The gates: `Err` refuses the silhouette; `Ok` gives its half width's deviation from
    /// the ring's learnt one, px, once there is a fit to compare with.
    fn gate(&self, r: &Silhouette) -> Result<Option<f64>, ()> {
        if self.frames < 5.0 {
            let plausible = r.offset_px.abs() <= 3.0 && (r.ratio - 1.0).abs() <= 0.3;
            return if plausible { Ok(None) } else { Err(()) };
        }
        let ring = &self.rings[r.ring];
        // The ring's own place and width once it has a few samples (rings differ by their
        // biases), else the pooled ones.
        let (e, ratio) = match ring.mean_s_v() {
            Some((ms, mv)) if ring.line.n >= RingFit::OWN_AFTER => (
                mv + self.slope * (r.s_mm - ms),
                ring.ratio.v / ring.ratio.n.max(1e-12),
            ),
            _ => self.at(r.s_mm),
        };
        if (r.offset_px - e).abs() > 0.75 || (r.ratio - ratio).abs() > 0.1 {
            return Err(());
        }
        let d = (r.ratio - ratio) * r.radius_px;
        if ring.width_n >= Self::WIDTH_GATE_AFTER {
            let sigma = (ring.width_dev2 / ring.width_n).sqrt();
            if d.abs() > (Self::WIDTH_GATE_SIGMAS * sigma).max(Self::WIDTH_GATE_MIN_PX) {
                return Err(());
            }
        }
        Ok((ring.line.n >= RingFit::OWN_AFTER).then_some(d))
    }

    /// Per ring (diagnostics): white, the samples taken, and its own slope (px per mm) once
    /// its samples spread far enough.
    pub fn rings(&self) -> impl Iterator<Item = (bool, f64, Option<f64>)> + '_ {
        self.rings.iter().map(|r| {
            (
                r.white,
                r.line.n,
                r.line.coeffs().map(|c| c.1).filter(|b| *b != 0.0),
            )
        })
    }

    /// The witnesses are the rings whose silhouettes are about as wide as the widest (within
    /// this share of the radius, 0.1 px on an 11 px radius): anything of a ring's neighbours
    /// in its row (blur along the rod, a ring's image bent by the lens away from the straight
    /// row across the rod, the row a little off the ring's middle) narrows its silhouette and
    /// moves it with the neighbour's shading. With strong lens distortion, six of the ten
    /// white rings of camera 1's rod 7 were 0.008-0.017 narrower than the widest and ran 0.3 px
    /// per 100 mm off the axis; their median made the rod's angle std 0.0105 rad, 0.0025 without
    /// them.
    const WIDEST_WITHIN: f64 = 0.01;

    /// Frames after which the witnesses' polarity is chosen, and how often (in frames that add
    /// to the fit) the other polarity's rings are still measured, to follow their contrast.
    const CHOOSE_AFTER: f64 = 20.0;
    const OTHER_POLARITY_EVERY: u64 = 8;

    /// Whether the next frame that adds to the fit needs the silhouettes of the rings of this
    /// polarity (white: true): both polarities until the witnesses are chosen, then only the
    /// witnesses' but every [`CentreFit::OTHER_POLARITY_EVERY`]th frame (the choice follows the
    /// contrast, which the light may change). Every witness every time: each ring's slope is
    /// limited by its samples' noise (taking half the witnesses in turn made camera 1 rod 3 of
    /// the reference setup 0.0049 rad instead of 0.0033 after automatic calibration).
    pub fn scans(&self, white: bool) -> bool {
        match self.witnesses {
            Some(w) if w != white => (self.frames as u64) % Self::OTHER_POLARITY_EVERY == 0,
            _ => true,
        }
    }

    /// Number of frames that added to the fit.
    pub fn samples(&self) -> f64 {
        self.frames
    }

    /// Frames in a row with every silhouette refused, after which their place counts as
    /// covered.
    const REFUSED_FRAMES_COVER: u32 = 8;
    /// How far beyond the covered span a place still counts as covered, mm.
    const COVER_MARGIN_MM: f64 = 5.0;

    /// True when samples were taken at or near `s_mm` (the line is not extrapolated there).
    pub fn covers(&self, s_mm: f64) -> bool {
        self.frames >= 1.0
            && s_mm >= self.s_lo - Self::COVER_MARGIN_MM
            && s_mm <= self.s_hi + Self::COVER_MARGIN_MM
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
        let paper = calib.paper.as_ref().map(|p| {
            let line = PaperLine::new(p.trajectory_abc, p.view_angle_deg.to_radians(), height);
            let n = (marker.kernel().len() as f64 * p.cell_px).round().max(4.0) as usize;
            let n = n.min(line.pixels.len().saturating_sub(1)).max(1);
            let kernel_px: Vec<f32> = (0..n)
                .map(|i| {
                    let c = ((i as f64 + 0.5) / p.cell_px) as usize;
                    let c = c.min(marker.kernel().len() - 1);
                    let c = if p.direction > 0 {
                        c
                    } else {
                        marker.kernel().len() - 1 - c
                    };
                    if marker.kernel()[c] {
                        1.0
                    } else {
                        0.0
                    }
                })
                .collect();
            let len = line.pixels.len();
            PaperState {
                kernel_px,
                raw: vec![0.0; len],
                filtered: vec![0.0; len],
                binary: vec![0.0; len],
                corr: vec![0.0; len.saturating_sub(n) + 1],
                d: vec![0.0; 2 * p.half_width_px as usize + 1],
                line,
            }
        });
        let enhanced = Self::build_enhanced(calib, &marker, width, height);
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

    fn build_enhanced(
        calib: &RodCalibration,
        marker: &Marker,
        width: usize,
        height: usize,
    ) -> EnhancedState {
        let knots = PreparedKnots::new(&calib.knots);
        let cell_len = 4usize;
        let step = marker.cell_mm() / cell_len as f64;
        let first = calib.travel_mm[0] - SEARCH_MARGIN_MM + marker.barcode_start_mm();
        let last = calib.travel_mm[1]
            + SEARCH_MARGIN_MM
            + marker.barcode_start_mm()
            + marker.barcode_len_mm();
        let n = ((last - first) / step).ceil() as usize + 1;
        let kernel_n = marker.kernel().len() * cell_len;
        let n = n.max(kernel_n + 1);
        let coarse_nodes: Vec<Option<(isize, isize)>> = (0..n)
            .map(|i| {
                let p = knots.at(first + i as f64 * step);
                // Nearest luma node; for Bayer the node offset is applied when reading.
                if p.x < 1.0 || p.y < 1.0 || p.x > width as f64 - 2.0 || p.y > height as f64 - 2.0 {
                    None
                } else {
                    Some((p.x.round() as isize, p.y.round() as isize))
                }
            })
            .collect();
        let n_cand = n - kernel_n + 1;
        let valid: Vec<bool> = (0..n_cand)
            .map(|k| coarse_nodes[k..k + kernel_n].iter().all(|c| c.is_some()))
            .collect();
        let cells: Vec<f32> = marker
            .kernel()
            .iter()
            .map(|&b| if b { 0.0 } else { 1.0 })
            .collect();
        let cycles = (marker.steps() / 4) as f64;
        // Whole periods inside +/- 70 deg of the facing line.
        let period = TAU / cycles;
        let periods = ((140f64.to_radians() / period).floor() as usize).max(1);
        let half = periods as f64 * period * 0.5;
        let count = periods * PHASE_SAMPLES_PER_PERIOD;
        let phase_delta: Vec<(f64, f64, f64)> = (0..count)
            .map(|j| {
                let d = -half + (j as f64 + 0.5) * (2.0 * half / count as f64);
                (d, d.cos(), d.sin())
            })
            .collect();
        let eps_values: Vec<f64> = (0..EPS_GRID).map(eps_of).collect();
        let eps_tables: Vec<Vec<(f64, f64, f64)>> = eps_values
            .iter()
            .map(|eps| {
                phase_delta
                    .iter()
                    .map(|&(d, w, _): &(f64, f64, f64)| {
                        let t = (d.sin() / (1.0 + eps)).clamp(-1.0, 1.0).asin();
                        (w, (cycles * t).cos(), (cycles * t).sin())
                    })
                    .collect()
            })
            .collect();
        let eps_ginv: Vec<[[f64; 3]; 3]> = eps_tables.iter().map(|t| normal_inverse(t)).collect();
        // Rows across the middle of the longest white and black runs of the barcode: the print's
        // shading across the rod (the light is fixed in the world, so it depends on the angle
        // from the facing line, not on the rod's angle) is measured there every frame.
        let run_rows = |black: bool| -> Vec<f64> {
            let k = marker.kernel();
            let mut best = (0usize, 0usize);
            let mut i = 0;
            while i < k.len() {
                if k[i] == black {
                    let j = (i..k.len()).find(|&j| k[j] != black).unwrap_or(k.len());
                    if j - i > best.1 - best.0 {
                        best = (i, j);
                    }
                    i = j;
                } else {
                    i += 1;
                }
            }
            let centre =
                marker.barcode_start_mm() + 0.5 * (best.0 + best.1) as f64 * marker.cell_mm();
            let half = 0.5 * (best.1 - best.0) as f64 * marker.cell_mm();
            if half >= marker.cell_mm() {
                vec![centre - 0.4 * half, centre + 0.4 * half]
            } else {
                vec![centre]
            }
        };
        let n_phase = count;
        let ring_u = silhouette_rings(marker);
        EnhancedState {
            last_k: None,
            ring_u_mid: ring_u.iter().map(|r| r.0).sum::<f64>() / ring_u.len().max(1) as f64,
            ring_u,
            centre: CentreFit::default(),
            frames_seen: 0,
            full_searches: 0,
            inter: None,
            predicted_mm: None,
            white_u: run_rows(false),
            black_u: run_rows(true),
            white: vec![0.0; n_phase],
            black: vec![0.0; n_phase],
            white_rel: vec![0.0; n_phase],
            black_rel: vec![0.0; n_phase],
            shading_at_mm: f64::NAN,
            shading_age: 0,
            knots,
            coarse_s0: first,
            coarse_step: step,
            coarse: vec![0.0; n],
            prefix: vec![0.0; n + 1],
            prefix2: vec![0.0; n + 1],
            corr: vec![0.0; n_cand],
            valid,
            coarse_grid: coarse_nodes.clone(),
            coarse_grid_offset: f64::NAN,
            coarse_nodes,
            cells,
            cell_len,
            edges: marker.barcode_edges_mm(),
            edge_offsets: Vec::with_capacity(64),
            edge_bias_mm: 0.0,
            scale: ScaleFit::default(),
            profile: vec![0.0; (2.0 * EDGE_HALF_CELLS * EDGE_SAMPLES_PER_CELL as f64) as usize + 1],
            eps_tables,
            eps_ginv,
            eps_acc: vec![0.0; eps_values.len()],
            eps_z: vec![(0.0, 0.0); eps_values.len()],
            eps_best: eps_values.len() / 2,
            phase_v: vec![0.0; count],
            phase_delta,
        }
    }

    /// What the enhanced mode has learnt (diagnostics): the centre line's offset across the
    /// calibrated line at `s_mm` (px) and the radius ratio, and the phase's radius correction
    /// `eps` in use.
    pub fn learnt(&self, s_mm: f64) -> (f64, f64, f64) {
        let st = &self.enhanced;
        let (offset, ratio) = st.centre.at(s_mm);
        (offset, ratio, eps_of(st.eps_best))
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

    // ---------------------------------------------------------------- paper mode

    fn process_paper(&mut self, frame: &FrameView) -> RodResult {
        let (Some(st), Some(p)) = (self.paper.as_mut(), self.calib.paper.as_ref()) else {
            return RodResult {
                status: Status::NotFound,
                ..Default::default()
            };
        };
        // 1. Line extraction, nearest pixel.
        for (v, &(x, y)) in st.raw.iter_mut().zip(&st.line.pixels) {
            *v = frame.luma_nearest(x as f32, y as f32);
        }
        // 2. Band-pass and hysteresis.
        paper_bandpass(&st.raw, &mut st.filtered);
        hysteresis(
            &st.filtered,
            -PAPER_HYSTERESIS,
            PAPER_HYSTERESIS,
            &mut st.binary,
        );
        // 3. NCC, argmax C^2.
        ncc_direct(&st.kernel_px, &st.binary, &mut st.corr);
        let Some(pk) = argmax_sq(&st.corr) else {
            return RodResult {
                status: Status::NotFound,
                ..Default::default()
            };
        };
        let c = st.corr[pk] as f64;
        let pm = pk as f64;
        // 4. Coarse angle.
        let len = st.raw.len() as f64;
        let mut samples = [0.0f32; 8];
        let bits = self.marker.bits() as usize;
        for (k, s) in samples.iter_mut().enumerate().take(bits) {
            let j = (pm + p.offset_px + (k as f64 + 1.5) * p.spacing_px).round();
            if j < 0.0 || j >= len {
                return RodResult {
                    status: Status::OutOfView,
                    ncc: c,
                    ..Default::default()
                };
            }
            *s = st.raw[j as usize];
        }
        let thr = paper_threshold(&samples[..bits]);
        let (_, alpha) = decode_bits(&samples[..bits], thr);
        // 5. Fine angle: pixels across the rod at bit space 0's centre row.
        let j0 = (pm + p.offset_px + 1.5 * p.spacing_px).round() as usize;
        let (x0, y0) = st.line.pixels[j0.min(st.line.pixels.len() - 1)];
        let np = p.half_width_px as i32;
        for (i, d) in st.d.iter_mut().enumerate() {
            *d = frame.luma_nearest((x0 + i as i32 - np) as f32, y0 as f32);
        }
        let phi = p.phase_sign as f32 * paper_phase(&st.d, p.period_px as f32);
        let steps = self.marker.steps();
        let theta = paper_fuse(phi, p.phase_offset_rad as f32, alpha, steps) as f64;
        let angle = (theta * TAU / steps as f64 - p.angle_offset_rad).rem_euclid(TAU);
        let position =
            p.direction as f64 * (pm - p.zero_px) * p.mm_per_px + self.calib.reference_position_mm;
        RodResult {
            position_mm: position,
            angle_rad: angle,
            quality: c.abs().min(1.0),
            status: Status::Ok,
            gray_step: alpha,
            theta_steps: theta,
            ncc: c,
            ..Default::default()
        }
    }

    // ------------------------------------------------------------- enhanced mode

    fn process_enhanced(&mut self, frame: &FrameView) -> RodResult {
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
        st.judge(m, calib, &inter, &gray, &ph)
    }

    /// Asks for the frame's cache lines that measuring this rod will read (enhanced mode, when
    /// the last frame found it), where the marker is expected: a narrow strip along the line
    /// for the barcode's correlation and edges and the Gray bits, the full width across the
    /// rod over bit space 0's phase rows, and the shading's and the rings' rows on the frames
    /// that measure them; see [`FrameView::touch_rect`]. Call it for every rod of a frame
    /// before measuring any: the misses then overlap instead of stalling each read in turn.
    /// Returns a mix of bytes of the strips (to keep the work from being optimised away).
    pub fn prefetch(&self, frame: &FrameView) -> u8 {
        let st = &self.enhanced;
        let (Mode::Enhanced, Some(p)) = (self.mode, st.predicted_mm) else {
            return 0;
        };
        let m = &self.marker;
        // The Gray and quiet-zone samples' reach across the line (the widest of the strip's
        // reads), and every read's bilinear footprint.
        let gray_across = GRAY_SAMPLES
            .iter()
            .chain(&QUIET_SAMPLES)
            .fold(0.0f64, |a, s| a.max(s.1.abs()));
        let footprint_px = 2.0;
        let mut acc = 0u8;
        let mut touch = |a_mm: f64, b_mm: f64, radii: f64| {
            acc ^= st.touch_strip(frame, p + a_mm, p + b_mm, radii, footprint_px);
        };
        let search_mm = SEARCH_WINDOWS_MM[0] + 1.0;
        touch(
            m.barcode_start_mm() - search_mm,
            m.length_mm() + 1.0,
            gray_across,
        );
        let (c0, half0) = (m.bit_space_centre_mm(0), 0.25 * m.bit_space_mm() + 1.0);
        // The learnt centre and radius move the phase's samples by a fraction of a radius.
        touch(c0 - half0, c0 + half0, 1.1);
        if st.shading_due(p) {
            for &u in st.white_u.iter().chain(&st.black_u) {
                touch(u - 1.0, u + 1.0, 1.1);
            }
        }
        if st.learns_centre(p, st.frames_seen.wrapping_add(1)) {
            for &(u, _) in st.ring_u.iter().filter(|r| st.centre.scans(r.1)) {
                touch(u - 1.0, u + 1.0, 1.5);
            }
        }
        acc
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

/// Where the coarse search found the barcode.
#[derive(Debug, Clone, Copy)]
struct Located {
    /// Coarse candidate.
    k: usize,
    /// Its correlation.
    ncc: f64,
    /// Marker position on the calibrated line from the coarse peak, mm.
    pos0_mm: f64,
    /// Print levels from the barcode's cells.
    white: f64,
    black: f64,
}

/// The position from the barcode's edges.
#[derive(Debug, Clone, Copy)]
struct EdgeFit {
    /// Marker position on the calibrated line, mm.
    position_mm: f64,
    /// The same in true mm (the learnt scale applied).
    position_out_mm: f64,
    /// Spread of the edges around their fit, mm.
    edge_std_mm: f64,
}

/// One frame's results between stages.
#[derive(Debug, Clone, Copy)]
struct Intermediate {
    loc: Located,
    edges: EdgeFit,
}

impl EnhancedState {
    /// Steps 1-2: coarse line at 1/4 cell (nearest luma node) and the NCC with the cell kernel
    /// in O(samples x cells): first in a window around the last frame's marker, and over the
    /// whole travel when that finds no clear peak inside the window.
    fn locate(&mut self, m: &Marker, frame: &FrameView) -> Result<Located, RodResult> {
        let st = self;
        let node_off = frame.node_offset() as f64;
        let n_cand = st.corr.len();
        let mut found = None;
        if let (Some(_), Some(p)) = (st.last_k, st.predicted_mm) {
            // Around where the last frame's motion says the marker is now.
            let k0 = ((p + m.barcode_start_mm() - st.coarse_s0) / st.coarse_step)
                .round()
                .clamp(0.0, (n_cand - 1) as f64) as usize;
            for window_mm in SEARCH_WINDOWS_MM {
                let window = (window_mm / st.coarse_step).ceil() as usize;
                let (lo, hi) = (k0.saturating_sub(window), (k0 + window).min(n_cand - 1));
                if let Some((k, c, sub)) = coarse_search(st, frame, node_off, lo, hi) {
                    let inside = (k > lo || lo == 0) && (k < hi || hi == n_cand - 1);
                    if inside && c >= 0.8 {
                        found = Some((k, c, sub));
                        break;
                    }
                }
            }
        }
        if found.is_none() {
            st.full_searches += 1;
            found = coarse_search(st, frame, node_off, 0, n_cand - 1);
        }
        st.last_k = None;
        let Some((k, _, sub)) = found else {
            return Err(RodResult {
                status: Status::OutOfView,
                ..Default::default()
            });
        };
        let ncc = st.corr[k] as f64;
        if !st.valid[k] {
            return Err(RodResult {
                status: Status::OutOfView,
                ..Default::default()
            });
        }
        if ncc < 0.5 {
            return Err(RodResult {
                status: Status::NotFound,
                quality: ncc.max(0.0) * 0.5,
                ncc,
                reason: "weak barcode correlation",
                ..Default::default()
            });
        }
        let pos0 = st.coarse_s0 + (k as f64 + sub) * st.coarse_step - m.barcode_start_mm();
        // Black and white levels from the cells' middle samples.
        let (mut w_sum, mut w_n, mut b_sum, mut b_n) = (0.0f64, 0usize, 0.0f64, 0usize);
        for (c, &cell) in st.cells.iter().enumerate() {
            let base = k + c * st.cell_len;
            let v = 0.5 * (st.coarse[base + 1] + st.coarse[base + 2]) as f64;
            if cell > 0.5 {
                w_sum += v;
                w_n += 1;
            } else {
                b_sum += v;
                b_n += 1;
            }
        }
        let white = w_sum / w_n.max(1) as f64;
        let black = b_sum / b_n.max(1) as f64;
        if white - black < 8.0 {
            return Err(RodResult {
                status: Status::NotFound,
                ncc,
                reason: "no contrast",
                ..Default::default()
            });
        }
        Ok(Located {
            k,
            ncc,
            pos0_mm: pos0,
            white,
            black,
        })
    }

    /// Step 3: sub-pixel position from the barcode's edges, and the learnt mm scale.
    fn fit_edges(
        &mut self,
        m: &Marker,
        reference_position_mm: f64,
        frame: &FrameView,
        loc: &Located,
    ) -> Result<EdgeFit, RodResult> {
        let st = self;
        let (pos0, contrast, ncc) = (loc.pos0_mm, loc.white - loc.black, loc.ncc);
        let cell = m.cell_mm();
        let n_prof = st.profile.len();
        let half = EDGE_HALF_CELLS * cell;
        let dstep = 2.0 * half / (n_prof - 1) as f64;
        st.edge_offsets.clear();
        for &(u_e, rising) in &st.edges {
            // The profile is centred where the edge is expected (the coarse peak plus its usual
            // offset from the edges) and read lazily: its two ends, then outward from the
            // middle until the crossing, which is then usually one of the first two pairs.
            let bias = st.edge_bias_mm;
            let s_e = pos0 + bias + u_e;
            // Along the tangent at the edge: the line's knots are straight segments, and the
            // profile spans one cell, so this is the line itself to far below a pixel.
            let lp = st.knots.at(s_e);
            let (dx, dy) = (
                (lp.tx * lp.px_per_mm * dstep) as f32,
                (lp.ty * lp.px_per_mm * dstep) as f32,
            );
            let (x0, y0) = (
                (lp.x - lp.tx * lp.px_per_mm * half) as f32,
                (lp.y - lp.ty * lp.px_per_mm * half) as f32,
            );
            let sample = |i: usize| {
                let t = i as f32;
                frame.luma_bilinear(x0 + t * dx, y0 + t * dy)
            };
            st.profile.fill(f32::NAN);
            st.profile[0] = sample(0);
            st.profile[n_prof - 1] = sample(n_prof - 1);
            let level = 0.5 * (st.profile[0] + st.profile[n_prof - 1]);
            let local = (st.profile[0] - st.profile[n_prof - 1]).abs() as f64;
            if local < 0.35 * contrast {
                continue;
            }
            // White-to-black in +s means the profile falls through the level.
            let sign = if rising { 1.0f32 } else { -1.0 };
            let mid = n_prof / 2;
            let mut found = None;
            for r in 0..mid {
                for i in [mid + r, mid - r - 1] {
                    if i + 1 >= n_prof {
                        continue;
                    }
                    for q in [i, i + 1] {
                        if st.profile[q].is_nan() {
                            st.profile[q] = sample(q);
                        }
                    }
                    let a = (level - st.profile[i]) * sign;
                    let b = (level - st.profile[i + 1]) * sign;
                    if a <= 0.0 && b > 0.0 {
                        let f = a / (a - b);
                        found = Some((i as f64 + f as f64) * dstep - half);
                        break;
                    }
                }
                if found.is_some() {
                    break;
                }
            }
            if let Some(o) = found {
                st.edge_offsets.push((u_e, o + bias));
            }
        }
        let n_edges = st.edge_offsets.len();
        if n_edges < st.edges.len() / 2 {
            return Err(RodResult {
                status: Status::Occluded,
                ncc,
                quality: 0.2,
                reason: "too few barcode edges",
                ..Default::default()
            });
        }
        st.edge_offsets.sort_unstable_by(|a, b| a.1.total_cmp(&b.1));
        let median = st.edge_offsets[n_edges / 2].1;
        // Inliers: offset and local scale by least squares, o = a + b (u - mean u).
        let (mut n_in, mut su, mut so, mut suu, mut suo, mut soo) =
            (0.0f64, 0.0, 0.0, 0.0, 0.0, 0.0);
        for &(u, o) in &st.edge_offsets {
            if (o - median).abs() < 0.25 * cell {
                n_in += 1.0;
                su += u;
                so += o;
                suu += u * u;
                suo += u * o;
                soo += o * o;
            }
        }
        let (mean_off, edge_std, u_mean, slope) = if n_in >= 2.0 {
            let mu = su / n_in;
            let mo = so / n_in;
            let vu = suu / n_in - mu * mu;
            let b = if vu > 1e-9 {
                (suo / n_in - mu * mo) / vu
            } else {
                0.0
            };
            let resid = (soo / n_in - mo * mo - b * b * vu).max(0.0).sqrt();
            (mo, resid, mu, b)
        } else {
            (
                median,
                cell,
                m.barcode_start_mm() + 0.5 * m.barcode_len_mm(),
                0.0,
            )
        };
        // The edges' centroid on the calibrated line, and the local scale error there.
        let s_centroid = pos0 + u_mean + mean_off;
        if n_in >= 8.0 {
            st.scale.add(s_centroid, slope);
            st.edge_bias_mm += 0.1 * (mean_off - st.edge_bias_mm);
            st.edge_bias_mm = st.edge_bias_mm.clamp(-0.25 * cell, 0.25 * cell);
        }
        let s_ref_c = reference_position_mm + u_mean;
        let position_out = st.scale.to_true(s_centroid, s_ref_c) - u_mean;
        let position = s_centroid - u_mean;
        // The rod's centre and apparent radius where the marker is: this frame's silhouettes of
        Ok(EdgeFit {
            position_mm: position,
            position_out_mm: position_out,
            edge_std_mm: edge_std,
        })
    }

    /// Whether frame number `frame_no` (counted from 1) with the marker at `position_mm`
    /// adds its rings' silhouettes to the centre line. Once the line is learnt, every 4th
    /// frame, then every 16th, is enough to follow slow changes; but where the marker has not
    /// been yet, the line is extrapolated and every frame adds to it until it is learnt there
    /// too.
    fn learns_centre(&self, position_mm: f64, frame_no: u64) -> bool {
        let every = match self.centre.samples() {
            _ if !self.centre.covers(position_mm + self.ring_u_mid) => 1,
            n if n < 60.0 => 1,
            n if n < 600.0 => 4,
            _ => 16,
        };
        frame_no % every == 0
    }

    /// Whether the print's shading must be measured with the marker at `position_mm`, or the
    /// last measurement still serves (see [`EnhancedState::shading`]).
    fn shading_due(&self, position_mm: f64) -> bool {
        let near = (position_mm - self.shading_at_mm).abs() <= SHADING_REUSE_MM;
        !(near && self.shading_age < SHADING_REUSE_FRAMES)
    }

    /// Asks for the frame's cache lines over the stretch `a_mm..b_mm` of the line, `radii`
    /// radii to either side and `footprint_px` beyond all round, in pieces short enough that
    /// each one's bounding box stays close to the strip however the line runs in the image.
    fn touch_strip(
        &self,
        frame: &FrameView,
        a_mm: f64,
        b_mm: f64,
        radii: f64,
        footprint_px: f64,
    ) -> u8 {
        let (pa, pb) = (self.knots.at(a_mm), self.knots.at(b_mm));
        // A piece's box holds at most about 8 px of the line's run across the image's minor
        // direction (a line along a row or a column is one piece).
        let minor = (pb.x - pa.x).abs().min((pb.y - pa.y).abs());
        let n = (minor / 8.0).ceil().clamp(1.0, 64.0) as usize;
        let mut acc = 0u8;
        let mut prev = pa;
        for i in 1..=n {
            let next = if i == n {
                pb
            } else {
                self.knots.at(a_mm + (b_mm - a_mm) * i as f64 / n as f64)
            };
            let mid = self
                .knots
                .at(a_mm + (b_mm - a_mm) * (i as f64 - 0.5) / n as f64);
            let (mut x0, mut y0, mut x1, mut y1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
            for lp in [&prev, &mid, &next] {
                let r = radii * lp.radius_px;
                for side in [-r, r] {
                    let (x, y) = lp.offset(0.0, side);
                    x0 = x0.min(x);
                    x1 = x1.max(x);
                    y0 = y0.min(y);
                    y1 = y1.max(y);
                }
            }
            let f = footprint_px;
            acc ^= frame.touch_rect(x0 - f, y0 - f, x1 + f, y1 + f);
            prev = next;
        }
        acc
    }

    /// The rod's centre and apparent radius where the marker is: this frame's silhouettes of
    /// the marker's white rings feed the centre line learnt over all frames.
    fn learn_centre(&mut self, frame: &FrameView, position_mm: f64) {
        let mut rings = [Silhouette::default(); MAX_RINGS];
        let mut n = 0;
        for (ring, &(u, white)) in self.ring_u.iter().take(MAX_RINGS).enumerate() {
            if !self.centre.scans(white) {
                continue;
            }
            let lp = self.knots.at(position_mm + u);
            let scan = if white {
                &WHITE_RING_SCAN
            } else {
                &BLACK_RING_SCAN
            };
            if let Some(sil) = ring_silhouette_measure(frame, &lp, scan) {
                let (c, hw) = (sil.centre_px, sil.half_width_px);
                rings[n] = Silhouette {
                    ring,
                    white,
                    contrast_dn: sil.contrast_dn,
                    s_mm: position_mm + u,
                    offset_px: c,
                    ratio: hw / lp.radius_px,
                    radius_px: lp.radius_px,
                };
                n += 1;
            }
        }
        self.centre.add_frame(&rings[..n]);
    }

    /// The learnt centre's offset at marker `u` relative to the reference pose (calibration
    /// fixed the absolute centre, and with it the angle offset, there; what is learnt is how
    /// the centre runs away from it), and the learnt radius ratio at bit space 0.
    fn centre_at(&self, m: &Marker, reference_position_mm: f64, position_mm: f64) -> CentreAt {
        let c0 = m.bit_space_centre_mm(0);
        let (offset_px, radius_ratio) = self
            .centre
            .run_between(reference_position_mm + c0, position_mm + c0);
        CentreAt {
            offset_px,
            radius_ratio,
        }
    }

    /// Step 4: the Gray bits at the centre of each bit space: the decoded step and each bit's
    /// margin.
    ///
    /// Each bit is read on the barcode's scale (its black 0, its white 1, with the print's
    /// shading across the rod) against a threshold that follows the light along the Gray
    /// code: the print may be lit unlike the barcode (a lamp's glare, a light gradient) by an
    /// offset that bit space 0's stripes measure (their mean is 0.5 when lit as the barcode:
    /// half black, half white) and the white quiet zone after the last bit space measures
    /// (1 when lit as the barcode); between them it is interpolated. `stripes_mean` is bit
    /// space 0's mean from the phase step.
    fn gray_code(
        &self,
        m: &Marker,
        frame: &FrameView,
        inter: &Intermediate,
        stripes_mean: f64,
    ) -> GrayRead {
        let position = inter.edges.position_mm;
        let bits = m.bits() as usize;
        // The shading at the facing line (the middle of the phase samples).
        let mid = self.white.len() / 2;
        let centre = |v: &[f64]| {
            if v.len() % 2 == 0 {
                0.5 * (v[mid - 1] + v[mid])
            } else {
                v[mid]
            }
        };
        let (white, black) = if self.white.is_empty() {
            (inter.loc.white, inter.loc.black)
        } else {
            (centre(&self.white), centre(&self.black))
        };
        let span = (white - black).max(0.2 * (inter.loc.white - inter.loc.black));
        let read = |u: f64, along_mm: f64, at: &[(f64, f64)]| -> Option<f64> {
            let lp = self.knots.at(position + u);
            if !frame.contains(lp.x as f32, lp.y as f32, 2.0 + 0.5 * lp.radius_px as f32) {
                return None;
            }
            let mut acc = 0.0f32;
            for &(da, dc) in at {
                let (x, y) = lp.offset(da * along_mm * lp.px_per_mm, dc * lp.radius_px);
                acc += frame.luma_bilinear(x as f32, y as f32);
            }
            Some((acc as f64 / at.len() as f64 - black) / span)
        };
        // The light's offset on the barcode's scale: at bit space 0 and at the quiet zone.
        let u0 = m.bit_space_centre_mm(0);
        let off0 = (stripes_mean - 0.5).clamp(-1.0, 1.0);
        let gray_end = m.gray_start_mm() + bits as f64 * m.bit_space_mm();
        let quiet = m.length_mm() - gray_end;
        let uq = gray_end + 0.5 * quiet;
        let offq = if quiet >= QUIET_REFERENCE_MIN_MM {
            read(uq, quiet, &QUIET_SAMPLES).map(|w| (w - 1.0).clamp(-1.0, 1.0))
        } else {
            None
        };
        let mut samples = [0.0f32; 8];
        let mut margins = [0.0f64; 8];
        for (kb, s) in samples.iter_mut().enumerate().take(bits) {
            let c = m.bit_space_centre_mm(kb as u32);
            let off = match offq {
                Some(oq) => off0 + (oq - off0) * (c - u0) / (uq - u0),
                None => off0,
            };
            // Outside the frame: read as the threshold, an ambiguous bit.
            let v = read(c, m.bit_space_mm(), &GRAY_SAMPLES).map_or(0.5, |v| v - off);
            *s = v as f32;
            margins[kb] = (v - 0.5).abs() / 0.5;
        }
        let (_, alpha) = decode_bits(&samples[..bits], 0.5);
        GrayRead { alpha, margins }
    }

    /// The shading of white and black print across the rod, from the barcode's runs (into
    /// `white` and `black`, per phase sample). The light is fixed, so while the marker stays
    /// within [`SHADING_REUSE_MM`] of where the shading was last measured (and for at most
    /// [`SHADING_REUSE_FRAMES`] frames), the last measurement is reused, rescaled to this
    /// frame's barcode levels (which follow exposure changes and flicker); `force` measures.
    fn shading(
        &mut self,
        m: &Marker,
        reference_position_mm: f64,
        frame: &FrameView,
        inter: &Intermediate,
        force: bool,
    ) {
        let position = inter.edges.position_mm;
        let (lo, span) = (inter.loc.black, inter.loc.white - inter.loc.black);
        if !force && !self.shading_due(position) {
            self.shading_age += 1;
            for (o, r) in self.white.iter_mut().zip(&self.white_rel) {
                *o = lo + r * span;
            }
            for (o, r) in self.black.iter_mut().zip(&self.black_rel) {
                *o = lo + r * span;
            }
            return;
        }
        let ca = self.centre_at(m, reference_position_mm, position);
        for (rows_u, out) in [
            (&self.white_u, &mut self.white),
            (&self.black_u, &mut self.black),
        ] {
            out.iter_mut().for_each(|v| *v = 0.0);
            for &u in rows_u.iter() {
                let lp = self.knots.at(position + u);
                let (e, r) = (ca.offset_px, lp.radius_px * ca.radius_ratio);
                for (o, &(_, _, sin_d)) in out.iter_mut().zip(&self.phase_delta) {
                    let (x, y) = lp.offset(0.0, e + r * sin_d);
                    *o += frame.luma_bilinear(x as f32, y as f32) as f64;
                }
            }
            let inv = 1.0 / rows_u.len().max(1) as f64;
            // Scale, then a 3-tap smoothing (the shading is smooth; this halves its noise).
            let mut prev = out[0] * inv;
            let n = out.len();
            for j in 0..n {
                let cur = out[j] * inv;
                let next = if j + 1 < n { out[j + 1] * inv } else { cur };
                out[j] = (prev + 2.0 * cur + next) * 0.25;
                prev = cur;
            }
        }
        for (r, o) in self.white_rel.iter_mut().zip(&self.white) {
            *r = (o - lo) / span;
        }
        for (r, o) in self.black_rel.iter_mut().zip(&self.black) {
            *r = (o - lo) / span;
        }
        self.shading_at_mm = position;
        self.shading_age = 0;
    }

    /// Step 5: the phase across the rod over bit space 0, with the cylinder's projection.
    fn phase(
        &mut self,
        m: &Marker,
        reference_position_mm: f64,
        frame: &FrameView,
        inter: &Intermediate,
    ) -> PhaseFit {
        let st = self;
        let position = inter.edges.position_mm;
        let ca = st.centre_at(m, reference_position_mm, position);
        let c0 = m.bit_space_centre_mm(0);
        let min_span = 0.2 * (inter.loc.white - inter.loc.black);
        // The samples sit at x = R sin(delta) across the rod. If the true apparent radius
        // differs by a factor (1 + eps), sample j really sees the surface angle
        // asin(sin(delta_j) / (1 + eps)); a wrong eps stretches the pattern symmetrically and
        // leaks the fundamental into its conjugate (an error at twice the stripe frequency).
        // The radius is static, so eps is learnt over frames: every frame scores a grid of eps
        // by the matched filter's energy, and the phase uses the best one so far.
        let rows = [-0.25, 0.0, 0.25];
        let n_eps = st.eps_tables.len();
        // The rows' raw samples summed per angle, then normalised to the print's own white (1)
        // and black (0) at that angle.
        st.phase_v.fill(0.0);
        for r in rows {
            let u = c0 + r * m.bit_space_mm();
            let lp: LinePoint = st.knots.at(position + u);
            let (e, rad) = (ca.offset_px, lp.radius_px * ca.radius_ratio);
            let (xb, yb) = lp.offset(0.0, e);
            let (xb, yb) = (xb as f32, yb as f32);
            let (sx, sy) = ((-lp.ty * rad) as f32, (lp.tx * rad) as f32);
            for (acc, &(_, _, sin_d)) in st.phase_v.iter_mut().zip(&st.phase_delta) {
                let sd = sin_d as f32;
                *acc += frame.luma_bilinear(xb + sx * sd, yb + sy * sd) as f64;
            }
        }
        let n_rows = rows.len() as f64;
        for (j, pv) in st.phase_v.iter_mut().enumerate() {
            *pv = (*pv - n_rows * st.black[j]) / (st.white[j] - st.black[j]).max(min_span);
        }
        // Weighted least squares of `v = m + a cos + b sin` (the stripes' fundamental): its
        // energy scores eps, its phase is the measurement.
        let fit = |table: &[(f64, f64, f64)], gi: &[[f64; 3]; 3], phase_v: &[f64]| {
            let mut r = [0.0f64; 3];
            let mut sw = 0.0f64;
            for (&(w, c, s_), &pv) in table.iter().zip(phase_v) {
                let wv = w * pv;
                sw += w;
                r[0] += wv;
                r[1] += wv * c;
                r[2] += wv * s_;
            }
            let x: [f64; 3] =
                std::array::from_fn(|i| gi[i][0] * r[0] + gi[i][1] * r[1] + gi[i][2] * r[2]);
            // Energy explained by the fundamental beyond the constant.
            let energy = x[0] * r[0] + x[1] * r[1] + x[2] * r[2] - r[0] * r[0] / sw.max(1e-12);
            (x[0], x[1], x[2], energy)
        };
        // Learn: score the whole grid (while learning, then every 8th frame), accumulate the
        // normalised energies (slowly forgetting), keep the best eps.
        if st.frames_seen < EPS_LEARN_FRAMES || st.frames_seen % EPS_RESCORE_EVERY == 0 {
            for ((z, table), gi) in st.eps_z.iter_mut().zip(&st.eps_tables).zip(&st.eps_ginv) {
                let (_, _, _, e) = fit(table, gi, &st.phase_v);
                *z = (e.max(0.0).sqrt(), 0.0);
            }
            let e_max = st
                .eps_z
                .iter()
                .map(|z| z.0 * z.0 + z.1 * z.1)
                .fold(0.0, f64::max);
            if e_max > 0.0 {
                let keep = if st.frames_seen < EPS_LEARN_FRAMES {
                    EPS_FORGET
                } else {
                    EPS_FORGET.powi(EPS_RESCORE_EVERY as i32)
                };
                for (acc, z) in st.eps_acc.iter_mut().zip(&st.eps_z) {
                    *acc = keep * *acc + (z.0 * z.0 + z.1 * z.1) / e_max;
                }
                st.eps_best = (0..n_eps)
                    .max_by(|&a, &b| st.eps_acc[a].total_cmp(&st.eps_acc[b]))
                    .unwrap_or(n_eps / 2);
            }
        }
        let table = &st.eps_tables[st.eps_best];
        let (mean, a, b, energy) = fit(table, &st.eps_ginv[st.eps_best], &st.phase_v);
        // The variation beyond the constant, weighted as in the fit.
        let (mut sw, mut swv, mut swvv) = (0.0f64, 0.0f64, 0.0f64);
        for (&(w, _, _), &pv) in table.iter().zip(&st.phase_v) {
            sw += w;
            swv += w * pv;
            swvv += w * pv * pv;
        }
        let variation = swvv - swv * swv / sw.max(1e-12);
        let phi = b.atan2(a);
        // Per row (phase_v sums the rows).
        let amplitude = (a * a + b * b).sqrt() / rows.len() as f64;
        PhaseFit {
            phi,
            // A square wave between 0 and 1 has a fundamental of amplitude 2/pi.
            amp_ratio: amplitude / (2.0 / std::f64::consts::PI),
            mean: mean / rows.len() as f64,
            share: if variation > 1e-12 {
                (energy / variation).clamp(0.0, 1.0)
            } else {
                0.0
            },
        }
    }

    /// Step 6: fuses the phase with the Gray code, checks their consistency, and gives the
    /// status and quality.
    fn judge(
        &mut self,
        m: &Marker,
        calib: &RodCalibration,
        inter: &Intermediate,
        gray: &GrayRead,
        ph: &PhaseFit,
    ) -> RodResult {
        let alpha = gray.alpha;
        let (phi, amp_ratio) = (ph.phi, ph.amp_ratio);
        let (ncc, k) = (inter.loc.ncc, inter.loc.k);
        let edge_std = inter.edges.edge_std_mm;
        let cell = m.cell_mm();
        let sigma = calib.enhanced.phase_sign as f64;
        let frac4 = (4.0 * ((-sigma * phi) / TAU).rem_euclid(1.0)
            + calib.enhanced.phase_offset_steps)
            .rem_euclid(4.0);
        let steps = m.steps();
        let theta = fuse_steps(frac4, alpha, steps);
        let angle = (theta * TAU / steps as f64 - calib.enhanced.angle_offset_rad).rem_euclid(TAU);
        // 6. Consistency and status.
        let code_dist = {
            let d = (theta - (alpha as f64 + 0.5)).rem_euclid(steps as f64);
            d.min(steps as f64 - d)
        };
        let near_group_edge = !(0.75..=3.25).contains(&frac4);
        let mut status = Status::Ok;
        let mut reason = "";
        if amp_ratio < 0.25 {
            status = Status::Occluded;
            reason = "weak stripes over bit space 0";
        }
        // What lies over bit space 0 must look like its stripes: a wave between the print's
        // black and white, whose fundamental can be no stronger than a square wave's (ratio
        // 1) and explains most of the variation across the rod (8/pi^2 = 0.81 for sharp
        // stripes, more when blurred). A hand's edge, a glare spot or a shadow over part of it
        // can still give a phase, and one that may agree with the Gray code by chance.
        if amp_ratio > MAX_STRIPE_AMP_RATIO {
            status = Status::Occluded;
            reason = "stripes stronger than the print's over bit space 0";
        }
        if ph.share < MIN_STRIPE_SHARE {
            status = Status::Occluded;
            reason = "no stripe pattern over bit space 0";
        }
        if edge_std > 0.2 * cell {
            status = Status::Occluded;
            reason = "barcode edges inconsistent";
        }
        // Every high bit (those above the two the phase refines) must stand clear of the
        // threshold, but for the one that changes where the phase puts the angle at the edge
        // of a group of 4 steps: that one is legitimately half way there (the Gray code
        // changes one bit at a time, so either reading is one step off at most, which the
        // phase then settles). Glare or a shadow over the code leaves several high bits
        // ambiguous at once, and then no reading is trusted.
        let excused = if near_group_edge {
            group_edge_bit(theta, steps)
        } else {
            0
        };
        let min_high_margin = (2..m.bits() as usize)
            .filter(|&k| excused & (1 << k) == 0)
            .map(|k| gray.margins[k])
            .fold(f64::MAX, f64::min);
        if min_high_margin < 0.35 {
            status = Status::Occluded;
            reason = "a high Gray bit is ambiguous";
        }
        if code_dist > 1.5 {
            status = Status::Occluded;
            reason = "Gray code and phase disagree";
        }
        let q_ncc = ((ncc - 0.5) / 0.45).clamp(0.0, 1.0);
        let q_amp = amp_ratio.clamp(0.0, 1.0);
        let q_edge = (1.0 - edge_std / (0.2 * cell)).clamp(0.0, 1.0);
        let q_code = (1.0 - (code_dist - 0.5).max(0.0)).clamp(0.0, 1.0);
        let quality = (q_ncc * q_amp * q_edge * q_code).sqrt().sqrt();
        if status == Status::Ok {
            self.last_k = Some(k);
        }
        RodResult {
            position_mm: inter.edges.position_out_mm,
            angle_rad: angle,
            quality: if status == Status::Ok {
                quality
            } else {
                quality.min(0.3)
            },
            status,
            gray_step: alpha,
            theta_steps: theta,
            ncc,
            reason,
            amp_ratio,
            stripe_share: ph.share,
            edge_std_mm: edge_std,
        }
    }
}

/// The Gray code step's result.
#[derive(Debug, Clone, Copy)]
struct GrayRead {
    /// The decoded step.
    alpha: u32,
    /// Each bit's distance from the threshold, in half contrasts (bit space `k` at `k`).
    margins: [f64; 8],
}

/// The phase step's result.
#[derive(Debug, Clone, Copy)]
struct PhaseFit {
    /// Phase of the stripes' fundamental, rad.
    phi: f64,
    /// Its amplitude over a full-contrast square wave's.
    amp_ratio: f64,
    /// The stripes' mean level over bit space 0, on the barcode's scale (its black 0, its
    /// white 1 at each point across the rod): 0.5 when bit space 0 is lit as the barcode is.
    mean: f64,
    /// The share of the samples' variation (beyond their mean) that the fundamental explains:
    /// 8/pi^2 = 0.81 for sharp stripes, more when blurred.
    share: f64,
}

/// One ring's silhouette, for [`CentreFit::add_frame`].
#[derive(Debug, Clone, Copy, Default)]
pub struct Silhouette {
    /// Which of the marker's rings (an index below [`MAX_RINGS`], the same ring every frame).
    pub ring: usize,
    /// A white ring (else black).
    pub white: bool,
    /// Its contrast with the background (the lesser of the two sides), DN.
    pub contrast_dn: f64,
    /// Axis coordinate of the ring, mm on the calibrated line.
    pub s_mm: f64,
    /// Centre offset across the calibrated line, px.
    pub offset_px: f64,
    /// Half width over the calibrated radius.
    pub ratio: f64,
    /// The calibrated radius there, px.
    pub radius_px: f64,
}

/// The learnt centre line, seen from one frame's marker position (worked out once per frame).
struct CentreAt {
    /// The offset across the calibrated line relative to the reference pose, px. The learnt
    /// centre is a line in `s`, so this is its slope times the marker's distance from the
    /// reference: the same at every row of the marker.
    offset_px: f64,
    /// The learnt half width over the calibrated radius at bit space 0.
    radius_ratio: f64,
}

/// Samples the coarse line over candidates `lo..=hi` (and the kernel's length beyond) and
/// correlates: the best candidate, its NCC and the sub-sample offset of the peak. Invalid
/// candidates (window not wholly in the frame) never win.
fn coarse_search(
    st: &mut EnhancedState,
    frame: &FrameView,
    node_off: f64,
    lo: usize,
    hi: usize,
) -> Option<(usize, f64, f64)> {
    let kernel_n = st.cells.len() * st.cell_len;
    let end = hi + kernel_n;
    if st.coarse_grid_offset != node_off {
        for (g, n) in st.coarse_grid.iter_mut().zip(&st.coarse_nodes) {
            *g = n.map(|(i, j)| {
                (
                    (i as f64 - node_off).round() as isize,
                    (j as f64 - node_off).round() as isize,
                )
            });
        }
        st.coarse_grid_offset = node_off;
    }
    frame.luma_nodes(&st.coarse_grid[lo..end], &mut st.coarse[lo..end]);
    let len = end - lo;
    prefix_sums(
        &st.coarse[lo..end],
        &mut st.prefix[..len + 1],
        &mut st.prefix2[..len + 1],
    );
    ncc_cells_prefix(
        &st.cells,
        st.cell_len,
        &st.prefix[..len + 1],
        &st.prefix2[..len + 1],
        &mut st.corr[lo..=hi],
    );
    for (c, ok) in st.corr[lo..=hi].iter_mut().zip(&st.valid[lo..=hi]) {
        if !ok {
            *c = -1.0;
        }
    }
    let k = lo + argmax(&st.corr[lo..=hi])?;
    if !st.valid[k] {
        return None;
    }
    let sub = parabolic_offset(&st.corr[lo..=hi], k - lo) as f64;
    Some((k, st.corr[k] as f64, sub))
}

/// Marker `u` of the white rings used to find the rod's silhouette: the middle of the longest
/// white run of the barcode and the gap before the Gray code (next to bit space 0).
pub fn ring_rows(marker: &Marker) -> Vec<f64> {
    let k = marker.kernel();
    let mut rows = Vec::new();
    let mut i = 0;
    let mut best = (0usize, 0usize);
    while i < k.len() {
        if !k[i] {
            let j = (i..k.len()).find(|&j| k[j]).unwrap_or(k.len());
            if j - i > best.1 - best.0 {
                best = (i, j);
            }
            i = j;
        } else {
            i += 1;
        }
    }
    let cell = marker.cell_mm();
    let bc0 = marker.barcode_start_mm();
    for c in best.0..best.1 {
        rows.push(bc0 + (c as f64 + 0.5) * cell);
    }
    let gap0 = bc0 + marker.barcode_len_mm();
    let gap = marker.gray_start_mm() - gap0;
    if gap >= 2.0 {
        rows.push(gap0 + 0.5 * gap);
    }
    rows
}

/// The median of `v` (reordered); 0 for an empty slice.
fn median(v: &mut [f64]) -> f64 {
    let n = v.len();
    v.sort_unstable_by(f64::total_cmp);
    match n {
        0 => 0.0,
        _ if n % 2 == 1 => v[n / 2],
        _ => 0.5 * (v[n / 2 - 1] + v[n / 2]),
    }
}

/// Marker `u` of the full rings whose silhouettes the tracker learns the rod's centre line
/// from, and whether each is white: the middle of every barcode cell, and of the gap before
/// the Gray code when there is one (white). Each is a witness of its own (see [`CentreFit`]):
/// the more there are, the fewer of them something beside the rod can sway.
pub fn silhouette_rings(marker: &Marker) -> Vec<(f64, bool)> {
    let cell = marker.cell_mm();
    let bc0 = marker.barcode_start_mm();
    let mut rows: Vec<(f64, bool)> = marker
        .kernel()
        .iter()
        .enumerate()
        .map(|(c, &black)| (bc0 + (c as f64 + 0.5) * cell, !black))
        .collect();
    let gap0 = bc0 + marker.barcode_len_mm();
    let gap = marker.gray_start_mm() - gap0;
    if gap >= 2.0 {
        rows.push((gap0 + 0.5 * gap, true));
    }
    rows.truncate(MAX_RINGS);
    rows
}

/// The tracker's fast scan for a white ring's silhouette: 0.5 px steps over 0.75 R .. 1.35 R.
pub const WHITE_RING_SCAN: SilhouetteScan = SilhouetteScan {
    bright: true,
    step_px: 0.5,
    min_contrast: 20.0,
    from_radii: 0.75,
    span_radii: 0.6,
};

/// The same for a black ring, with the least contrast that calibration's careful scan asks of
/// either polarity (12 DN). Whether the black rings serve is decided by their measured
/// contrast against the white rings' (see [`CentreFit`]), not by this floor.
pub const BLACK_RING_SCAN: SilhouetteScan = SilhouetteScan {
    bright: false,
    min_contrast: 12.0,
    ..WHITE_RING_SCAN
};

/// The silhouette of a white ring across the rod at `lp`: (centre offset along the normal,
/// half width), px. Each edge is where the profile crosses halfway between the print inside
/// and the background outside; `None` when the ring does not stand out from the background.
/// The tracker's fast scan: 0.5 px steps over 0.75 R .. 1.35 R.
pub fn ring_silhouette(frame: &FrameView, lp: &LinePoint) -> Option<(f64, f64)> {
    ring_silhouette_scan(frame, lp, &WHITE_RING_SCAN)
}

/// How [`ring_silhouette_scan`] looks for a ring's edges.
#[derive(Debug, Clone, Copy)]
pub struct SilhouetteScan {
    /// A white ring (brighter than the background) or a black one (darker).
    pub bright: bool,
    /// Scan step, px.
    pub step_px: f64,
    /// Least difference between the print (at 0.6 R) and the background (at 1.5 R).
    pub min_contrast: f64,
    /// Where the scan for an edge starts, in radii from the line.
    pub from_radii: f64,
    /// How far it goes, in radii.
    pub span_radii: f64,
}

/// The silhouette of a full ring across the rod at `lp`, bright or dark against the
/// background: (centre offset along the normal, half width), px. Each edge is where the
/// profile crosses halfway between the print inside and the background outside.
pub fn ring_silhouette_scan(
    frame: &FrameView,
    lp: &LinePoint,
    scan: &SilhouetteScan,
) -> Option<(f64, f64)> {
    ring_silhouette_measure(frame, lp, scan).map(|m| (m.centre_px, m.half_width_px))
}

/// A ring's silhouette across the rod, from [`ring_silhouette_measure`].
#[derive(Debug, Clone, Copy)]
pub struct RingSilhouette {
    /// Centre offset along the normal, px.
    pub centre_px: f64,
    /// Half width, px.
    pub half_width_px: f64,
    /// The print's contrast with the background, the lesser of the two sides, DN.
    pub contrast_dn: f64,
}

/// [`ring_silhouette_scan`], with the ring's contrast with the background.
pub fn ring_silhouette_measure(
    frame: &FrameView,
    lp: &LinePoint,
    scan: &SilhouetteScan,
) -> Option<RingSilhouette> {
    let r = lp.radius_px;
    let step = scan.step_px;
    let sign = if scan.bright { 1.0 } else { -1.0 };
    let at = |x: f64| {
        let (px, py) = lp.offset(0.0, x);
        sign * frame.luma_bilinear(px as f32, py as f32) as f64
    };
    let mut edge = [0.0f64; 2];
    let mut contrast = f64::MAX;
    for (k, side) in [-1.0f64, 1.0].into_iter().enumerate() {
        let x_out = side * 1.5 * r;
        if !frame.contains(
            (lp.x - lp.ty * x_out) as f32,
            (lp.y + lp.tx * x_out) as f32,
            1.0,
        ) {
            return None;
        }
        let inside = at(side * 0.6 * r);
        let outside = at(x_out);
        if inside - outside < scan.min_contrast {
            return None;
        }
        contrast = contrast.min(inside - outside);
        let level = 0.5 * (inside + outside);
        let x_from = side * scan.from_radii * r;
        let n = ((scan.span_radii * r) / step) as usize;
        let mut prev = (x_from, at(x_from));
        if prev.1 < level {
            return None;
        }
        let mut found = None;
        for i in 1..=n {
            let x = x_from + side * step * i as f64;
            let v = at(x);
            if prev.1 >= level && v < level {
                let f = (prev.1 - level) / (prev.1 - v);
                found = Some(prev.0 + f * (x - prev.0));
                break;
            }
            prev = (x, v);
        }
        edge[k] = found?;
    }
    Some(RingSilhouette {
        centre_px: 0.5 * (edge[0] + edge[1]),
        half_width_px: 0.5 * (edge[1] - edge[0]),
        contrast_dn: contrast,
    })
}

/// The Gray code's bit (as a mask) that changes at the edge between groups of 4 steps nearest
/// to `theta` (in steps, `[0, steps)`): the one bit in which the codes of the steps either
/// side of that edge differ.
fn group_edge_bit(theta: f64, steps: u32) -> u32 {
    let group = ((theta / 4.0).round() as u32 * 4) % steps;
    let before = (group + steps - 1) % steps;
    (group ^ (group >> 1)) ^ (before ^ (before >> 1))
}

/// Fuses a phase fraction `frac4` in `[0, 4)` (position inside a group of 4 Gray steps) with
/// the decoded step `alpha`, by the paper's steps 2-4. Returns `[0, steps)`.
pub fn fuse_steps(frac4: f64, alpha: u32, steps: u32) -> f64 {
    let alpha_p = (alpha & !3) as f64;
    let d = frac4 + alpha_p - alpha as f64;
    let j = (-d / 4.0).round();
    (frac4 + alpha_p + 4.0 * j).rem_euclid(steps as f64)
}

/// The inverse of the weighted normal matrix `sum w [1 c s]^T [1 c s]` of a phase table.
fn normal_inverse(table: &[(f64, f64, f64)]) -> [[f64; 3]; 3] {
    let mut g = [[0.0f64; 3]; 3];
    for &(w, c, s) in table {
        let x = [1.0, c, s];
        for i in 0..3 {
            for j in 0..3 {
                g[i][j] += w * x[i] * x[j];
            }
        }
    }
    let det = g[0][0] * (g[1][1] * g[2][2] - g[1][2] * g[2][1])
        - g[0][1] * (g[1][0] * g[2][2] - g[1][2] * g[2][0])
        + g[0][2] * (g[1][0] * g[2][1] - g[1][1] * g[2][0]);
    let mut inv = [[0.0f64; 3]; 3];
    if det.abs() < 1e-300 {
        return inv;
    }
    for (i, row) in inv.iter_mut().enumerate() {
        for (j, v) in row.iter_mut().enumerate() {
            let (a0, a1) = ((j + 1) % 3, (j + 2) % 3);
            let (b0, b1) = ((i + 1) % 3, (i + 2) % 3);
            *v = (g[a0][b0] * g[a1][b1] - g[a0][b1] * g[a1][b0]) / det;
        }
    }
    inv
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::marker::gray_decode;

    /// At every edge between groups of 4 steps, from either side, the excused bit is a single
    /// high bit (the two low bits are the phase's), and reading it the other way decodes the
    /// step on the other side of the edge: one step off, never a group.
    #[test]
    fn the_group_edge_bit_is_the_one_high_bit_that_changes_there() {
        for bits in [3u32, 5, 6] {
            let steps = 1u32 << bits;
            for g in 0..steps / 4 {
                let edge = 4 * g;
                for theta in [
                    edge as f64 + 0.3,
                    (edge as f64 - 0.3).rem_euclid(steps as f64),
                ] {
                    let mask = group_edge_bit(theta, steps);
                    assert_eq!(mask.count_ones(), 1, "bits {bits} edge {edge}");
                    assert!(mask >= 4, "a high bit: {mask:#b} at edge {edge}");
                    let code = edge ^ (edge >> 1);
                    assert_eq!(gray_decode(code ^ mask), (edge + steps - 1) % steps);
                }
            }
        }
    }
}
