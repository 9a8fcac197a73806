//! Fast mode's figures, hands and ball: camera-facing box faces rasterised far to near, with
//! occlusion tests against the rods and walls.

use super::renderer::{CameraRenderer, TILE};
use crate::geom::{dot, rod_hit, Shader, WorldGeom, V3};
use crate::raster::{box_faces, scan, Quad};
use crate::scene::Team;

impl CameraRenderer {
    /// Fast mode: rasterises figures, hands and the ball over the image; marks their tiles.
    pub(super) fn paint_objects(&mut self, g: &WorldGeom, shader: &Shader) {
        let mut quads = std::mem::take(&mut self.quads);
        quads.clear();
        self.build_quads(g, shader, &mut quads);
        self.paint_quads(g, shader, &quads);
        self.quads = quads;
    }

    /// The camera-facing faces of every figure, hand and the ball, far to near.
    pub(super) fn build_quads(&self, g: &WorldGeom, shader: &Shader, quads: &mut Vec<Quad>) {
        let cam = self.cam.camera;
        let o = self.origin.map(|v| v as f64);
        let amb = shader.ambient;
        for rod in &g.rods {
            let (c, s) = (rod.cphi, rod.sphi);
            let col = match rod.team {
                Team::Red => shader.red,
                Team::Blue => shader.blue,
            };
            let rot = |n: V3| [n[0] * c + n[2] * s, n[1], -n[0] * s + n[2] * c];
            for &fy in &rod.figs {
                let to_world = |l: V3| {
                    [
                        rod.x + l[0] * c + l[2] * s,
                        fy + l[1],
                        rod.z - l[0] * s + l[2] * c,
                    ]
                };
                for (lo, hi) in &shader.figure {
                    box_faces(&cam, o, *lo, *hi, &to_world, &rot, col, amb, quads);
                }
            }
        }
        let id = |v: V3| v;
        for b in &g.hand_boxes {
            box_faces(&cam, o, b.lo, b.hi, &id, &id, shader.skin, amb, quads);
        }
        if let Some((c, r)) = g.ball {
            let cd = [c[0] as f64, c[1] as f64, c[2] as f64];
            if let (Some((u, v)), Some((u2, _))) = (
                cam.project(cd),
                cam.project([cd[0] + r as f64, cd[1], cd[2]]),
            ) {
                let dv = [
                    c[0] - self.origin[0],
                    c[1] - self.origin[1],
                    c[2] - self.origin[2],
                ];
                let dist = (dv[0] * dv[0] + dv[1] * dv[1] + dv[2] * dv[2]).sqrt() - r;
                // The path's half length in the image, px (the blur's ends).
                let m = g.ball_move;
                let half_px = [-0.5f64, 0.5]
                    .iter()
                    .filter_map(|&s| {
                        let e = [
                            cd[0] + s * m[0] as f64,
                            cd[1] + s * m[1] as f64,
                            cd[2] + s * m[2] as f64,
                        ];
                        cam.project(e).map(|(a, b)| (a - u).hypot(b - v))
                    })
                    .fold(0.0, f64::max);
                // A bounding disc around the projected centre: the silhouette itself (the
                // sphere's tangent cone, with perspective and distortion, swept along its
                // path) is found per pixel.
                quads.push(Quad {
                    v: [
                        [u as f32, v as f32],
                        [(1.3 * (u2 - u).abs() + 1.1 * half_px) as f32 + 3.0, 0.0],
                        [r, 0.0],
                        [0.0; 2],
                    ],
                    dist,
                    rgb: shader.ball,
                    n: [0.0, 0.0, 1.0],
                    c,
                    zmin: c[2] - r,
                    disc: true,
                    motion: m,
                });
            }
        }
        quads.sort_by(|a, b| b.dist.total_cmp(&a.dist));
    }

