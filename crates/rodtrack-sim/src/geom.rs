//! The world at one instant as ray-traceable geometry (single precision), and the ray tests:
//! rods (cylinders along `y`), figures (boxes in the rotating rod frame), hands (boxes), the
//! ball (sphere), and the static table (field, lines, walls, floor).

use crate::scenario::Scenario;
use crate::scene::{SceneConfig, Team};
use rodtrack_core::angle::wrap_2pi;
use rodtrack_core::Marker;

/// A 3-vector.
pub type V3 = [f32; 3];

#[inline(always)]
fn dot(a: V3, b: V3) -> f32 {
    a[0] * b[0] + a[1] * b[1] + a[2] * b[2]
}

/// One rod at one instant.
#[derive(Debug, Clone)]
pub(crate) struct RodGeom {
    pub x: f32,
    pub z: f32,
    pub r: f32,
    /// Rod extent in world `y`.
    pub y_lo: f32,
    pub y_hi: f32,
    /// `phi = dir * theta`: rotation about world `+y`.
    pub cphi: f32,
    pub sphi: f32,
    pub dir: f32,
    /// World `y` of the marker's `u = 0` now.
    pub marker_start: f32,
    /// `(theta + psi0) mod 2 pi`.
    pub psi_base: f32,
    /// Analytic motion blur half-widths added to the texture footprint (fast mode), mm / rad.
    pub hu_blur: f32,
    pub hpsi_blur: f32,
    /// World `y` of each figure centre now.
    pub figs: Vec<f32>,
    pub team: Team,
}

/// An axis-aligned box in the world (hands).
#[derive(Debug, Clone, Copy)]
pub(crate) struct WBox {
    pub lo: V3,
    pub hi: V3,
}

/// The world at one instant.
#[derive(Debug, Clone, Default)]
pub(crate) struct WorldGeom {
    pub rods: Vec<RodGeom>,
    pub hand_boxes: Vec<WBox>,
    pub ball: Option<(V3, f32)>,
}

/// Pose of every rod (position, unwrapped angle, rates) at one instant.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RodPose {
    /// Position, mm.
    pub position_mm: f64,
    /// Unwrapped angle, rad.
    pub angle_rad: f64,
    /// Velocity, mm/s.
    pub velocity_mm_s: f64,
    /// Angular velocity, rad/s.
    pub angular_velocity_rad_s: f64,
}

/// Everything that moves, at one instant (double precision, from the scenario).
#[derive(Debug, Clone, PartialEq, Default)]
pub struct WorldState {
    /// Rod poses.
    pub rods: Vec<RodPose>,
    /// Palm centres and arm sides of the hands present.
    pub hands: Vec<([f64; 3], f64)>,
    /// Ball centre.
    pub ball: Option<[f64; 3]>,
}

impl WorldState {
    /// The scenario's state at `t_s`.
    pub fn at(scene: &SceneConfig, scenario: &Scenario, t_s: f64) -> WorldState {
        let mut s = WorldState::default();
        s.set_at(scene, scenario, t_s);
        s
    }

    /// Overwrites `self` with the scenario's state at `t_s`, reusing its buffers.
    pub fn set_at(&mut self, scene: &SceneConfig, scenario: &Scenario, t_s: f64) {
        self.rods.clear();
        self.rods
            .extend((0..scene.rods.len()).map(|i| match scenario.rods.get(i) {
                Some(m) => {
                    let (p, v) = m.position.eval(t_s);
                    let (a, w) = m.angle.eval(t_s);
                    RodPose {
                        position_mm: p,
                        angle_rad: a,
                        velocity_mm_s: v,
                        angular_velocity_rad_s: w,
                    }
                }
                None => RodPose {
                    position_mm: 0.0,
                    angle_rad: 0.0,
                    velocity_mm_s: 0.0,
                    angular_velocity_rad_s: 0.0,
                },
            }));
        self.hands.clear();
        self.hands.extend(
            scenario
                .hands
                .iter()
                .filter_map(|h| h.palm_at(t_s).map(|p| (p, h.side))),
        );
        let r = 0.5 * scene.ball_diameter_mm;
        self.ball = scenario
            .ball
            .as_ref()
            .and_then(|b| b.at(t_s))
            .map(|(x, y)| [x, y, r]);
    }

