//! Finding the ball in one frame: colour candidates on a grid of Bayer quads, the compact blob
//! of the ball's expected size, its silhouette's edge points, and the sphere's centre fitted
//! to their rays (no allocation per frame: every buffer is made in [`BallDetector::new`]).

mod area;
mod sample;
mod smear;

pub use area::Reach;

use super::colour::{ColourModel, QuadLayout, OFF_AXIS};
use super::memo::{bilinear, leaves_block, AlphaMemo, Block};
use super::tuning::{
    AREA_RATIO_MAX, AREA_RATIO_MIN, EXTENT_RATIO_MAX, MIN_EDGE_POINTS,
    MIN_EDGE_POINTS_NEAR_PREDICTION, MIN_OCTANTS, NEAR_WINDOW_RADII, N_RAYS, RAY_START_RATIO,
    RESIDUAL_RATIO_MAX, SMEAR_FADED_FRACTION, WINDOW_RADII,
};
use crate::calib::ball::expected_radius_px;
use crate::calib::CameraCalibration;
use crate::{Camera, CameraIntrinsics, CoreError, FrameView};

/// One detection of the ball.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Detection {
    /// The ball's centre in the table frame, mm.
    pub x_mm: f64,
    /// The ball's centre in the table frame, mm.
    pub y_mm: f64,
    /// The projected centre, px.
    pub u_px: f64,
    /// The projected centre, px.
    pub v_px: f64,
    /// Edge points used in the fit.
    pub edge_points: usize,
    /// Fraction of the silhouette's rays that gave an edge point (0..1).
    pub seen_fraction: f64,
    /// RMS distance of the edge rays from the sphere, mm; for a ball smeared by its motion
    /// (placed by its image's symmetry), the RMS difference of the colour positions on
    /// opposite sides (0 field, 1 ball) times the ball's radius. With `edge_points` it sets
    /// the measurement's weight in the tracker.
    pub residual_mm: f64,
}

/// Where the coarse scan looks when the window finds no ball: the part of the field a ball
/// last seen can have reached (`reach`), when that is no larger than the band (`band`, `(k,
/// n)`: band `k` of `n`) or, without a band, than the whole field; else the band; else the
/// whole field.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct ScanArea {
    /// Band `k` of `n` of the field's rows.
    pub band: Option<(usize, usize)>,
    /// The disc the ball is known to be in.
    pub reach: Option<Reach>,
}

/// The detector of one camera; see the module documentation.
#[derive(Debug, Clone)]
pub struct BallDetector {
    layout: QuadLayout,
    colours: ColourModel,
    cam: Camera,
    radius_mm: f64,
    qw: usize,
    qh: usize,
    /// The region searched when lost, quads: `[x0, y0, x1, y1)`.
    field_q: [usize; 4],
    coarse_step: usize,
    /// Bounds of the ball's expected image radius anywhere in the image, quads: a blob is
    /// judged against them before its own expected radius (a ray through the lens) is
    /// computed, so that specks of the ball's colour cost no ray.
    rq_low: f64,
    rq_high: f64,
    /// The plain reference: no early rejection, no memo ([`BallDetector::reference`]).
    plain: bool,
    mask: Vec<u8>,
    stack: Vec<u32>,
    dirs: [[f32; 2]; N_RAYS],
    rays: Vec<[f64; 3]>,
    octant: Vec<u8>,
    resid: Vec<f64>,
    sorted: Vec<f64>,
    /// Each quad's colour position (field 0, ball 1) around the blob being fitted, computed
    /// once per quad the rays reach (NaN until then): the rays' bilinear samples share quads.
    alpha: AlphaMemo,
}

/// A blob of colour candidates.
#[derive(Debug, Clone, Copy)]
struct Blob {
    cx_q: f64,
    cy_q: f64,
    rq: f64,
    score: f64,
}

