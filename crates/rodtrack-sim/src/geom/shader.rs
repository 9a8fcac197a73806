//! The tracer: nearest hit among rods, figures, hands and the ball, with shading.

use super::ray::{dot, inv_dir, ray_box, rod_sample, RodSample, V3};
use super::texture::MarkerTexture;
use super::world::{RodGeom, WorldGeom};
use crate::scene::{SceneConfig, Team};
use rodtrack_core::Marker;

/// Something the tracer can hit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Obj {
    Rod(u16),
    Figure(u16, u16),
    Hand(u16),
    Ball,
}

/// A traced sample: distance, colour (albedo times shading, plus specular), coverage.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Shaded {
    #[allow(dead_code)]
    pub t: f32,
    pub rgb: V3,
    pub alpha: f32,
}

/// A ray in one rod's rotating frame, with its interval inside the figures' `x`/`z` slabs.
struct FigCache {
    rod: i32,
    lo: V3,
    linv: V3,
    t0: f32,
    t1: f32,
}

/// Precomputed constants for shading.
#[derive(Debug, Clone)]
pub(crate) struct Shader {
    pub tex: MarkerTexture,
    pub paper: f32,
    pub ink: f32,
    pub steel: f32,
    pub steel_spec: f32,
    pub red: V3,
    pub blue: V3,
    pub ball: V3,
    pub skin: V3,
    pub ambient: f32,
    pub figure: Vec<(V3, V3)>,
    pub figure_bounds: (V3, V3),
}

impl Shader {
    pub fn new(scene: &SceneConfig) -> Shader {
        let c = &scene.colours;
        let grey = |v: [f64; 3]| ((v[0] + v[1] + v[2]) / 3.0) as f32;
        let f = |v: [f64; 3]| v.map(|x| x as f32);
        let (blo, bhi) = scene.figure.bounds();
        Shader {
            tex: MarkerTexture::new(
                &scene
                    .marker_spec_for(0)
                    .validate()
                    .unwrap_or_else(|_| Marker::v1()),
            ),
            paper: grey(c.paper),
            ink: grey(c.ink),
            steel: grey(c.steel),
            steel_spec: c.steel_specular as f32,
            red: f(c.red),
            blue: f(c.blue),
            ball: f(c.ball),
            skin: f(c.skin),
            ambient: scene.lighting.ambient as f32,
            figure: scene
                .figure
                .boxes
                .iter()
                .map(|(a, b)| (f(*a), f(*b)))
                .collect(),
            figure_bounds: (f(blo), f(bhi)),
        }
    }

    /// Grey level of a rod sample (albedo times shading plus specular), before light.
    #[inline]
    pub fn rod_grey(&self, rod: &RodGeom, s: &RodSample) -> f32 {
        let u = rod.dir * (s.y - rod.marker_start);
        let hu = s.hu + rod.hu_blur;
        let len = self.tex.len;
        if u + hu <= 0.0 || u - hu >= len {
            return s.shade * self.steel + s.spec * self.steel_spec;
        }
        let psi = rod.psi_base - rod.dir * s.a;
        let (paper, black) = self.tex.coverage(u, psi, hu, s.hpsi + rod.hpsi_blur);
        let alb = (paper - black) * self.paper + black * self.ink + (1.0 - paper) * self.steel;
        s.shade * alb + s.spec * self.steel_spec * (1.0 - paper)
    }

