//! The enhanced mode's tuning constants, by stage: the search, the edges, the Gray bits, the
//! shading, the phase and its learnt radius correction, and the judge's thresholds. The
//! learners' own gates and schedules sit with them (associated constants of
//! [`super::CentreFit`], [`super::ScaleFit`] and their parts).

// ---------------------------------------------------------------- locate (steps 1-2)

/// Candidate search margin beyond the travel, mm.
pub(super) const SEARCH_MARGIN_MM: f64 = 10.0;
/// Half widths of the search windows around where the marker is expected (the last frame's
/// position plus its motion), mm, tried in turn: a change of speed of 0.8 m/s, then of
/// 2.4 m/s, from one frame to the next at 200 fps. Beyond them, the whole travel is searched.
/// The prediction is usually right to a fraction of a mm, so the narrow window nearly always
/// holds the peak, at a third of the wide one's cost.
pub(super) const SEARCH_WINDOWS_MM: [f64; 2] = [4.0, 12.0];
/// Largest motion from one frame to the next taken as motion (not a jump), mm.
pub(super) const MAX_MOTION_MM: f64 = 40.0;

// ---------------------------------------------------------------- edges (step 3)

/// Fine-profile half length around an edge, in cells.
pub(super) const EDGE_HALF_CELLS: f64 = 0.5;
/// Fine-profile samples per cell.
pub(super) const EDGE_SAMPLES_PER_CELL: usize = 10;

// ---------------------------------------------------------------- centre line

/// Most rings whose silhouettes one frame adds to the learnt centre line.
pub const MAX_RINGS: usize = 32;

// ---------------------------------------------------------------- Gray bits (step 4)

/// Where a Gray bit is read, around its bit space's centre: (along the rod in bit spaces,
/// across it in radii).
pub(super) const GRAY_SAMPLES: [(f64, f64); 5] = [
    (0.0, 0.0),
    (-0.2, 0.0),
    (0.2, 0.0),
    (0.0, -0.15),
    (0.0, 0.15),
];
/// Where the quiet zone is read, around its middle: (along the rod in quiet-zone lengths,
/// across it in radii). Plain white: two samples are enough.
pub(super) const QUIET_SAMPLES: [(f64, f64); 2] = [(0.0, -0.15), (0.0, 0.15)];
/// Shortest quiet zone after the Gray code that serves as the white reference of the Gray
/// bits' threshold, mm.
pub(super) const QUIET_REFERENCE_MIN_MM: f64 = 2.0;

// ---------------------------------------------------------------- shading

/// How far the marker may move from where the print's shading was measured before it is
/// measured again, mm.
pub(super) const SHADING_REUSE_MM: f64 = 5.0;
/// For how many frames a shading measurement is reused at most.
pub(super) const SHADING_REUSE_FRAMES: u32 = 8;

// ---------------------------------------------------------------- phase (step 5)

/// Phase samples per stripe period.
pub(super) const PHASE_SAMPLES_PER_PERIOD: usize = 8;
/// Rows along the rod over a bit space that the phase (and the refinement by the other bit
/// spaces' edges) reads, in bit spaces from its centre.
pub(super) const PHASE_ROWS: [f64; 3] = [-0.25, 0.0, 0.25];
/// Frames over which the radius correction `eps` is scored every frame; then every
/// [`EPS_RESCORE_EVERY`]th frame.
pub(super) const EPS_LEARN_FRAMES: u64 = 64;
/// After [`EPS_LEARN_FRAMES`], the radius correction `eps` is scored on every this many
/// frames (its scores forgotten by [`EPS_FORGET`] per frame all the same).
pub(super) const EPS_RESCORE_EVERY: u64 = 8;
/// The phase's grid of radius corrections `eps`: `EPS_GRID` values from -0.08 by 0.01 (see
/// [`eps_of`]).
pub(super) const EPS_GRID: usize = 21;
/// The radius correction `eps` of grid point `i` (`0..EPS_GRID`): -0.08 at 0, 0 at 8.
pub(super) fn eps_of(i: usize) -> f64 {
    (i as f64 - 8.0) * 0.01
}
/// Per-frame forgetting factor of the `eps` scores.
pub(super) const EPS_FORGET: f64 = 0.995;
/// The phase fit weighs each sample by the print's contrast there (white minus black, as the
/// shading measured it) to this power, beside the `cos delta` taper: 2 makes it the inverse
/// of the normalised sample's noise variance. On 10 simulated tables as built (known poses,
/// raw rows) the angle std per camera, worst / median: power 0 2.64 / 1.78 mrad, 1 1.98 /
/// 1.43, 2 1.79 / 1.34.
pub(super) const CONTRAST_WEIGHT_POWER: i32 = 2;

// ---------------------------------------------------------------- refinement (step 5b)

/// The profile across each edge of bit spaces 1 and up: its half length in Gray steps and its
/// samples (a quarter step either side and on the edge: an edge further than
/// [`REFINE_MAX_STEPS`] from where it is expected is not used, so the crossing of one that is
/// lies between two of these samples).
pub(super) const REFINE_PROFILE: (f64, usize) = (0.25, 3);
/// An edge found further than this from where the decoded angle puts it (Gray steps) is not
/// the print's edge as the model sees it (glare, a shadow, a finger over it) and is left out:
/// two and a half times the angle's own error (a tenth of a step).
pub(super) const REFINE_MAX_STEPS: f64 = 0.25;

// ---------------------------------------------------------------- judge (step 6)

/// The stripes' fundamental over a square wave's between the print's black and white, above
/// which bit space 0 is not (only) the print: 1 at most for the print itself, with room for
/// the error of the shading it is normalised by.
pub(super) const MAX_STRIPE_AMP_RATIO: f64 = 1.2;
/// The least share of the stripes' variation across the rod that their fundamental must
/// explain: 0.81 for sharp stripes (8/pi^2), more when blurred; below this, noise alone
/// would have to be a third of the variation.
pub(super) const MIN_STRIPE_SHARE: f64 = 0.6;

// ---------------------------------------------------------------- the code across the rod

/// The code's check across the rod uses every this many phase samples.
pub(super) const CODE_CHECK_EVERY: usize = 1;
/// The code's check across the rod reads the print within this angle of the line facing the
/// camera, deg: there the stripes are seen at least half as wide as face on (`cos 60 = 0.5`);
/// nearer the limbs the print is squeezed into a pixel or two, dim and blurred with the
/// background, and its samples vote by noise. (The phase's fit reads further out, each sample
/// weighed by its contrast.)
pub(super) const CODE_CHECK_MAX_DELTA_DEG: f64 = 60.0;
/// Samples this near an edge of a bit space's pattern (in Gray steps) are not checked: the
/// print's blur and the angle's own error (a tenth of a step) stay inside it.
pub(super) const CODE_CHECK_EDGE_STEPS: f64 = 0.5;

// ---------------------------------------------------------------- fresh search

/// A rod not measured `ok` gets a fresh search from its calibration alone on the first such
/// frame and every this many frames after: a marker measurable again is measured within this
/// many frames whatever the learnt state holds.
pub(super) const FRESH_SEARCH_EVERY: u64 = 4;
/// A rod measured ok whose angle moved less than this (Gray steps) from the last frame, and
/// had moved less than this the frame before, is not checked across the rod: a fooled group
/// would need a change of speed by 4 - 2 x this steps per frame in one frame (about 19 000
/// rad/s^2 at 200 fps; a spin-up to 3000 rpm in 20 ms is 15 700).
pub(super) const CODE_CHECK_SLOW_STEPS: f64 = 0.75;