impl BallDetector {
    /// The detector of a camera's calibration; `None` when it has no `[cameras.ball]`.
    pub fn new(cal: &CameraCalibration) -> Result<Option<BallDetector>, CoreError> {
        let Some(ball) = &cal.ball else {
            return Ok(None);
        };
        let camera = format!("{} ({})", cal.index, cal.name);
        let err = |field: &str, reason: String| CoreError::CameraField {
            camera: camera.clone(),
            field: field.to_string(),
            reason,
        };
        let table = cal
            .table
            .as_ref()
            .ok_or_else(|| err("ball", "needs `[cameras.table]`".into()))?;
        let model = cal
            .opencv_model
            .as_ref()
            .ok_or_else(|| err("ball", "needs the camera model `opencv_model`".into()))?;
        let k = CameraIntrinsics::from_opencv(model.camera_matrix, &model.dist_coeffs)
            .map_err(|e| err("opencv_model", e.to_string()))?;
        let format = cal.format()?;
        let layout = QuadLayout::of(format).ok_or_else(|| {
            err(
                "pixel_format",
                format!("the ball needs a colour format, got {}", format.name()),
            )
        })?;
        let colours = ball.colour_model(&camera)?;
        let cam = table.camera(k, cal.image_width, cal.image_height);
        let radius_mm = 0.5 * ball.diameter_mm;
        let (qw, qh) = (cal.image_width / 2, cal.image_height / 2);
        // The whole image is searched (a camera's table points span only the part of the
        // field it sees); the smallest expected ball over the image's border and centre sets
        // the coarse step.
        let (w, h) = (cal.image_width as f64, cal.image_height as f64);
        let mut rq_min = f64::INFINITY;
        for i in 0..=8 {
            let s = i as f64 / 8.0;
            for (u, v) in [
                (s * (w - 1.0), 0.0),
                (s * (w - 1.0), h - 1.0),
                (0.0, s * (h - 1.0)),
                (w - 1.0, s * (h - 1.0)),
                (0.5 * w, 0.5 * h),
            ] {
                if let Some(r) = expected_radius_px(&cam, u, v, radius_mm) {
                    rq_min = rq_min.min(0.5 * r);
                }
            }
        }
        if !rq_min.is_finite() {
            return Err(err(
                "table",
                "the field plane is not in front of the camera".into(),
            ));
        }
        // The nearest a ball can be is the camera's height above the ball's plane: the largest
        // image radius anywhere. The smallest, from the border samples above, is lowered by a
        // tenth for the border between them.
        let height_mm = cam.pose.centre_world()[2] - radius_mm;
        if height_mm.is_nan() || height_mm <= radius_mm {
            return Err(err(
                "table",
                "the camera is not above the ball's plane".into(),
            ));
        }
        let f = 0.5 * (k.fx + k.fy);
        let rq_high = 0.5 * f * radius_mm / (height_mm * height_mm - radius_mm * radius_mm).sqrt();
        let rq_low = 0.9 * rq_min;
        // The rays reach 1.8 expected radii and one quad beyond the blob's centre, and look two
        // quads past an edge.
        let memo_side = (2.0 * (1.8 * rq_high + 4.0)).ceil() as usize + 3;
        let field_q = [0, 0, qw, qh];
        // Every 4th quad when the ball is large enough to leave a blob of cells at that step.
        let coarse_step = ((rq_min / 2.0).floor() as usize).clamp(1, 4);
        let mut dirs = [[0.0f32; 2]; N_RAYS];
        for (i, d) in dirs.iter_mut().enumerate() {
            let a = std::f32::consts::TAU * i as f32 / N_RAYS as f32;
            *d = [a.cos(), a.sin()];
        }
        Ok(Some(BallDetector {
            layout,
            colours,
            cam,
            radius_mm,
            qw,
            qh,
            field_q,
            coarse_step,
            rq_low,
            rq_high,
            plain: false,
            mask: vec![0; qw * qh],
            stack: Vec::with_capacity(qw * qh),
            dirs,
            rays: Vec::with_capacity(N_RAYS),
            octant: Vec::with_capacity(N_RAYS),
            resid: Vec::with_capacity(N_RAYS),
            sorted: Vec::with_capacity(N_RAYS),
            alpha: AlphaMemo::new(memo_side),
        }))
    }

    /// The same detector in its plain form: every blob judged by its own expected radius and
    /// every sample's colour computed where it is read. Slower, with the same results: the
    /// parity tests hold the fast path to it.
    pub fn reference(mut self) -> BallDetector {
        self.plain = true;
        self
    }

    /// The camera in the table frame.
    pub fn camera(&self) -> &Camera {
        &self.cam
    }

