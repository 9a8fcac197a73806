//! A ball smeared along its path within the exposure. Its outline is no sphere's: its ends
//! fade over the smear's length and its sides are flattened, so the sphere fitted to the
//! edge points is off along the path. But a ball moving straight over the exposure leaves an
//! image symmetric about its place at mid-exposure (each point of its path has its mirror
//! about the middle, and the ball looks the same from either), whatever the edge's level, the
//! ball's brightness or the smear's length: the centre is where the colour positions around
//! it are most nearly the same on opposite sides.

use super::{BallDetector, Blob, Detection};
use crate::ball::colour::OFF_AXIS;
use crate::ball::tuning::{BLUR_RISE_MAX, N_RAYS, SMEAR_ANGLES, SMEAR_ASYMMETRY_MAX};
use crate::{Camera, FrameView};

/// The centre found by symmetry.
#[derive(Debug, Clone, Copy)]
pub(super) struct Symmetric {
    /// The centre, quads.
    pub centre_q: [f64; 2],
    /// RMS difference of the colour positions on opposite sides (0..1).
    pub asymmetry: f64,
}

impl BallDetector {
    /// The colour position at `p` (quads), clamped to `[0, 1]`; `None` off the image or for
    /// a colour that is no mixture of the field's and the ball's (an occluder).
    fn mixture_at(&mut self, view: &FrameView, p: [f64; 2]) -> Option<f64> {
        let a = self.alpha_at(view, p[0], p[1])?;
        (a != OFF_AXIS).then(|| (a as f64).clamp(0.0, 1.0))
    }

    /// The gradient of [`BallDetector::mixture_at`] at `p`, per quad (central differences
    /// over half a quad).
    fn mixture_gradient(&mut self, view: &FrameView, p: [f64; 2]) -> Option<[f64; 2]> {
        const H: f64 = 0.5;
        let xp = self.mixture_at(view, [p[0] + H, p[1]])?;
        let xm = self.mixture_at(view, [p[0] - H, p[1]])?;
        let yp = self.mixture_at(view, [p[0], p[1] + H])?;
        let ym = self.mixture_at(view, [p[0], p[1] - H])?;
        Some([(xp - xm) / (2.0 * H), (yp - ym) / (2.0 * H)])
    }

    /// The centre of symmetry of the colour positions within `2 rq + 1` quads of it, from
    /// `start` (Gauss-Newton on the differences between opposite samples: rings a quad apart,
    /// [`SMEAR_ANGLES`] directions over half a turn). `None` when fewer than half of the pairs
    /// are clear of occluders and the image's border, or when the two sides differ by more
    /// than [`SMEAR_ASYMMETRY_MAX`] (no ball's image).
    pub(super) fn symmetric_centre(
        &mut self,
        view: &FrameView,
        start: [f64; 2],
        rq: f64,
    ) -> Option<Symmetric> {
        // A blob's expected radius is finite and positive (its area was judged by it); the
        // rings' count rests on it.
        if !(rq.is_finite() && rq > 0.0) {
            return None;
        }
        let reach = 2.0 * rq + 1.0;
        let rings = reach.ceil().max(1.0) as usize;
        let mut c = start;
        let mut asymmetry = f64::INFINITY;
        for _ in 0..10 {
            let (mut a, mut b) = ([[0.0; 2]; 2], [0.0; 2]);
            let (mut ss, mut used, mut total) = (0.0, 0usize, 0usize);
            for k in 1..=rings {
                let rad = reach * k as f64 / rings as f64;
                for j in 0..SMEAR_ANGLES {
                    let th = std::f64::consts::PI * j as f64 / SMEAR_ANGLES as f64;
                    let d = [rad * th.cos(), rad * th.sin()];
                    let p = [c[0] + d[0], c[1] + d[1]];
                    let m = [c[0] - d[0], c[1] - d[1]];
                    total += 1;
                    let (Some(ap), Some(am)) = (self.mixture_at(view, p), self.mixture_at(view, m))
                    else {
                        continue;
                    };
                    let (Some(gp), Some(gm)) = (
                        self.mixture_gradient(view, p),
                        self.mixture_gradient(view, m),
                    ) else {
                        continue;
                    };
                    let e = ap - am;
                    let j = [gp[0] - gm[0], gp[1] - gm[1]];
                    used += 1;
                    ss += e * e;
                    for r in 0..2 {
                        b[r] -= j[r] * e;
                        for q in 0..2 {
                            a[r][q] += j[r] * j[q];
                        }
                    }
                }
            }
            if 2 * used < total {
                return None;
            }
            asymmetry = (ss / used as f64).sqrt();
            let dx = crate::linalg_small::solve_dense::<2>(a, b)?;
            // At most a quad per step: the differences are linear only that far.
            let n = dx[0].hypot(dx[1]);
            let s = if n > 1.0 { 1.0 / n } else { 1.0 };
            c = [c[0] + s * dx[0], c[1] + s * dx[1]];
            if n < 1e-3 {
                break;
            }
        }
        (c[0].is_finite() && c[1].is_finite() && asymmetry <= SMEAR_ASYMMETRY_MAX).then_some(
            Symmetric {
                centre_q: c,
                asymmetry,
            },
        )
    }
}