    /// Nearest hit among `cands` (excluding `skip`) with `t < t_max`.
    #[allow(clippy::too_many_arguments)]
    pub fn trace(
        &self,
        g: &WorldGeom,
        cands: &[Obj],
        o: V3,
        d: V3,
        foot: f32,
        t_max: f32,
        skip: Option<Obj>,
    ) -> Option<Shaded> {
        let inv = inv_dir(d);
        let mut best: Option<Shaded> = None;
        let mut t_best = t_max;
        let mut fig_cache = FigCache {
            rod: -1,
            lo: [0.0; 3],
            linv: [0.0; 3],
            t0: 0.0,
            t1: 0.0,
        };
        for &c in cands {
            if Some(c) == skip {
                continue;
            }
            match c {
                Obj::Rod(i) => {
                    let rod = &g.rods[i as usize];
                    if let Some(s) = rod_sample(rod.x, rod.z, rod.r, o, d, foot, self.ambient) {
                        if s.t < t_best && s.y >= rod.y_lo && s.y <= rod.y_hi {
                            let v = self.rod_grey(rod, &s);
                            t_best = s.t;
                            best = Some(Shaded {
                                t: s.t,
                                rgb: [v, v, v],
                                alpha: s.alpha,
                            });
                        }
                    }
                }
                Obj::Figure(i, k) => {
                    let rod = &g.rods[i as usize];
                    let (c_, s_) = (rod.cphi, rod.sphi);
                    // The ray in the rod's rotating frame (shared by all its figures): subtract
                    // the axis point, rotate by -phi about y. Cached per rod.
                    if fig_cache.rod != i as i32 {
                        let px = o[0] - rod.x;
                        let pz = o[2] - rod.z;
                        let lo_ = [c_ * px - s_ * pz, o[1], s_ * px + c_ * pz];
                        let ld = [c_ * d[0] - s_ * d[2], d[1], s_ * d[0] + c_ * d[2]];
                        let linv = inv_dir(ld);
                        let (blo, bhi) = self.figure_bounds;
                        let mut t0 = 0.0f32;
                        let mut t1 = f32::INFINITY;
                        for a in [0usize, 2] {
                            let u1 = (blo[a] - lo_[a]) * linv[a];
                            let u2 = (bhi[a] - lo_[a]) * linv[a];
                            t0 = t0.max(u1.min(u2));
                            t1 = t1.min(u1.max(u2));
                        }
                        fig_cache = FigCache {
                            rod: i as i32,
                            lo: lo_,
                            linv,
                            t0,
                            t1,
                        };
                    }
                    let fc = &fig_cache;
                    if fc.t0 > fc.t1 || fc.t0 >= t_best {
                        continue;
                    }
                    let (blo, bhi) = self.figure_bounds;
                    let ly = fc.lo[1] - rod.figs[k as usize];
                    let u1 = (blo[1] - ly) * fc.linv[1];
                    let u2 = (bhi[1] - ly) * fc.linv[1];
                    let tn = fc.t0.max(u1.min(u2));
                    let tf = fc.t1.min(u1.max(u2));
                    if tn > tf || tn >= t_best {
                        continue;
                    }
                    let lo_ = [fc.lo[0], ly, fc.lo[2]];
                    for (blo, bhi) in &self.figure {
                        if let Some((t, axis, sign)) = ray_box(lo_, fc.linv, *blo, *bhi) {
                            if t < t_best {
                                // World z of the local face normal (rotation by +phi about y).
                                let nz = match axis {
                                    0 => -s_ * sign,
                                    2 => c_ * sign,
                                    _ => 0.0,
                                };
                                let sh = self.ambient + (1.0 - self.ambient) * nz.max(0.0);
                                let col = match rod.team {
                                    Team::Red => self.red,
                                    Team::Blue => self.blue,
                                };
                                t_best = t;
                                best = Some(Shaded {
                                    t,
                                    rgb: col.map(|v| v * sh),
                                    alpha: 1.0,
                                });
                            }
                        }
                    }
                }
                Obj::Hand(h) => {
                    let b = g.hand_boxes[h as usize];
                    if let Some((t, axis, sign)) = ray_box(o, inv, b.lo, b.hi) {
                        if t < t_best {
                            let nz = if axis == 2 { sign } else { 0.0 };
                            let sh = self.ambient + (1.0 - self.ambient) * nz.max(0.0);
                            t_best = t;
                            best = Some(Shaded {
                                t,
                                rgb: self.skin.map(|v| v * sh),
                                alpha: 1.0,
                            });
                        }
                    }
                }
                Obj::Ball => {
                    if let Some((c, r)) = g.ball {
                        let oc = [o[0] - c[0], o[1] - c[1], o[2] - c[2]];
                        let b = dot(oc, d);
                        let cc = dot(oc, oc) - r * r;
                        let disc = b * b - cc;
                        if disc > 0.0 {
                            let t = -b - disc.sqrt();
                            if t > 0.0 && t < t_best {
                                let nz = (o[2] + t * d[2] - c[2]) / r;
                                let sh = self.ambient + (1.0 - self.ambient) * nz.max(0.0);
                                t_best = t;
                                best = Some(Shaded {
                                    t,
                                    rgb: self.ball.map(|v| v * sh),
                                    alpha: 1.0,
                                });
                            }
                        }
                    }
                }
            }
        }
        best
    }
}
