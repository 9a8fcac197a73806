//! The world at one instant: rod poses, hands and ball (double precision, from the
//! scenario) and the same as ray-traceable geometry (single precision).

use super::ray::V3;
use crate::scenario::Scenario;
use crate::scene::{SceneConfig, Team};
use rodtrack_core::angle::wrap_2pi;

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
    /// The ball's displacement over the exposure, mm, its centre `ball` at mid-exposure: fast
    /// mode's motion blur (zero where each geometry is one instant, as in quality mode).
    pub ball_move: V3,
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
        self.ball_move = [0.0; 3];
    }
}
