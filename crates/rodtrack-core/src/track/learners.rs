//! The online learners of the enhanced mode: what is learnt over frames rather than measured
//! in one. [`ScaleFit`] (the mm scale along the calibrated line, from the barcode's edges) and
//! [`CentreFit`] (the rod's centre line and apparent radius, from the rings' silhouettes), both
//! built on a running least-squares line, [`LineFit`].

use super::tuning::MAX_RINGS;

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
/// `CentreFit::WIDEST_WITHIN`).
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
    /// witnesses' but every `CentreFit::OTHER_POLARITY_EVERY`th frame (the choice follows the
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