    /// Every rod at the given poses, nothing else.
    pub fn posed(poses: &[(f64, f64)]) -> WorldState {
        WorldState {
            rods: poses
                .iter()
                .map(|&(p, a)| RodPose {
                    position_mm: p,
                    angle_rad: a,
                    velocity_mm_s: 0.0,
                    angular_velocity_rad_s: 0.0,
                })
                .collect(),
            hands: vec![],
            ball: None,
        }
    }
}

impl WorldGeom {
    /// Geometry of `state`; `blur_s` is the exposure for the analytic marker blur (0 for none).
    pub fn build(scene: &SceneConfig, state: &WorldState, blur_s: f64) -> WorldGeom {
        let mut g = WorldGeom::default();
        g.build_into(scene, state, blur_s);
        g
    }

    /// Like [`WorldGeom::build`], reusing `self`'s buffers (no allocation once warm).
    pub fn build_into(&mut self, scene: &SceneConfig, state: &WorldState, blur_s: f64) {
        self.rods.truncate(scene.rods.len());
        for (i, (rc, p)) in scene.rods.iter().zip(&state.rods).enumerate() {
            let shift = rc.shift_y(p.position_mm);
            let phi = rc.marker_dir * p.angle_rad;
            let centre = 0.5 * scene.field_width_mm + shift;
            let mut figs = match self.rods.get_mut(i) {
                Some(r) => std::mem::take(&mut r.figs),
                None => Vec::new(),
            };
            figs.clear();
            figs.extend(rc.figure_y_mm.iter().map(|y| (y + shift) as f32));
            let g = RodGeom {
                x: rc.x_mm as f32,
                z: rc.z_mm as f32,
                r: rc.radius_mm() as f32,
                y_lo: (centre - 0.5 * rc.length_mm) as f32,
                y_hi: (centre + 0.5 * rc.length_mm) as f32,
                cphi: phi.cos() as f32,
                sphi: phi.sin() as f32,
                dir: rc.marker_dir as f32,
                marker_start: rc.marker_y(0.0, p.position_mm) as f32,
                psi_base: wrap_2pi(p.angle_rad + rc.psi0_rad) as f32,
                hu_blur: (0.5 * p.velocity_mm_s.abs() * blur_s) as f32,
                hpsi_blur: (0.5 * p.angular_velocity_rad_s.abs() * blur_s) as f32,
                figs,
                team: rc.team,
            };
            if i < self.rods.len() {
                self.rods[i] = g;
            } else {
                self.rods.push(g);
            }
        }
        let hs = &scene.hand;
        let hand_boxes = &mut self.hand_boxes;
        hand_boxes.clear();
        for &(c, side) in &state.hands {
            let lo = [
                c[0] - 0.5 * hs.palm_mm[0],
                c[1] - 0.5 * hs.palm_mm[1],
                c[2] - 0.5 * hs.palm_mm[2],
            ];
            let hi = [
                c[0] + 0.5 * hs.palm_mm[0],
                c[1] + 0.5 * hs.palm_mm[1],
                c[2] + 0.5 * hs.palm_mm[2],
            ];
            hand_boxes.push(WBox {
                lo: lo.map(|v| v as f32),
                hi: hi.map(|v| v as f32),
            });
            // Forearm: from the palm out over the wall, a bit higher towards the player.
            let (y0, y1) = if side > 0.0 {
                (hi[1] - 10.0, scene.field_width_mm + 450.0)
            } else {
                (-450.0, lo[1] + 10.0)
            };
            hand_boxes.push(WBox {
                lo: [
                    (c[0] - 0.5 * hs.forearm_mm[0]) as f32,
                    y0 as f32,
                    (c[2] - 0.5 * hs.forearm_mm[1] + 8.0) as f32,
                ],
                hi: [
                    (c[0] + 0.5 * hs.forearm_mm[0]) as f32,
                    y1 as f32,
                    (c[2] + 0.5 * hs.forearm_mm[1] + 8.0) as f32,
                ],
            });
        }
        self.ball = state
            .ball
            .map(|b| (b.map(|v| v as f32), (0.5 * scene.ball_diameter_mm) as f32));
    }
}