/// Faded ends (bit `k`: octant `k` of the rays) on opposite sides of the blob, as a path's two
/// ends are: an octant and the opposite one or either beside it. A ball standing still beside
/// a shadow or a fading stain fades on one side only.
pub(super) fn opposite_ends(octants: u8) -> bool {
    (0..8).any(|k| {
        let opposite = [(k + 3) % 8, (k + 4) % 8, (k + 5) % 8];
        octants & (1 << k) != 0 && opposite.iter().any(|&o| octants & (1 << o) != 0)
    })
}

/// Where the centre of a sphere's image lies beside the projection of its centre, px: a
/// sphere seen off the optical axis images as an oval whose middle is further out than its
/// centre's image (and the lens bends it more on one side). The middle of its outline's
/// extent over 64 tangent rays, minus the projected centre; `None` when it is not in view.
pub(super) fn outline_offset_px(cam: &Camera, centre: [f64; 3], radius: f64) -> Option<[f64; 2]> {
    use crate::linalg_small::{cross, norm3};
    let o = cam.pose.centre_world();
    let w = [centre[0] - o[0], centre[1] - o[1], centre[2] - o[2]];
    let dist = norm3(w);
    if dist <= radius {
        return None;
    }
    let ax = w.map(|v| v / dist);
    let e1 = {
        let v = cross(ax, [0.0, 0.0, 1.0]);
        let v = if norm3(v) < 1e-9 {
            cross(ax, [1.0, 0.0, 0.0])
        } else {
            v
        };
        let n = norm3(v);
        v.map(|x| x / n)
    };
    let e2 = cross(ax, e1);
    let (sb, cb) = (radius / dist).asin().sin_cos();
    let (u0, v0) = cam.project(centre)?;
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    const N: usize = 64;
    for i in 0..N {
        let (sp, cp) = (std::f64::consts::TAU * i as f64 / N as f64).sin_cos();
        let p: [f64; 3] =
            std::array::from_fn(|k| o[k] + dist * (cb * ax[k] + sb * (cp * e1[k] + sp * e2[k])));
        let (u, v) = cam.project(p)?;
        lo = [lo[0].min(u), lo[1].min(v)];
        hi = [hi[0].max(u), hi[1].max(v)];
    }
    // The middle of the outline's extent: an ellipse's centre (its centre of symmetry).
    Some([0.5 * (lo[0] + hi[0]) - u0, 0.5 * (lo[1] + hi[1]) - v0])
}

impl BallDetector {
    /// The edge at `te` quads along the ray from `centre` in direction `dir` is a moving
    /// ball's faded end: beyond it, within one expected radius `rq` (a smear up to the ball's
    /// diameter over the exposure), only mixtures of the field's and the ball's colours below
    /// half the ball's, fading (each sample at most [`BLUR_RISE_MAX`] above the last), then
    /// the field (two samples). Anything else beyond it (an occluder, the ball's colour again)
    /// and the edge is not a smeared ball's.
    pub(super) fn faded_end(
        &mut self,
        view: &FrameView,
        centre: [f64; 2],
        dir: [f64; 2],
        te: f64,
        rq: f64,
    ) -> bool {
        let at = |d: f64| [centre[0] + (te + d) * dir[0], centre[1] + (te + d) * dir[1]];
        let mut last = 0.5f32;
        let mut d = 1.0;
        while d <= rq + 1.0 {
            let [x, y] = at(d);
            let [x2, y2] = at(d + 1.0);
            if self.is_field_at(view, x, y) && self.is_field_at(view, x2, y2) {
                return d > 1.0;
            }
            match self.alpha_at(view, x, y) {
                Some(a) if a != OFF_AXIS && a < 0.5 && a <= last + BLUR_RISE_MAX => last = a,
                _ => return false,
            }
            d += 1.0;
        }
        false
    }

