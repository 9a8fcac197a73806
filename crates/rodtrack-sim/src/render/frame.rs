//! One frame: restore last frame's changes, shade the markers, trace or paint the moving
//! objects, then finish (light, noise, quantisation).

use super::renderer::{CameraRenderer, Rect, RenderMode, RenderStats, QSUB, TILE};
use crate::geom::{rod_hit, Obj, Shader, WorldGeom};
use crate::raster::scan;

/// Time slot of each quality sub-sample (a 4x4 ordered-dither matrix: neighbours differ).
const QTIME: [usize; 16] = [0, 8, 2, 10, 12, 4, 14, 6, 3, 11, 1, 9, 15, 7, 13, 5];

impl CameraRenderer {
    /// Projected bounding rectangle of world points, with a margin; `None` if off-image.
    fn project_rect(&self, pts: &[[f64; 3]]) -> Option<Rect> {
        let (mut u0, mut v0, mut u1, mut v1) = (f64::MAX, f64::MAX, f64::MIN, f64::MIN);
        for p in pts {
            let (u, v) = self.cam.camera.project(*p)?;
            u0 = u0.min(u);
            u1 = u1.max(u);
            v0 = v0.min(v);
            v1 = v1.max(v);
        }
        let m = 2.0 + 0.03 * (u1 - u0).max(v1 - v0);
        let r = Rect {
            x0: (u0 - m).floor().clamp(0.0, self.w as f64) as usize,
            y0: (v0 - m).floor().clamp(0.0, self.h as f64) as usize,
            x1: (u1 + m).ceil().clamp(0.0, self.w as f64) as usize,
            y1: (v1 + m).ceil().clamp(0.0, self.h as f64) as usize,
        };
        (!r.is_empty()).then_some(r)
    }

    fn mark(&mut self, r: Rect, o: Obj) {
        for ty in r.y0 / TILE..r.y1.div_ceil(TILE) {
            for tx in r.x0 / TILE..r.x1.div_ceil(TILE) {
                let t = ty * self.tiles_x + tx;
                if self.tile_objs[t].is_empty() {
                    self.touched.push(t as u32);
                }
                self.tile_objs[t].push(o);
            }
        }
    }

    /// Marks the tiles covered by moving things (over all time samples), with the objects
    /// that may be seen in each.
    fn collect_tiles(&mut self, geoms: &[WorldGeom], shader: &Shader) {
        for &t in &self.touched {
            self.tile_objs[t as usize].clear();
        }
        self.touched.clear();
        let (blo, bhi) = shader.figure_bounds;
        let last = geoms.len() - 1;
        let picks = if last >= 2 {
            [0, last / 2, last]
        } else {
            [0, last, last]
        };
        let g0 = &geoms[0];
        let mut pts: Vec<[f64; 3]> = Vec::with_capacity(24);
        for i in 0..g0.rods.len() {
            for k in 0..g0.rods[i].figs.len() {
                pts.clear();
                for &gi in &picks {
                    let rg = &geoms[gi].rods[i];
                    for c in 0..8 {
                        let lx = if c & 1 == 0 { blo[0] } else { bhi[0] };
                        let ly = if c & 2 == 0 { blo[1] } else { bhi[1] };
                        let lz = if c & 4 == 0 { blo[2] } else { bhi[2] };
                        // Local to world: rotation by +phi about y.
                        let wx = rg.x + lx * rg.cphi + lz * rg.sphi;
                        let wz = rg.z - lx * rg.sphi + lz * rg.cphi;
                        pts.push([wx as f64, (rg.figs[k] + ly) as f64, wz as f64]);
                    }
                }
                if let Some(r) = self.project_rect(&pts) {
                    self.mark(r, Obj::Figure(i as u16, k as u16));
                }
            }
        }
        for h in 0..g0.hand_boxes.len() {
            pts.clear();
            for &gi in &picks {
                let Some(b) = geoms[gi].hand_boxes.get(h) else {
                    continue;
                };
                for c in 0..8 {
                    pts.push([
                        if c & 1 == 0 { b.lo[0] } else { b.hi[0] } as f64,
                        if c & 2 == 0 { b.lo[1] } else { b.hi[1] } as f64,
                        if c & 4 == 0 { b.lo[2] } else { b.hi[2] } as f64,
                    ]);
                }
            }
            if let Some(r) = self.project_rect(&pts) {
                self.mark(r, Obj::Hand(h as u16));
            }
        }
        if g0.ball.is_some() {
            pts.clear();
            for &gi in &picks {
                if let Some((c, r)) = geoms[gi].ball {
                    for k in 0..8 {
                        pts.push([
                            (c[0] + if k & 1 == 0 { -r } else { r }) as f64,
                            (c[1] + if k & 2 == 0 { -r } else { r }) as f64,
                            (c[2] + if k & 4 == 0 { -r } else { r }) as f64,
                        ]);
                    }
                }
            }
            if let Some(r) = self.project_rect(&pts) {
                self.mark(r, Obj::Ball);
            }
        }
    }