    /// Millimetres on the ball's plane per pixel at the image's centre (from the expected
    /// image radius of the ball there); `None` when the plane is not in front of the camera.
    pub fn mm_per_px_at_centre(&self) -> Option<f64> {
        let r = expected_radius_px(&self.cam, self.qw as f64, self.qh as f64, self.radius_mm)?;
        (r > 0.0 && r.is_finite()).then(|| self.radius_mm / r)
    }

    /// The ball's radius, mm.
    pub fn radius_mm(&self) -> f64 {
        self.radius_mm
    }

    /// The coarse scan's step, quads.
    pub fn coarse_step(&self) -> usize {
        self.coarse_step
    }

    /// Looks for the ball: in a window around `around_px` (the prediction) when given, else
    /// (or when the window finds nothing) over the whole field with the coarse step.
    pub fn detect(&mut self, view: &FrameView, around_px: Option<(f64, f64)>) -> Option<Detection> {
        self.detect_in_band(view, around_px, None)
    }

    /// [`BallDetector::detect`] with the coarse scan limited to band `k` of `n` (`band = (k,
    /// n)`): the field's rows cut in `n` bands, each widened by a ball's extent and a step on
    /// both sides so that a ball on a border lies whole in a band, its rows on the whole
    /// scan's grid (a ball a band holds whole is found there as the whole scan finds it).
    /// `None`, one band, or `k >= n`: the whole field.
    pub fn detect_in_band(
        &mut self,
        view: &FrameView,
        around_px: Option<(f64, f64)>,
        band: Option<(usize, usize)>,
    ) -> Option<Detection> {
        self.detect_in_area(view, around_px, ScanArea { band, reach: None })
    }

    /// [`BallDetector::detect`] with the coarse scan limited to `area` (see [`ScanArea`]).
    pub fn detect_in_area(
        &mut self,
        view: &FrameView,
        around_px: Option<(f64, f64)>,
        area: ScanArea,
    ) -> Option<Detection> {
        if view.width() / 2 != self.qw || view.height() / 2 != self.qh {
            return None;
        }
        if let Some((u, v)) = around_px {
            if let Some(r) = expected_radius_px(&self.cam, u, v, self.radius_mm) {
                let rq = 0.5 * r;
                let (cx, cy) = ((u - 0.5) / 2.0, (v - 0.5) / 2.0);
                let step = ((rq / 4.0).floor() as usize).clamp(1, 2);
                // First the ball where the prediction puts it (a rolling ball is within a
                // fraction of its radius of it), then the window a bounce can reach.
                for radii in [NEAR_WINDOW_RADII, WINDOW_RADII] {
                    let h = radii * rq + 2.0;
                    let region = [
                        (cx - h).floor().max(self.field_q[0] as f64) as usize,
                        (cy - h).floor().max(self.field_q[1] as f64) as usize,
                        ((cx + h).ceil().max(0.0) as usize).min(self.field_q[2]),
                        ((cy + h).ceil().max(0.0) as usize).min(self.field_q[3]),
                    ];
                    if region[2] > region[0] && region[3] > region[1] {
                        if !self.plain {
                            touch_rows(view, region, step);
                        }
                        if let Some(d) = self.scan_and_fit(view, region, step, Some((u, v))) {
                            return Some(d);
                        }
                    }
                }
            }
        }
        let region = self.scan_region(area);
        self.scan_and_fit(view, region, self.coarse_step, None)
    }

    /// The quads the coarse scan of `area` covers (at every coarse step's quad): what its
    /// cost grows with.
    pub fn scan_quads(&self, area: ScanArea) -> usize {
        Self::region_quads(self.scan_region(area))
    }

    /// The quads `[x0, y0, x1, y1)` the coarse scan of `area` covers.
    fn scan_region(&self, area: ScanArea) -> [usize; 4] {
        let wide = area
            .band
            .and_then(|b| self.band_region(b))
            .unwrap_or(self.field_q);
        match area.reach.and_then(|r| self.reach_region(r)) {
            Some(r) if Self::region_quads(r) <= Self::region_quads(wide) => r,
            _ => wide,
        }
    }

    /// The best blob of `region` fitted; `predicted_px`: where the tracker predicts the ball
    /// (see [`MIN_EDGE_POINTS_NEAR_PREDICTION`]).
    fn scan_and_fit(
        &mut self,
        view: &FrameView,
        region: [usize; 4],
        step: usize,
        predicted_px: Option<(f64, f64)>,
    ) -> Option<Detection> {
        let blob = self.best_blob(view, region, step)?;
        self.fit(view, blob, predicted_px)
    }