    /// Fills the quads into the image (fast mode) and marks their tiles dirty.
    fn paint_quads(&mut self, g: &WorldGeom, shader: &Shader, quads: &[Quad]) {
        let amb = shader.ambient;
        let mut spans = std::mem::take(&mut self.spans);
        let mut rad = std::mem::take(&mut self.rad);
        let (ch, w, bayer) = (self.ch, self.w, self.bayer);
        for q in quads {
            spans.clear();
            scan(q, self.w, self.h, &mut spans);
            if spans.is_empty() {
                continue;
            }
            let (u, v) = if q.disc {
                (q.v[0][0], q.v[0][1])
            } else {
                (
                    0.25 * (q.v[0][0] + q.v[1][0] + q.v[2][0] + q.v[3][0]),
                    0.25 * (q.v[0][1] + q.v[1][1] + q.v[2][1] + q.v[3][1]),
                )
            };
            let (_, _, light) = self.grid.sample(u, v);
            let val = q.rgb.map(|c| c * light);
            for &(y, x0, x1) in &spans {
                let y = y as usize;
                let ty = y / TILE;
                for t in
                    ty * self.tiles_x + x0 as usize / TILE..=ty * self.tiles_x + x1 as usize / TILE
                {
                    if !self.tile_dirty[t] {
                        self.tile_dirty[t] = true;
                        self.prev_tiles.push(t as u32);
                    }
                }
                for x in x0 as usize..=x1 as usize {
                    let p = y * self.w + x;
                    // The ball: the pixel's ray against the sphere (its true silhouette).
                    let mut t_ball = 0.0f32;
                    let mut nz_ball = 0.0f32;
                    let mut cover = 1.0f32;
                    if q.disc {
                        let (d, _, _) = self.grid.sample(x as f32, y as f32);
                        let w0 = sub(q.c, self.origin);
                        let r = q.v[2][0];
                        let Some((frac, s_mid)) = sweep_cover(w0, q.motion, d, r) else {
                            continue;
                        };
                        // The sphere where the ray meets it in the middle of that time.
                        let c = [
                            q.c[0] + s_mid * q.motion[0],
                            q.c[1] + s_mid * q.motion[1],
                            q.c[2] + s_mid * q.motion[2],
                        ];
                        let w = sub(c, self.origin);
                        let b = dot(d, w);
                        let disc = (b * b - (dot(w, w) - r * r)).max(0.0);
                        t_ball = b - disc.sqrt();
                        nz_ball = (self.origin[2] + t_ball * d[2] - c[2]) / r;
                        cover = frac;
                    }
                    let mut rm = self.rod_mask[p];
                    if rm != 0 {
                        // A ray from above meets a face that lies above the rod's top first.
                        let rod = &g.rods[rm as usize - 1];
                        if q.zmin > rod.z + rod.r {
                            rm = 0;
                        }
                    }
                    let wall = self.tile_wall[ty * self.tiles_x + x / TILE];
                    if rm != 0 || wall {
                        let (d, _, _) = self.grid.sample(x as f32, y as f32);
                        let nd = q.n[0] * d[0] + q.n[1] * d[1] + q.n[2] * d[2];
                        let t_face = if q.disc {
                            t_ball
                        } else if nd.abs() < 1e-6 {
                            q.dist
                        } else {
                            (q.n[0] * (q.c[0] - self.origin[0])
                                + q.n[1] * (q.c[1] - self.origin[1])
                                + q.n[2] * (q.c[2] - self.origin[2]))
                                / nd
                        };
                        if rm != 0 {
                            let rod = &g.rods[rm as usize - 1];
                            if let Some((t, yh)) = rod_hit(rod.x, rod.z, rod.r, self.origin, d) {
                                if t < t_face && yh >= rod.y_lo && yh <= rod.y_hi {
                                    continue;
                                }
                            }
                        }
                        if wall && self.table.trace_walls(self.origin, d) < t_face {
                            continue;
                        }
                    }
                    let rgb = if q.disc {
                        // Lit from above, as the quality mode's tracer shades it.
                        let sh = amb + (1.0 - amb) * nz_ball.max(0.0);
                        val.map(|c| c * sh)
                    } else {
                        val
                    };
                    // A moving ball covers the pixel for part of the exposure only: over what
                    // is behind it (already in the image) for the rest.
                    let mix = |old: f32, new: f32| {
                        if cover >= 1.0 {
                            new
                        } else {
                            cover * new + (1.0 - cover) * old
                        }
                    };
                    match (ch, bayer) {
                        (3, _) => {
                            for c in 0..3 {
                                rad[p * 3 + c] = mix(rad[p * 3 + c], rgb[c]);
                            }
                        }
                        (_, Some(bp)) => {
                            rad[p] = mix(rad[p], rgb[bp[(y & 1) * 2 + (x & 1)] as usize])
                        }
                        _ => rad[p] = mix(rad[p], 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2]),
                    }
                }
            }
        }
        self.rad = rad;
        let _ = w;
        for &t in &self.prev_tiles {
            self.tile_dirty[t as usize] = false;
        }
        self.spans = spans;
    }
}