    /// The range of rod `i`'s strip pixels that may show the marker in `geoms`.
    fn marker_range(&self, i: usize, geoms: &[WorldGeom], len: f32) -> (usize, usize) {
        let mut lo = f32::INFINITY;
        let mut hi = f32::NEG_INFINITY;
        for g in [&geoms[0], &geoms[geoms.len() - 1]] {
            let r = &g.rods[i];
            let a = r.marker_start;
            let b = r.marker_start + r.dir * len;
            let m = 3.0 + r.hu_blur;
            lo = lo.min(a.min(b) - m);
            hi = hi.max(a.max(b) + m);
        }
        let px = &self.strips[i].px;
        (
            px.partition_point(|p| p.y < lo),
            px.partition_point(|p| p.y <= hi),
        )
    }

    /// Renders one frame into `out` (tightly packed, `width * bytes_per_pixel` per row).
    ///
    /// `geoms` are the world at the time samples (1 in fast mode, 16 in quality mode);
    /// `brightness` and `glare` are the scenario's levels; `noise_seed` seeds the noise.
    #[allow(clippy::too_many_arguments)]
    pub fn render(
        &mut self,
        geoms: &[WorldGeom],
        shader: &Shader,
        mode: RenderMode,
        brightness: f32,
        glare: f32,
        noise: &[f32],
        noise_seed: u64,
        out: &mut [u8],
    ) {
        let ch = self.ch;
        let t_start = std::time::Instant::now();
        // 1. Restore what changed last frame.
        let prev_tiles = std::mem::take(&mut self.prev_tiles);
        for &t in &prev_tiles {
            let r = self.tile_rect(t as usize);
            for y in r.y0..r.y1 {
                let a = (y * self.w + r.x0) * ch;
                let b = (y * self.w + r.x1) * ch;
                self.rad[a..b].copy_from_slice(&self.bg[a..b]);
            }
        }
        self.prev_tiles = prev_tiles;
        self.prev_tiles.clear();
        for &(i, a, b) in &self.prev_ranges {
            for sp in &self.strips[i].px[a..b] {
                let p = sp.idx as usize * ch;
                self.rad[p..p + ch].copy_from_slice(&self.bg[p..p + ch]);
            }
        }
        self.prev_ranges.clear();
        let t_restore = t_start.elapsed();
        // 2. Markers.
        let len = shader.tex.len;
        let mut marker_px = 0;
        for i in 0..self.strips.len() {
            let (a, b) = self.marker_range(i, geoms, len);
            match (mode, self.point_rays) {
                (RenderMode::Fast, None) => self.shade_marker_fast(i, a, b, &geoms[0], shader),
                (_, rays) => {
                    let cands = [Obj::Rod(i as u16)];
                    for j in a..b {
                        let p = self.strips[i].px[j].idx as usize;
                        self.shade_pixel_quality(
                            p % self.w,
                            p / self.w,
                            geoms,
                            shader,
                            &cands,
                            SubSamples {
                                per_axis: rays.unwrap_or(QSUB),
                                points: rays.is_some(),
                            },
                        );
                    }
                }
            }
            self.prev_ranges.push((i, a, b));
            marker_px += b - a;
        }
        let t_markers = t_start.elapsed();
        // 3. Figures, hands, ball.
        if mode == RenderMode::Fast {
            self.paint_objects(&geoms[0], shader);
            let t_objects = t_start.elapsed();
            self.finish(brightness, glare, noise, noise_seed, out);
            let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
            self.stats = RenderStats {
                restore_ms: ms(t_restore),
                markers_ms: ms(t_markers - t_restore),
                objects_ms: ms(t_objects - t_markers),
                finish_ms: ms(t_start.elapsed() - t_objects),
                marker_px,
                object_tiles: self.prev_tiles.len(),
                object_cands: self.quads.len(),
            };
            return;
        }
        self.collect_tiles(geoms, shader);
        // Quality: only pixels near what the moving objects cover during the exposure.
        let last = geoms.len() - 1;
        let mut quads = std::mem::take(&mut self.quads);
        let mut spans = std::mem::take(&mut self.spans);
        for gi in [0, last / 2, last] {
            quads.clear();
            spans.clear();
            self.build_quads(&geoms[gi], shader, &mut quads);
            for q in &quads {
                scan(q, self.w, self.h, &mut spans);
            }
            for &(y, x0, x1) in &spans {
                let y = y as usize;
                for yy in y.saturating_sub(1)..(y + 2).min(self.h) {
                    for x in (x0 as usize).saturating_sub(1)..(x1 as usize + 2).min(self.w) {
                        let p = yy * self.w + x;
                        if !self.obj_mask[p] {
                            self.obj_mask[p] = true;
                            self.mask_list.push(p as u32);
                        }
                    }
                }
            }
        }
        self.quads = quads;
        self.spans = spans;
        let touched = std::mem::take(&mut self.touched);
        let mut cands: Vec<Obj> = Vec::new();
        for &t in &touched {
            let r = self.tile_rect(t as usize);
            cands.clear();
            cands.extend_from_slice(&self.tile_objs[t as usize]);
            let rods = self.tile_rods[t as usize];
            match mode {
                RenderMode::Fast => {
                    for y in r.y0..r.y1 {
                        for x in r.x0..r.x1 {
                            self.shade_object_fast(x, y, &geoms[0], shader, &cands, rods);
                        }
                    }
                }
                RenderMode::Quality => {
                    for i in 0..64 {
                        if rods & (1u64 << i) != 0 {
                            cands.push(Obj::Rod(i as u16));
                        }
                    }
                    for y in r.y0..r.y1 {
                        for x in r.x0..r.x1 {
                            if self.obj_mask[y * self.w + x] {
                                self.shade_pixel_quality(
                                    x,
                                    y,
                                    geoms,
                                    shader,
                                    &cands,
                                    SubSamples {
                                        per_axis: 2,
                                        points: false,
                                    },
                                );
                            }
                        }
                    }
                }
            }
        }
        for &p in &self.mask_list {
            self.obj_mask[p as usize] = false;
        }
        self.mask_list.clear();
        self.prev_tiles.clear();
        self.prev_tiles.extend_from_slice(&touched);
        let object_tiles = touched.len();
        self.touched = touched;
        let t_objects = t_start.elapsed();
        // 4. Light level, glare, noise, quantisation.
        self.finish(brightness, glare, noise, noise_seed, out);
        let ms = |d: std::time::Duration| d.as_secs_f64() * 1e3;
        self.stats = RenderStats {
            restore_ms: ms(t_restore),
            markers_ms: ms(t_markers - t_restore),
            objects_ms: ms(t_objects - t_markers),
            finish_ms: ms(t_start.elapsed() - t_objects),
            marker_px,
            object_tiles,
            object_cands: self
                .touched
                .iter()
                .map(|&t| self.tile_objs[t as usize].len())
                .sum(),
        };
    }

