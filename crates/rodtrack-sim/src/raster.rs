//! Fast-mode drawing of the moving distractors (figures, hands, ball) by rasterisation: each
//! box face that faces the camera is projected (with the lens distortion, at its corners) and
//! filled as a convex quad, far to near (painter's order). Edges are straight between the
//! distorted corners, a sub-pixel approximation for boxes this small. The rods and markers are
//! never drawn this way: they are ray traced.

use crate::geom::V3;
use rodtrack_core::Camera;

/// A filled face.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Quad {
    /// Corners in pixels, in order around the face.
    pub v: [[f32; 2]; 4],
    /// Distance of the face centre from the camera, mm (for sorting).
    pub dist: f32,
    /// Colour (albedo times shading), before light.
    pub rgb: V3,
    /// Face plane: world normal and a point on it.
    pub n: V3,
    pub c: V3,
    /// Lowest world `z` of the face, mm (a face above a rod's top is never behind it).
    pub zmin: f32,
    /// A disc instead of a quad: centre `v[0]`, radius `v[1][0]` (px).
    pub disc: bool,
    /// A disc's sphere: its displacement over the exposure, world mm, centred on `c` (fast
    /// mode's motion blur; zero for faces).
    pub motion: V3,
}

/// Appends the camera-facing faces of a box. `to_world` maps box-local points to world;
/// `rot` maps box-local directions to world.
#[allow(clippy::too_many_arguments)]
pub(crate) fn box_faces(
    cam: &Camera,
    origin: [f64; 3],
    lo: V3,
    hi: V3,
    to_world: &dyn Fn(V3) -> V3,
    rot: &dyn Fn(V3) -> V3,
    albedo: V3,
    ambient: f32,
    out: &mut Vec<Quad>,
) {
    let mut corners = [[0.0f32; 3]; 8];
    let mut px = [[0.0f32; 2]; 8];
    for (i, c) in corners.iter_mut().enumerate() {
        let l = [
            if i & 1 == 0 { lo[0] } else { hi[0] },
            if i & 2 == 0 { lo[1] } else { hi[1] },
            if i & 4 == 0 { lo[2] } else { hi[2] },
        ];
        *c = to_world(l);
        match cam.project([c[0] as f64, c[1] as f64, c[2] as f64]) {
            Some((u, v)) => px[i] = [u as f32, v as f32],
            None => return,
        }
    }
    for axis in 0..3 {
        for side in 0..2 {
            let mut nl = [0.0f32; 3];
            nl[axis] = if side == 0 { -1.0 } else { 1.0 };
            let n = rot(nl);
            let bit = 1usize << axis;
            let (a, b) = ((axis + 1) % 3, (axis + 2) % 3);
            let (ba, bb) = (1usize << a, 1usize << b);
            let base = if side == 0 { 0 } else { bit };
            let idx = [base, base | ba, base | ba | bb, base | bb];
            let mut cen = [0.0f32; 3];
            for &i in &idx {
                for k in 0..3 {
                    cen[k] += 0.25 * corners[i][k];
                }
            }
            let view = [
                cen[0] - origin[0] as f32,
                cen[1] - origin[1] as f32,
                cen[2] - origin[2] as f32,
            ];
            let facing = n[0] * view[0] + n[1] * view[1] + n[2] * view[2];
            if facing >= 0.0 {
                continue;
            }
            let sh = ambient + (1.0 - ambient) * n[2].max(0.0);
            out.push(Quad {
                v: idx.map(|i| px[i]),
                dist: (view[0] * view[0] + view[1] * view[1] + view[2] * view[2]).sqrt(),
                rgb: albedo.map(|v| v * sh),
                n,
                c: cen,
                zmin: idx
                    .iter()
                    .map(|&i| corners[i][2])
                    .fold(f32::INFINITY, f32::min),
                disc: false,
                motion: [0.0; 3],
            });
        }
    }
}

/// Appends the pixel spans `(y, x0, x1)` (inclusive) inside the quad (or disc), clipped to the
/// image.
pub(crate) fn scan(q: &Quad, w: usize, h: usize, spans: &mut Vec<(u32, u32, u32)>) {
    if q.disc {
        let [cx, cy] = q.v[0];
        let r = q.v[1][0];
        let y0 = (cy - r).ceil().max(0.0) as i64;
        let y1 = ((cy + r).floor() as i64).min(h as i64 - 1);
        for y in y0..=y1 {
            let dy = y as f32 - cy;
            let hw = (r * r - dy * dy).max(0.0).sqrt();
            let x0 = (cx - hw).ceil().max(0.0) as i64;
            let x1 = ((cx + hw).floor() as i64).min(w as i64 - 1);
            if x0 <= x1 {
                spans.push((y as u32, x0 as u32, x1 as u32));
            }
        }
        return;
    }
    let ymin = q.v.iter().map(|p| p[1]).fold(f32::INFINITY, f32::min);
    let ymax = q.v.iter().map(|p| p[1]).fold(f32::NEG_INFINITY, f32::max);
    let y0 = ymin.ceil().max(0.0) as i64;
    let y1 = (ymax.floor() as i64).min(h as i64 - 1);
    for y in y0..=y1 {
        let yf = y as f32;
        let mut xl = f32::INFINITY;
        let mut xr = f32::NEG_INFINITY;
        for e in 0..4 {
            let a = q.v[e];
            let b = q.v[(e + 1) % 4];
            let (lo, hi) = if a[1] <= b[1] { (a, b) } else { (b, a) };
            if yf < lo[1] || yf > hi[1] {
                continue;
            }
            let x = if hi[1] - lo[1] < 1e-6 {
                xl = xl.min(lo[0].min(hi[0]));
                xr = xr.max(lo[0].max(hi[0]));
                continue;
            } else {
                lo[0] + (yf - lo[1]) * (hi[0] - lo[0]) / (hi[1] - lo[1])
            };
            xl = xl.min(x);
            xr = xr.max(x);
        }
        if xl > xr {
            continue;
        }
        let x0 = xl.ceil().max(0.0) as i64;
        let x1 = (xr.floor() as i64).min(w as i64 - 1);
        if x0 <= x1 {
            spans.push((y as u32, x0 as u32, x1 as u32));
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn scan_fills_a_square_exactly() {
        let q = Quad {
            v: [[1.5, 1.5], [5.5, 1.5], [5.5, 4.5], [1.5, 4.5]],
            dist: 0.0,
            rgb: [0.0; 3],
            n: [0.0; 3],
            c: [0.0; 3],
            zmin: 0.0,
            disc: false,
            motion: [0.0; 3],
        };
        let mut spans = Vec::new();
        scan(&q, 100, 100, &mut spans);
        assert_eq!(spans, vec![(2, 2, 5), (3, 2, 5), (4, 2, 5)]);
    }
}