/// A rod hit (or near miss, for the antialiased silhouette).
#[derive(Debug, Clone, Copy)]
pub(crate) struct RodSample {
    pub t: f32,
    /// World `y` of the hit.
    pub y: f32,
    /// Angle of the surface normal from `+z` towards `+x`: `atan2(n_x, n_z)`.
    pub a: f32,
    /// Diffuse shading factor.
    pub shade: f32,
    /// Specular factor (times the steel's specular strength).
    pub spec: f32,
    /// Texture footprint half-widths, mm along the rod and rad around it.
    pub hu: f32,
    pub hpsi: f32,
    /// Silhouette coverage.
    pub alpha: f32,
}

/// Ray against an infinite cylinder along `y` through `(x, z)` with radius `r`. `foot` is the
/// angular size of the pixel (or sub-sample), for the footprint and the silhouette coverage.
#[inline]
pub(crate) fn rod_sample(
    x: f32,
    z: f32,
    r: f32,
    o: V3,
    d: V3,
    foot: f32,
    ambient: f32,
) -> Option<RodSample> {
    let ox = o[0] - x;
    let oz = o[2] - z;
    let a = d[0] * d[0] + d[2] * d[2];
    if a < 1e-12 {
        return None;
    }
    let b = ox * d[0] + oz * d[2];
    let tc = -b / a;
    if tc <= 0.0 {
        return None;
    }
    let cx = ox + tc * d[0];
    let cz = oz + tc * d[2];
    let dmin2 = cx * cx + cz * cz;
    let w = tc * foot;
    let lim = r + 0.5 * w;
    if dmin2 >= lim * lim {
        return None;
    }
    let dmin = dmin2.sqrt();
    let alpha = (0.5 + (r - dmin) / w.max(1e-6)).clamp(0.0, 1.0);
    let (t, nx, nz) = if dmin < r {
        let t = tc - ((r * r - dmin2) / a).sqrt();
        ((t), (ox + t * d[0]) / r, (oz + t * d[2]) / r)
    } else {
        let inv = 1.0 / dmin.max(1e-9);
        (tc, cx * inv, cz * inv)
    };
    let y = o[1] + t * d[1];
    let shade = ambient + (1.0 - ambient) * nz.max(0.0);
    // Half vector between the light (straight up) and the view direction (-d).
    let (hx, hy, hz) = (-d[0], -d[1], 1.0 - d[2]);
    let hn = (hx * hx + hy * hy + hz * hz).sqrt().max(1e-9);
    let ndh = ((nx * hx + nz * hz) / hn).max(0.0);
    let ndh2 = ndh * ndh;
    let ndh4 = ndh2 * ndh2;
    let ndh8 = ndh4 * ndh4;
    let spec = ndh8 * ndh8 * ndh8 * ndh8; // ^32
    let cos_i = (nx * d[0] + nz * d[2]).abs().max(0.08);
    let sin_ax = (1.0 - d[1] * d[1]).max(0.05).sqrt();
    let hu = 0.5 * w / sin_ax;
    let hpsi = (0.5 * w / (r * cos_i)).min(std::f32::consts::PI);
    Some(RodSample {
        t,
        y,
        a: nx.atan2(nz),
        shade,
        spec,
        hu,
        hpsi,
        alpha,
    })
}

/// Ray against an infinite cylinder along `y`: entry distance and world `y` of the hit.
#[inline]
pub(crate) fn rod_hit(x: f32, z: f32, r: f32, o: V3, d: V3) -> Option<(f32, f32)> {
    let ox = o[0] - x;
    let oz = o[2] - z;
    let a = d[0] * d[0] + d[2] * d[2];
    let b = ox * d[0] + oz * d[2];
    let c = ox * ox + oz * oz - r * r;
    let disc = b * b - a * c;
    if disc <= 0.0 || a < 1e-12 {
        return None;
    }
    let t = (-b - disc.sqrt()) / a;
    (t > 0.0).then(|| (t, o[1] + t * d[1]))
}

/// Ray against an axis-aligned box: entry distance and the entry face's axis and sign.
#[inline]
pub(crate) fn ray_box(o: V3, inv: V3, lo: V3, hi: V3) -> Option<(f32, usize, f32)> {
    let mut tmin = 0.0f32;
    let mut tmax = f32::INFINITY;
    let mut axis = 0usize;
    let mut sign = 0.0f32;
    for k in 0..3 {
        let t1 = (lo[k] - o[k]) * inv[k];
        let t2 = (hi[k] - o[k]) * inv[k];
        let (tn, tf, s) = if t1 < t2 {
            (t1, t2, -1.0)
        } else {
            (t2, t1, 1.0)
        };
        if tn > tmin {
            tmin = tn;
            axis = k;
            sign = s;
        }
        tmax = tmax.min(tf);
        if tmin > tmax {
            return None;
        }
    }
    if sign == 0.0 {
        return None; // origin inside the box
    }
    Some((tmin, axis, sign))
}