    /// Marks the ball-coloured quads of `region` every `step` quads and returns the blob whose
    /// size and extent match the ball's expected image there.
    fn best_blob(&mut self, view: &FrameView, region: [usize; 4], step: usize) -> Option<Blob> {
        let [x0, y0, x1, y1] = region;
        let gw = (x1 - x0).div_ceil(step);
        let gh = (y1 - y0).div_ceil(step);
        let n = gw * gh;
        if n == 0 || n > self.mask.len() {
            return None;
        }
        let colours = &self.colours;
        for (gy, row) in self.mask[..n].chunks_exact_mut(gw).enumerate() {
            let qy = y0 + gy * step;
            if self.plain {
                for (gx, m) in row.iter_mut().enumerate() {
                    *m = colours.is_ball(self.layout.rgb(view, x0 + gx * step, qy)) as u8;
                }
            } else {
                self.layout.for_row(view, qy, x0, step, gw, |gx, rgb| {
                    row[gx] = colours.is_ball(rgb) as u8;
                });
            }
        }
        let mut best: Option<Blob> = None;
        for start in 0..n {
            if self.mask[start] != 1 {
                continue;
            }
            self.stack.clear();
            self.stack.push(start as u32);
            self.mask[start] = 2;
            let (mut cnt, mut sx, mut sy) = (0usize, 0usize, 0usize);
            let (mut bx0, mut by0, mut bx1, mut by1) = (usize::MAX, usize::MAX, 0usize, 0usize);
            while let Some(c) = self.stack.pop() {
                let c = c as usize;
                let (gx, gy) = (c % gw, c / gw);
                cnt += 1;
                sx += gx;
                sy += gy;
                bx0 = bx0.min(gx);
                by0 = by0.min(gy);
                bx1 = bx1.max(gx);
                by1 = by1.max(gy);
                for (dx, dy) in [
                    (-1i64, 0i64),
                    (1, 0),
                    (0, -1),
                    (0, 1),
                    (-1, -1),
                    (1, 1),
                    (-1, 1),
                    (1, -1),
                ] {
                    let (nx, ny) = (gx as i64 + dx, gy as i64 + dy);
                    if nx < 0 || ny < 0 || nx >= gw as i64 || ny >= gh as i64 {
                        continue;
                    }
                    let ni = ny as usize * gw + nx as usize;
                    if self.mask[ni] == 1 {
                        self.mask[ni] = 2;
                        self.stack.push(ni as u32);
                    }
                }
            }
            let s = step as f64;
            // What no ball anywhere in the image could leave: too few cells or too long.
            let (ext_x, ext_y) = ((bx1 - bx0 + 1) as f64 * s, (by1 - by0 + 1) as f64 * s);
            let low_area = std::f64::consts::PI * self.rq_low * self.rq_low / (s * s);
            let high_ext = EXTENT_RATIO_MAX * 2.0 * self.rq_high + s;
            let hopeless =
                (cnt as f64) < AREA_RATIO_MIN * low_area || ext_x > high_ext || ext_y > high_ext;
            if hopeless && !self.plain {
                continue;
            }
            let cx_q = x0 as f64 + s * sx as f64 / cnt as f64;
            let cy_q = y0 as f64 + s * sy as f64 / cnt as f64;
            let Some(r) = expected_radius_px(
                &self.cam,
                2.0 * cx_q + 0.5,
                2.0 * cy_q + 0.5,
                self.radius_mm,
            ) else {
                continue;
            };
            let rq = 0.5 * r;
            let expected = std::f64::consts::PI * rq * rq / (s * s);
            let ratio = cnt as f64 / expected;
            let max_ext = EXTENT_RATIO_MAX * 2.0 * rq + s;
            if !(AREA_RATIO_MIN..=AREA_RATIO_MAX).contains(&ratio)
                || ext_x > max_ext
                || ext_y > max_ext
            {
                continue;
            }
            let score = ratio.ln().abs();
            if best.is_none_or(|b| score < b.score) {
                best = Some(Blob {
                    cx_q,
                    cy_q,
                    rq,
                    score,
                });
            }
        }
        best
    }