    /// A ball smeared by its motion (its blob's rays found `edges` edges, sharp or ending in a
    /// fade, see [`BallDetector::faded_end`]): its centre at mid-exposure by symmetry, on the
    /// ball's plane. Needs as many edges as a fit.
    pub(super) fn fit_smeared(
        &mut self,
        view: &FrameView,
        blob: Blob,
        edges: usize,
        fewest: usize,
    ) -> Option<Detection> {
        if edges < fewest {
            return None;
        }
        let sym = self.symmetric_centre(view, [blob.cx_q, blob.cy_q], blob.rq)?;
        let (u, v) = (2.0 * sym.centre_q[0] + 0.5, 2.0 * sym.centre_q[1] + 0.5);
        let r = self.radius_mm;
        let (_, p0) = self.on_ball_plane(u, v)?;
        let off = outline_offset_px(&self.cam, p0, r)?;
        let (_, p) = self.on_ball_plane(u - off[0], v - off[1])?;
        let (pu, pv) = self.cam.project(p)?;
        // The centre must lie within the blob it came from.
        let (bu, bv) = (2.0 * blob.cx_q + 0.5, 2.0 * blob.cy_q + 0.5);
        if (pu - bu).hypot(pv - bv) > 4.0 * blob.rq {
            return None;
        }
        Some(Detection {
            x_mm: p[0],
            y_mm: p[1],
            u_px: pu,
            v_px: pv,
            edge_points: edges,
            seen_fraction: edges as f64 / N_RAYS as f64,
            residual_mm: sym.asymmetry * r,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::outline_offset_px;
    use crate::{Camera, CameraIntrinsics, Pose};

    #[test]
    fn a_path_has_two_opposite_ends() {
        use super::opposite_ends;
        assert!(opposite_ends(0b0001_0001));
        assert!(opposite_ends(0b0000_1001));
        assert!(opposite_ends(0b1000_0100));
        assert!(!opposite_ends(0b0000_0011));
        assert!(!opposite_ends(0b0000_0001));
        assert!(!opposite_ends(0b1000_0001));
    }

    #[test]
    fn a_sphere_off_the_axis_images_further_out_than_its_centre() {
        let k = CameraIntrinsics::from_opencv(
            [[1000.0, 0.0, 720.0], [0.0, 1000.0, 540.0], [0.0, 0.0, 1.0]],
            &[0.0; 5],
        )
        .unwrap();
        // Looking straight down from 1000 mm.
        let cam = Camera {
            intrinsics: k,
            pose: Pose::looking_down([0.0, 0.0, 1000.0], 0.0, 0.0),
            width: 1440,
            height: 1080,
        };
        let on_axis = outline_offset_px(&cam, [0.0, 0.0, 17.5], 17.5).unwrap();
        assert!(
            on_axis[0].abs() < 1e-9 && on_axis[1].abs() < 1e-9,
            "{on_axis:?}"
        );
        // 400 mm to the side: the image's ellipse is centred further out along +u than the
        // centre's image, by f x r^2 / (z (z^2 - r^2)) (0.13 px here), and not across.
        let (u0, _) = cam.project([400.0, 0.0, 17.5]).unwrap();
        let off = outline_offset_px(&cam, [400.0, 0.0, 17.5], 17.5).unwrap();
        assert!(u0 > 720.0, "{u0}");
        let (r, z) = (17.5f64, 1000.0 - 17.5f64);
        let expected = 1000.0 * 400.0 * r * r / (z * (z * z - r * r));
        assert!(
            (off[0] - expected).abs() < 0.05 * expected,
            "{off:?} {expected}"
        );
        assert!(off[1].abs() < 1e-6, "{off:?}");
    }
}
