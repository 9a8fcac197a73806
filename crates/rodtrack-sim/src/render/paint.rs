//! Fast mode's figures, hands and ball: camera-facing box faces rasterised far to near, with
//! occlusion tests against the rods and walls.

use super::renderer::{CameraRenderer, TILE};
use crate::geom::{rod_hit, Shader, WorldGeom, V3};
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
                // A bounding disc around the projected centre: the silhouette itself (the
                // sphere's tangent cone, with perspective and distortion) is found per pixel.
                quads.push(Quad {
                    v: [
                        [u as f32, v as f32],
                        [1.3 * (u2 - u).abs() as f32 + 3.0, 0.0],
                        [r, 0.0],
                        [0.0; 2],
                    ],
                    dist,
                    rgb: shader.ball,
                    n: [0.0, 0.0, 1.0],
                    c,
                    zmin: c[2] - r,
                    disc: true,
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
                    if q.disc {
                        let (d, _, _) = self.grid.sample(x as f32, y as f32);
                        let w = [
                            q.c[0] - self.origin[0],
                            q.c[1] - self.origin[1],
                            q.c[2] - self.origin[2],
                        ];
                        let b = d[0] * w[0] + d[1] * w[1] + d[2] * w[2];
                        let r = q.v[2][0];
                        let disc = b * b - (w[0] * w[0] + w[1] * w[1] + w[2] * w[2] - r * r);
                        if disc < 0.0 {
                            continue;
                        }
                        t_ball = b - disc.sqrt();
                        nz_ball = (self.origin[2] + t_ball * d[2] - q.c[2]) / r;
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
                    match (ch, bayer) {
                        (3, _) => rad[p * 3..p * 3 + 3].copy_from_slice(&rgb),
                        (_, Some(bp)) => rad[p] = rgb[bp[(y & 1) * 2 + (x & 1)] as usize],
                        _ => rad[p] = 0.299 * rgb[0] + 0.587 * rgb[1] + 0.114 * rgb[2],
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