fn sub(a: V3, b: V3) -> V3 {
    [a[0] - b[0], a[1] - b[1], a[2] - b[2]]
}

/// The part of the exposure during which a pixel's ray (unit direction `d` from the camera)
/// meets a sphere of radius `r` whose centre, `w0` from the camera at mid-exposure, moves by
/// `motion` over the exposure: `(fraction, s)` with `s` the middle of that time in `[-1/2,
/// 1/2]` of the exposure; `None` if it never does. A ball standing still covers the whole
/// exposure or none of it.
pub(crate) fn sweep_cover(w0: V3, motion: V3, d: V3, r: f32) -> Option<(f32, f32)> {
    // The centre's offset from the ray, across it: `a + s b`.
    let perp = |v: V3| {
        let k = dot(v, d);
        [v[0] - k * d[0], v[1] - k * d[1], v[2] - k * d[2]]
    };
    let (a, b) = (perp(w0), perp(motion));
    let (qa, qb, qc) = (dot(b, b), 2.0 * dot(a, b), dot(a, a) - r * r);
    if qa <= 1e-12 * r * r {
        return (qc < 0.0).then_some((1.0, 0.0));
    }
    let disc = qb * qb - 4.0 * qa * qc;
    if disc <= 0.0 {
        return None;
    }
    let root = disc.sqrt();
    let s0 = ((-qb - root) / (2.0 * qa)).max(-0.5);
    let s1 = ((-qb + root) / (2.0 * qa)).min(0.5);
    (s1 > s0).then_some((s1 - s0, 0.5 * (s0 + s1)))
}

#[cfg(test)]
mod tests {
    use super::sweep_cover;

    #[test]
    fn a_swept_sphere_covers_a_ray_for_the_time_it_crosses_it() {
        let d = [0.0, 0.0, 1.0];
        // Still: all or nothing.
        assert_eq!(
            sweep_cover([3.0, 0.0, 100.0], [0.0; 3], d, 5.0),
            Some((1.0, 0.0))
        );
        assert_eq!(sweep_cover([6.0, 0.0, 100.0], [0.0; 3], d, 5.0), None);
        // Moving 40 mm along x through the ray: the ray is inside for |x| < 5, 10 of 40 mm.
        let (f, s) = sweep_cover([0.0, 0.0, 100.0], [40.0, 0.0, 0.0], d, 5.0).unwrap();
        assert!((f - 0.25).abs() < 1e-6 && s.abs() < 1e-6);
        // The same path, the ray at x = 12 mm from the mid-exposure centre: [7, 17] of
        // [-20, 20], the middle at +12 mm (s = 0.3).
        let (f, s) = sweep_cover([-12.0, 0.0, 100.0], [40.0, 0.0, 0.0], d, 5.0).unwrap();
        assert!((f - 0.25).abs() < 1e-5 && (s - 0.3).abs() < 1e-5, "{f} {s}");
        // Near the path's end, cut by the exposure: [15, 20] of the path, 5 of 40 mm.
        let (f, s) = sweep_cover([-20.0, 0.0, 100.0], [40.0, 0.0, 0.0], d, 5.0).unwrap();
        assert!(
            (f - 0.125).abs() < 1e-5 && (s - 0.4375).abs() < 1e-5,
            "{f} {s}"
        );
        // Beside the path.
        assert_eq!(
            sweep_cover([0.0, 6.0, 100.0], [40.0, 0.0, 0.0], d, 5.0),
            None
        );
    }
}