#[inline]
fn inv_dir(d: V3) -> V3 {
    d.map(|v| {
        if v.abs() < 1e-20 {
            1e20f32.copysign(v)
        } else {
            1.0 / v
        }
    })
}

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

/// The marker's print, box-filtered analytically over a footprint in `(u, psi)`.
#[derive(Debug, Clone)]
pub(crate) struct MarkerTexture {
    pub len: f32,
    bc0: f32,
    cell: f32,
    /// Black cells before cell `i`.
    prefix: Vec<f32>,
    kernel: Vec<bool>,
    g0: f32,
    bs: f32,
    bits: u32,
    steps: f32,
}

impl MarkerTexture {
    pub fn new(m: &Marker) -> MarkerTexture {
        let mut prefix = vec![0.0f32];
        for &b in m.kernel() {
            let last = *prefix.last().unwrap_or(&0.0);
            prefix.push(last + if b { 1.0 } else { 0.0 });
        }
        MarkerTexture {
            len: m.length_mm() as f32,
            bc0: m.barcode_start_mm() as f32,
            cell: m.cell_mm() as f32,
            prefix,
            kernel: m.kernel().to_vec(),
            g0: m.gray_start_mm() as f32,
            bs: m.bit_space_mm() as f32,
            bits: m.bits(),
            steps: m.steps() as f32,
        }
    }

    /// Black length of the barcode in `[bc0, u]`, mm.
    #[inline]
    fn barcode_cum(&self, u: f32) -> f32 {
        let x = ((u - self.bc0) / self.cell).clamp(0.0, self.kernel.len() as f32);
        let i = (x.floor() as usize).min(self.kernel.len() - 1);
        let frac = x - i as f32;
        (self.prefix[i] + if self.kernel[i] { frac } else { 0.0 }) * self.cell
    }

    /// Mean of bit `k` of `gray(floor(steps psi / 2 pi))` over `[psi - h, psi + h]`.
    #[inline]
    fn bit_mean(&self, k: u32, psi: f32, h: f32) -> f32 {
        let sc = self.steps / std::f32::consts::TAU;
        // Bit k of gray(n) is floor((n + 2^k) / 2^(k+1)) mod 2: it repeats every 2^(k+2) steps
        // and is black over the second half of each period after a shift of 2^k. The top bit
        // (black for n in [steps/2, steps)) repeats every `steps` (n wraps around the rod).
        let (period, shift) = if k + 1 >= self.bits {
            (self.steps, 0.0)
        } else {
            ((4u32 << k) as f32, (1u32 << k) as f32)
        };
        let cum = |s: f32| {
            let x = (s + shift) / period;
            let f = x.floor();
            f * 0.5 + (x - f - 0.5).max(0.0)
        };
        let s0 = (psi - h) * sc;
        let s1 = (psi + h) * sc;
        if s1 - s0 < 1e-4 {
            let x = (0.5 * (s0 + s1) + shift) / period;
            return if x - x.floor() >= 0.5 { 1.0 } else { 0.0 };
        }
        (period * (cum(s1) - cum(s0)) / (s1 - s0)).clamp(0.0, 1.0)
    }

    /// (paper fraction, black fraction) of the footprint `[u - hu, u + hu] x [psi - hpsi,
    /// psi + hpsi]`.
    pub fn coverage(&self, u: f32, psi: f32, hu: f32, hpsi: f32) -> (f32, f32) {
        let hu = hu.max(1e-4);
        let (u0, u1) = (u - hu, u + hu);
        let inv = 1.0 / (u1 - u0);
        let ov = |a: f32, b: f32| (u1.min(b) - u0.max(a)).max(0.0);
        let paper = ov(0.0, self.len) * inv;
        let mut black = self.barcode_cum(u1) - self.barcode_cum(u0);
        for k in 0..self.bits {
            let a = self.g0 + k as f32 * self.bs;
            let o = ov(a, a + self.bs);
            if o > 0.0 {
                black += o * self.bit_mean(k, psi, hpsi);
            }
        }
        (paper, (black * inv).min(paper))
    }
}