    fn shade_marker_fast(&mut self, i: usize, a: usize, b: usize, g: &WorldGeom, shader: &Shader) {
        let rod = &g.rods[i];
        let ch = self.ch;
        for sp in &self.strips[i].px[a..b] {
            let p = sp.idx as usize;
            let sample = crate::geom::RodSample {
                t: 0.0,
                y: sp.y,
                a: sp.a,
                shade: sp.shade,
                spec: sp.spec,
                hu: sp.hu,
                hpsi: sp.hpsi,
                alpha: sp.alpha,
            };
            let v = shader.rod_grey(rod, &sample);
            for c in 0..ch {
                let k = p * ch + c;
                self.rad[k] = sp.alpha * v + (1.0 - sp.alpha) * sp.bg0[c];
            }
        }
    }

    /// Fast mode: one ray against the moving objects; written only where one is hit and no rod
    /// is in front of it (elsewhere the image already holds the table, rods and markers).
    fn shade_object_fast(
        &mut self,
        x: usize,
        y: usize,
        g: &WorldGeom,
        shader: &Shader,
        cands: &[Obj],
        rods: u64,
    ) {
        let p = y * self.w + x;
        let (d, _, l) = self.sub_ray(x, y, 0.0, 0.0);
        let t_max = self.t_max(x, y, d);
        let Some(hit) = shader.trace(g, cands, self.origin, d, 0.0, t_max, None) else {
            return;
        };
        let mut m = rods;
        while m != 0 {
            let i = m.trailing_zeros() as usize;
            m &= m - 1;
            let rod = &g.rods[i];
            if let Some((t, yh)) = rod_hit(rod.x, rod.z, rod.r, self.origin, d) {
                if t < hit.t && yh >= rod.y_lo && yh <= rod.y_hi {
                    return;
                }
            }
        }
        let mut rad = std::mem::take(&mut self.rad);
        self.put(&mut rad, p, hit.rgb.map(|v| v * l));
        self.rad = rad;
    }