    /// Edge points on rays from the blob's centre (an edge counts only with the field's colour
    /// beyond it: never the border of a figure, a hand or a rod), then the sphere's centre.
    fn fit(
        &mut self,
        view: &FrameView,
        blob: Blob,
        predicted_px: Option<(f64, f64)>,
    ) -> Option<Detection> {
        let rq = blob.rq;
        let dt = 0.25;
        let half = if self.plain { f64::NAN } else { 1.8 * rq + 2.0 };
        if self.alpha.start(blob.cx_q, blob.cy_q, half) {
            // The disc the rays cross up to the expected edge and the bilinear neighbour.
            let r = rq + 2.0;
            let (cx, cy) = (blob.cx_q, blob.cy_q);
            let square = [cx - r, cy - r, cx + r + 1.0, cy + r + 1.0].map(|v| v.max(0.0) as usize);
            touch_rows(view, square, 1);
            self.prefill_alpha(view, cx, cy, r);
        }
        self.rays.clear();
        self.octant.clear();
        // Edges whose field lies beyond a fade (a smeared ball's ends).
        let (mut faded, mut faded_octants) = (0usize, 0u8);
        // Samples in a block of quads all of the ball's colour are inside whatever their
        // place in it: no bilinear value is computed for them (the plain path computes each).
        let blocks = !self.plain && self.alpha.w > 0;
        // Where every quad within `RAY_START_RATIO` radii of the centre (and the bilinear
        // neighbours) is surely the ball's colour, the rays' samples before it are inside
        // whatever their place: each ray starts there, as the march through them would.
        let far = RAY_START_RATIO * rq;
        let skip = blocks && self.sure_disc(blob.cx_q, blob.cy_q, far + 1.5);
        for i in 0..N_RAYS {
            let [c, s] = self.dirs[i].map(|v| v as f64);
            let mut t = 0.3 * rq;
            // The previous sample's `t` and colour position (NaN: not computed, inside).
            let mut prev: Option<(f64, f32)> = None;
            let mut inside = false;
            if skip {
                // The same sums as the march's.
                let mut last = t;
                while t < far {
                    last = t;
                    t += dt;
                }
                if t > 0.3 * rq {
                    (prev, inside) = (Some((last, f32::NAN)), true);
                }
            }
            let mut edge = None;
            // Samples of the ball's colour since the last occluder (`None`: none crossed).
            let mut since_occluder: Option<usize> = None;
            // The block the last sample fell in.
            let mut block: Option<Block> = None;
            while t <= 1.8 * rq + 1.0 {
                let (x, y) = (blob.cx_q + t * c, blob.cy_q + t * s);
                let mut in_block = None;
                if blocks {
                    let within = |b: &[f64; 4]| x >= b[0] && x < b[2] && y >= b[1] && y < b[3];
                    if !block.is_some_and(|b| within(&b.quads)) {
                        block = self.sure_block(view, x, y);
                    }
                    if let Some(Block {
                        quads: b,
                        sure: true,
                        ..
                    }) = block
                    {
                        // This sample and the next ones the ray surely keeps in the block.
                        let stop =
                            (1.8 * rq + 1.0).min(leaves_block(b, [blob.cx_q, blob.cy_q], [c, s]));
                        let (mut last, mut next, mut n) = (t, t + dt, 1);
                        while next <= stop {
                            (last, next, n) = (next, next + dt, n + 1);
                        }
                        inside = true;
                        if let Some(k) = since_occluder.as_mut() {
                            *k += n;
                        }
                        prev = Some((last, f32::NAN));
                        t = next;
                        continue;
                    }
                    // The sample is in the block (checked or just found): its value from the
                    // block's corners, as `alpha_at` would read them.
                    in_block = block.map(|b| {
                        let (fx, fy) = ((x - b.quads[0]) as f32, (y - b.quads[1]) as f32);
                        bilinear(b.corners, fx, fy)
                    });
                }
                let Some(a) = in_block.or_else(|| self.alpha_at(view, x, y)) else {
                    break;
                };
                if a == OFF_AXIS {
                    // An occluder or the highlight: no edge through it; one beyond it only
                    // after more than a quad of the ball's colour again (not the colour
                    // fringe along an occluder's border).
                    prev = None;
                    since_occluder = Some(0);
                    t += dt;
                    continue;
                }
                if a >= 0.5 {
                    inside = true;
                    if let Some(n) = since_occluder.as_mut() {
                        *n += 1;
                    }
                } else if inside {
                    if since_occluder.is_some_and(|n| (n as f64) * dt <= 1.0) {
                        break;
                    }
                    if let Some((tp, ap)) = prev {
                        let ap = match ap.is_nan() {
                            true => self
                                .alpha_at(view, blob.cx_q + tp * c, blob.cy_q + tp * s)
                                .unwrap_or(ap),
                            false => ap,
                        };
                        let te = tp + (ap as f64 - 0.5) / (ap - a).max(1e-6) as f64 * dt;
                        edge = Some(te);
                    }
                    break;
                }
                prev = Some((t, a));
                t += dt;
            }
            let Some(te) = edge else {
                continue;
            };
            // The field beyond the edge (two samples): not an occluder's border.
            let ok = [1.0, 2.0].iter().all(|d| {
                self.is_field_at(view, blob.cx_q + (te + d) * c, blob.cy_q + (te + d) * s)
            });
            if !ok {
                if self.faded_end(view, [blob.cx_q, blob.cy_q], [c, s], te, rq) {
                    faded += 1;
                    faded_octants |= 1 << (i * 8 / N_RAYS);
                }
                continue;
            }
            let (u, v) = (
                2.0 * (blob.cx_q + te * c) + 0.5,
                2.0 * (blob.cy_q + te * s) + 0.5,
            );
            let (_, d) = self.cam.ray(u, v);
            self.rays.push(d);
            self.octant.push((i * 8 / N_RAYS) as u8);
        }
        let fewest = match predicted_px {
            Some(_) => MIN_EDGE_POINTS_NEAR_PREDICTION,
            None => MIN_EDGE_POINTS,
        };
        // A smeared ball placed by its symmetry; where that fails (an occluder or the
        // image's border beside it), the sphere's fit as for a ball standing still.
        let edges = (self.rays.len() + faded) as f64;
        if faded as f64 >= SMEAR_FADED_FRACTION * edges && smear::opposite_ends(faded_octants) {
            if let Some(d) = self.fit_smeared(view, blob, self.rays.len() + faded, fewest) {
                return Some(d);
            }
        }
        if self.rays.len() < fewest {
            return None;
        }
        let (o, c0) = self.on_ball_plane(2.0 * blob.cx_q + 0.5, 2.0 * blob.cy_q + 0.5)?;
        let mut c = [c0[0], c0[1]];
        let mut used = first_bits(self.rays.len());
        for round in 0..2 {
            c = self.gauss_newton(o, c, used)?;
            self.residuals(o, c);
            if round == 0 {
                self.sorted.clear();
                self.sorted.extend(self.resid.iter().map(|e| e.abs()));
                self.sorted.sort_unstable_by(|a, b| a.total_cmp(b));
                let sigma = 1.4826 * self.sorted[self.sorted.len() / 2];
                let lim = (3.0 * sigma).max(1e-3 * self.radius_mm);
                used = 0;
                for (i, e) in self.resid.iter().enumerate() {
                    if e.abs() <= lim && i < 64 {
                        used |= 1u64 << i;
                    }
                }
            }
        }
        let n = used.count_ones() as usize;
        let mut oct = 0u8;
        let mut ss = 0.0;
        for i in 0..self.rays.len() {
            if used & (1u64 << i) != 0 {
                oct |= 1 << self.octant[i];
                ss += self.resid[i] * self.resid[i];
            }
        }
        let rms = (ss / n.max(1) as f64).sqrt();
        if n < fewest
            || (oct.count_ones() as usize) < MIN_OCTANTS
            || rms > RESIDUAL_RATIO_MAX * self.radius_mm
        {
            return None;
        }
        let (u, v) = self.cam.project([c[0], c[1], self.radius_mm])?;
        // Fewer rays than a fit alone needs only where the prediction stands in for the rest:
        // the centre within the ball's image radius (`2 rq` px) of it.
        let radius_px = 2.0 * rq;
        let near = |(pu, pv): (f64, f64)| (u - pu).hypot(v - pv) <= radius_px;
        if n < MIN_EDGE_POINTS && !predicted_px.is_some_and(near) {
            return None;
        }
        // The fitted centre must lie within the blob it came from.
        let (bu, bv) = (2.0 * blob.cx_q + 0.5, 2.0 * blob.cy_q + 0.5);
        if ((u - bu).powi(2) + (v - bv).powi(2)).sqrt() > 2.0 * rq * 2.0 {
            return None;
        }
        Some(Detection {
            x_mm: c[0],
            y_mm: c[1],
            u_px: u,
            v_px: v,
            edge_points: n,
            seen_fraction: n as f64 / N_RAYS as f64,
            residual_mm: rms,
        })
    }