/// Static table geometry: field with lines, walls, floor.
#[derive(Debug, Clone)]
pub(crate) struct Table {
    l: f32,
    w: f32,
    floor_z: f32,
    walls: Vec<WBox>,
    field: V3,
    lines: V3,
    wall: V3,
    floor: V3,
    ambient: f32,
}

impl Table {
    pub fn new(scene: &SceneConfig) -> Table {
        let l = scene.field_length_mm as f32;
        let w = scene.field_width_mm as f32;
        let t = scene.wall_thickness_mm as f32;
        let h = scene.wall_height_mm as f32;
        let walls = vec![
            WBox {
                lo: [-t, -t, -40.0],
                hi: [l + t, 0.0, h],
            },
            WBox {
                lo: [-t, w, -40.0],
                hi: [l + t, w + t, h],
            },
            WBox {
                lo: [-t, 0.0, -40.0],
                hi: [0.0, w, h],
            },
            WBox {
                lo: [l, 0.0, -40.0],
                hi: [l + t, w, h],
            },
        ];
        let f = |v: [f64; 3]| v.map(|x| x as f32);
        let c = &scene.colours;
        Table {
            l,
            w,
            floor_z: scene.floor_z_mm as f32,
            walls,
            field: f(c.field),
            lines: f(c.lines),
            wall: f(c.wall),
            floor: f(c.floor),
            ambient: scene.lighting.ambient as f32,
        }
    }

    /// Distance to the nearest wall along a ray (infinite if none).
    pub fn trace_walls(&self, o: V3, d: V3) -> f32 {
        let inv = inv_dir(d);
        self.walls
            .iter()
            .filter_map(|b| ray_box(o, inv, b.lo, b.hi).map(|h| h.0))
            .fold(f32::INFINITY, f32::min)
    }

    /// (distance, colour) of the static background along a ray.
    pub fn trace(&self, o: V3, d: V3) -> (f32, V3) {
        let inv = inv_dir(d);
        let mut best = (f32::INFINITY, [0.0; 3]);
        for b in &self.walls {
            if let Some((t, axis, sign)) = ray_box(o, inv, b.lo, b.hi) {
                if t < best.0 {
                    let sh = if axis == 2 && sign > 0.0 {
                        1.0
                    } else {
                        self.ambient + 0.15
                    };
                    best = (t, self.wall.map(|v| v * sh));
                }
            }
        }
        if d[2] < 0.0 {
            let t = -o[2] / d[2];
            if t < best.0 {
                let x = o[0] + t * d[0];
                let y = o[1] + t * d[1];
                if x >= 0.0 && x <= self.l && y >= 0.0 && y <= self.w {
                    let cx = x - 0.5 * self.l;
                    let cy = y - 0.5 * self.w;
                    let rr = (cx * cx + cy * cy).sqrt();
                    let line = cx.abs() < 2.5 || (rr - 100.0).abs() < 2.5;
                    best = (t, if line { self.lines } else { self.field });
                }
            }
            let t = (self.floor_z - o[2]) / d[2];
            if t < best.0 {
                best = (t, self.floor);
            }
        }
        best
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::TAU;

    /// The analytic box filter agrees with the marker's own point definition.
    #[test]
    fn texture_matches_marker_definition() {
        let m = Marker::v1();
        let t = MarkerTexture::new(&m);
        let mut bad = 0;
        for i in 0..2000 {
            let u = -3.0 + 112.0 * (i as f64 + 0.37) / 2000.0;
            for j in 0..64 {
                // Print angles beyond one turn must wrap.
                let psi = TAU * (j as f64 + 0.29) / 64.0 - TAU + TAU * (i % 3) as f64;
                let (paper, black) = t.coverage(u as f32, psi as f32, 1e-5, 1e-6);
                let inside = (0.0..m.length_mm()).contains(&u);
                assert_eq!(paper > 0.5, inside, "u {u}");
                let want = inside && m.is_black(u, psi);
                if (black > 0.5) != want {
                    bad += 1;
                }
            }
        }
        assert_eq!(bad, 0);
        // A footprint over a whole bit-0 period is half black.
        let (_, b) = t.coverage(75.0, 1.0, 0.1, (TAU / 8.0) as f32 * 0.5);
        assert!((b - 0.5).abs() < 1e-3, "{b}");
    }
}