    /// Quality mode: `n x n` sub-samples (`n` = `subs.per_axis`: 4 or 2), each at its own
    /// time, against `cands`, over the table; each the mean over its share of the pixel's
    /// footprint, or with `subs.points` the print at the sub-sample's ray alone (see
    /// [`crate::Simulation::with_point_rays`]).
    #[allow(clippy::needless_range_loop)]
    fn shade_pixel_quality(
        &mut self,
        x: usize,
        y: usize,
        geoms: &[WorldGeom],
        shader: &Shader,
        cands: &[Obj],
        subs: SubSamples,
    ) {
        let (sub, points) = (subs.per_axis, subs.points);
        let p = y * self.w + x;
        let ch = self.ch;
        let mut acc = [0.0f32; 3];
        let n = sub * sub;
        for s in 0..n {
            let fx = ((s % sub) as f32 + 0.5) / sub as f32 - 0.5;
            let fy = ((s / sub) as f32 + 0.5) / sub as f32 - 0.5;
            let slot = if sub == QSUB {
                QTIME[s]
            } else {
                [0, 2, 3, 1][s % 4]
            };
            let g = &geoms[slot * geoms.len() / n];
            let (d, foot, light) = self.sub_ray(x, y, fx, fy);
            // A point ray still needs a footprint for the shader's box filter: a hundredth of
            // the pixel's is a point beside the print's finest detail (a tenth of a pixel).
            let foot = if points {
                foot * 0.01
            } else {
                foot / sub as f32
            };
            let t_max = self.t_max(x, y, d);
            match shader.trace(g, cands, self.origin, d, foot, t_max, None) {
                Some(hit) => {
                    for c in 0..ch {
                        let v = if ch == 3 {
                            hit.rgb[c]
                        } else {
                            self.pick(hit.rgb, x, y)
                        };
                        acc[c] += hit.alpha * v * light + (1.0 - hit.alpha) * self.bg0[p * ch + c];
                    }
                }
                None => {
                    for c in 0..ch {
                        acc[c] += self.bg0[p * ch + c];
                    }
                }
            }
        }
        for c in 0..ch {
            self.rad[p * ch + c] = acc[c] / n as f32;
        }
    }
}

/// How a pixel is sub-sampled (see [`CameraRenderer::shade_pixel_quality`]).
#[derive(Debug, Clone, Copy)]
struct SubSamples {
    /// Sub-samples per axis.
    per_axis: usize,
    /// Each sub-sample a point ray (else the mean over its share of the pixel).
    points: bool,
}