    /// The camera's centre and the point where pixel `(u, v)`'s ray meets the plane of the
    /// ball's centre (`z` = its radius), table frame, mm; `None` for a ray along the plane.
    fn on_ball_plane(&self, u: f64, v: f64) -> Option<([f64; 3], [f64; 3])> {
        let (o, d) = self.cam.ray(u, v);
        if d[2].abs() < 1e-9 {
            return None;
        }
        let s = (self.radius_mm - o[2]) / d[2];
        Some((o, [o[0] + s * d[0], o[1] + s * d[1], self.radius_mm]))
    }

    /// Signed distance of every edge ray from the sphere at `c` (z = radius), into `resid`.
    fn residuals(&mut self, o: [f64; 3], c: [f64; 2]) {
        self.resid.clear();
        let w = [c[0] - o[0], c[1] - o[1], self.radius_mm - o[2]];
        for d in &self.rays {
            let p = crate::linalg_small::cross(w, *d);
            self.resid
                .push(crate::linalg_small::norm3(p) - self.radius_mm);
        }
    }

    /// Gauss-Newton on the rays' distances from the sphere's centre, over `(x, y)`.
    fn gauss_newton(&self, o: [f64; 3], mut c: [f64; 2], used: u64) -> Option<[f64; 2]> {
        for _ in 0..10 {
            let w = [c[0] - o[0], c[1] - o[1], self.radius_mm - o[2]];
            let (mut a, mut b) = ([[0.0; 2]; 2], [0.0; 2]);
            for (i, d) in self.rays.iter().enumerate() {
                if used & (1u64 << i) == 0 {
                    continue;
                }
                let p = crate::linalg_small::cross(w, *d);
                let np = crate::linalg_small::norm3(p);
                if np < 1e-12 {
                    continue;
                }
                let e = np - self.radius_mm;
                let g = crate::linalg_small::cross(*d, p.map(|v| v / np));
                let j = [g[0], g[1]];
                for r in 0..2 {
                    b[r] -= j[r] * e;
                    for k in 0..2 {
                        a[r][k] += j[r] * j[k];
                    }
                }
            }
            let dx = crate::linalg_small::solve_dense::<2>(a, b)?;
            c = [c[0] + dx[0], c[1] + dx[1]];
            if dx[0].abs() + dx[1].abs() < 1e-6 {
                break;
            }
        }
        (c[0].is_finite() && c[1].is_finite()).then_some(c)
    }
}

/// Reads one byte of every 64 (a cache line) of the pixel rows of the quads `region` covers,
/// every `step`-th quad row, all independent loads: the mosaic is fetched from memory in
/// parallel before the scan or the fit read it in order (a camera's frame is new to the
/// caches).
fn touch_rows(view: &FrameView, region: [usize; 4], step: usize) {
    let [x0, y0, x1, y1] = region;
    let (d, s) = (view.data(), view.stride());
    let bytes_per_px = view.format().bytes_per_pixel();
    let (b0, b1) = (2 * x0 * bytes_per_px, 2 * x1 * bytes_per_px);
    let mut acc = 0u8;
    let rows = (y0..y1)
        .step_by(step.max(1))
        .flat_map(|qy| [2 * qy, 2 * qy + 1]);
    for y in rows {
        let Some(row) = d.get(y * s + b0..(y * s + b1).min(d.len())) else {
            break;
        };
        for b in row.iter().step_by(64) {
            acc ^= *b;
        }
        if let Some(b) = row.last() {
            acc ^= *b;
        }
    }
    std::hint::black_box(acc);
}

/// A mask of the first `n` of 64 bits.
fn first_bits(n: usize) -> u64 {
    if n >= 64 {
        u64::MAX
    } else {
        (1u64 << n) - 1
    }
}
