//! Motion scripts ("scenarios"): what every rod, hand, the ball and the light do over time.
//!
//! Experiment motions are applied to all rods, scaled to each rod's travel. Times are seconds
//! from the first frame's trigger.

use crate::motion::{Track, TrackBuilder};
use crate::rng::Rng;
use crate::scene::{Glare, Lighting, SceneConfig};
use crate::SimError;
use serde::{Deserialize, Serialize};
use std::f64::consts::{PI, TAU};

/// One rod's motion: position along `u` (mm) and unwrapped angle (rad).
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct RodMotion {
    /// Position, mm.
    pub position: Track,
    /// Angle, rad, unwrapped.
    pub angle: Track,
}

/// A hand passing over the table: its palm centre moves from `from_mm` to `to_mm` (smoothly)
/// during `[t0_s, t1_s]`; outside that interval there is no hand. The forearm reaches from the
/// palm out over the wall on side `side` (+1: beyond `y = field width`, -1: beyond `y = 0`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct HandPass {
    /// Start, s.
    pub t0_s: f64,
    /// End, s.
    pub t1_s: f64,
    /// Palm centre at the start, mm.
    pub from_mm: [f64; 3],
    /// Palm centre at the end, mm.
    pub to_mm: [f64; 3],
    /// Which wall the arm comes over.
    pub side: f64,
}

impl HandPass {
    /// Palm centre at `t_s`, or `None` when the hand is away.
    pub fn palm_at(&self, t_s: f64) -> Option<[f64; 3]> {
        if t_s < self.t0_s || t_s > self.t1_s {
            return None;
        }
        let s = ((t_s - self.t0_s) / (self.t1_s - self.t0_s).max(1e-9)).clamp(0.0, 1.0);
        let s = s * s * (3.0 - 2.0 * s);
        Some([
            self.from_mm[0] + s * (self.to_mm[0] - self.from_mm[0]),
            self.from_mm[1] + s * (self.to_mm[1] - self.from_mm[1]),
            self.from_mm[2] + s * (self.to_mm[2] - self.from_mm[2]),
        ])
    }
}

/// The ball's path on the field: linear between keypoints `(t_s, x_mm, y_mm)`, absent
/// (in a goal, off the table, in a hand) during the `hidden` intervals.
#[derive(Debug, Clone, PartialEq, Default, Serialize, Deserialize)]
pub struct BallPath {
    /// Keypoints in time order.
    pub keys: Vec<(f64, f64, f64)>,
    /// Intervals `[t0_s, t1_s)` without a ball.
    #[serde(default)]
    pub hidden: Vec<(f64, f64)>,
}

impl BallPath {
    /// A path through `keys`, never hidden.
    pub fn new(keys: Vec<(f64, f64, f64)>) -> BallPath {
        BallPath {
            keys,
            hidden: Vec::new(),
        }
    }

    /// True when there is no ball at `t_s`.
    pub fn is_hidden(&self, t_s: f64) -> bool {
        self.hidden.iter().any(|&(a, b)| t_s >= a && t_s < b)
    }

    /// Ball centre `(x, y)` at `t_s` (held before the first and after the last keypoint);
    /// `None` while hidden.
    pub fn at(&self, t_s: f64) -> Option<(f64, f64)> {
        if self.is_hidden(t_s) {
            return None;
        }
        let first = self.keys.first()?;
        if t_s <= first.0 {
            return Some((first.1, first.2));
        }
        for w in self.keys.windows(2) {
            let (a, b) = (w[0], w[1]);
            if t_s <= b.0 {
                let s = (t_s - a.0) / (b.0 - a.0).max(1e-9);
                return Some((a.1 + s * (b.1 - a.1), a.2 + s * (b.2 - a.2)));
            }
        }
        self.keys.last().map(|k| (k.1, k.2))
    }

    /// Ball velocity `(vx, vy)` at `t_s`, mm/s (the slope of the segment holding `t_s`; 0
    /// outside the keypoints).
    pub fn velocity(&self, t_s: f64) -> (f64, f64) {
        for w in self.keys.windows(2) {
            let (a, b) = (w[0], w[1]);
            if t_s >= a.0 && t_s < b.0 && b.0 > a.0 {
                let dt = b.0 - a.0;
                return ((b.1 - a.1) / dt, (b.2 - a.2) / dt);
            }
        }
        (0.0, 0.0)
    }
}

/// A complete motion script.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Scenario {
    /// Name (`exp1`, `gameplay`, ...).
    pub name: String,
    /// Duration, s (frames = round(duration * fps)).
    pub duration_s: f64,
    /// Frame rate, frames/s.
    pub fps: f64,
    /// One motion per rod of the scene.
    pub rods: Vec<RodMotion>,
    /// Hands.
    pub hands: Vec<HandPass>,
    /// Optional ball.
    pub ball: Option<BallPath>,
    /// The ball's events as scripted (`goals`): `(t_s, event)`, the time at which each
    /// happens (a goal's crossing of the line, a kick, the start of a rest, the last moment
    /// seen before the ball leaves the table).
    #[serde(default)]
    pub events: Vec<(f64, rodtrack_core::ball::events::EventKind)>,
    /// Lighting that replaces the scene's (gradient, glare), if any.
    pub lighting: Option<Lighting>,
    /// Brightness factor over time (1 = the camera's brightness).
    pub brightness: Track,
    /// Glare level over time (0 = off, 1 = the glare's peak).
    pub glare: Track,
}

/// Names accepted by [`Scenario::by_name`].
pub const SCENARIO_NAMES: [&str; 15] = [
    "exp1", "exp2", "exp3", "spin600", "spin3000", "lighting", "gameplay", "sweep", "static",
    "poses", "ball", "hands", "goals", "stretch", "shots",
];

impl Scenario {
    /// All rods still at position 0, angle 0, for `duration_s`.
    pub fn still(scene: &SceneConfig, duration_s: f64) -> Scenario {
        Scenario {
            name: "still".into(),
            duration_s,
            fps: 200.0,
            rods: vec![RodMotion::default(); scene.rods.len()],
            hands: vec![],
            ball: None,
            events: Vec::new(),
            lighting: None,
            brightness: Track::constant(1.0),
            glare: Track::constant(0.0),
        }
    }

    /// Builds a named scenario for `scene`; `seed` drives the random ones.
    pub fn by_name(name: &str, scene: &SceneConfig, seed: u64) -> Result<Scenario, SimError> {
        let mut s = Scenario::still(scene, 1.0);
        s.name = name.to_string();
        let mut rng = Rng::new(seed ^ 0xC0FF_EE00);
        let n = scene.rods.len();
        let halves: Vec<f64> = scene.rods.iter().map(|r| r.half_travel_mm()).collect();
        let mut end = 0.0f64;
        match name {
            "exp1" => {
                for (i, &h) in halves.iter().enumerate() {
                    let mut p = TrackBuilder::new(0.0);
                    p.hold(0.5);
                    for k in 1..=7 {
                        let sign = if k % 2 == 1 { 1.0 } else { -1.0 };
                        p.move_to(sign * 0.95 * h * k as f64 / 7.0, 400.0, 4000.0);
                        p.hold(1.0);
                    }
                    p.move_to(0.0, 400.0, 4000.0).hold(0.5);
                    end = end.max(p.t_s);
                    s.rods[i].position = p.build();
                }
            }
            "exp2" => {
                for rod in s.rods.iter_mut() {
                    let mut a = TrackBuilder::new(0.0);
                    a.hold(0.5)
                        .move_to(10.0 * PI, 1.2, 6.0)
                        .hold(0.5)
                        .move_to(0.0, 1.2, 6.0)
                        .hold(0.5);
                    end = end.max(a.t_s);
                    rod.angle = a.build();
                }
            }
            "exp3" => {
                for (i, &h) in halves.iter().enumerate() {
                    let mut p = TrackBuilder::new(0.0);
                    let mut a = TrackBuilder::new(0.0);
                    p.hold(0.3);
                    for k in 0..17 {
                        let target = if k % 2 == 0 { -h } else { h };
                        p.move_to(target, 400.0, 4000.0).hold(0.15);
                        a.t_s = p.t_s;
                        a.move_to(TAU, 4.0 * PI, 40.0)
                            .hold(0.15)
                            .move_to(0.0, 4.0 * PI, 40.0)
                            .hold(0.15);
                        p.t_s = a.t_s;
                    }
                    p.hold(0.5);
                    end = end.max(p.t_s);
                    s.rods[i].position = p.build();
                    s.rods[i].angle = a.build();
                }
            }
            "spin600" | "spin3000" => {
                let (rate, ramp) = if name == "spin600" {
                    (600.0 / 60.0 * TAU, 1.0)
                } else {
                    (3000.0 / 60.0 * TAU, 2.0)
                };
                end = 10.0;
                for (i, &h) in halves.iter().enumerate() {
                    let mut a = TrackBuilder::new(0.0);
                    let sign = if i % 2 == 0 { 1.0 } else { -1.0 };
                    a.hold(0.3).spin(sign * rate, ramp);
                    s.rods[i].angle = a.build();
                    let mut p = TrackBuilder::new(0.0);
                    p.hold(0.5);
                    while p.t_s < end {
                        let target = if p.value <= 0.0 { 0.8 * h } else { -0.8 * h };
                        p.move_to(target, 40.0, 200.0).hold(0.3);
                    }
                    s.rods[i].position = p.build();
                }
            }
            "lighting" => {
                end = 20.0;
                s.lighting = Some(Lighting {
                    gradient_ratio: 4.0,
                    gradient_dir_rad: 0.35,
                    glare: Some(Glare {
                        at_mm: [600.0, 300.0, 80.0],
                        sigma_px: 70.0,
                        peak_dn: 170.0,
                        camera: None,
                    }),
                    ..scene.lighting
                });
                let mut b = TrackBuilder::new(1.0);
                b.hold(3.0).move_to(0.3, 0.7 / 6.0, 50.0).hold(5.0);
                b.move_to(1.0, 0.7 / 3.0, 50.0);
                s.brightness = b.build();
                let mut g = TrackBuilder::new(0.0);
                g.hold(5.0)
                    .move_to(1.0, 1.0, 10.0)
                    .hold(6.0)
                    .move_to(0.0, 1.0, 10.0);
                s.glare = g.build();
                for (i, &h) in halves.iter().enumerate() {
                    s.rods[i] = wander(&mut rng, h, end, 120.0, 3.0);
                }
            }
            "gameplay" => {
                end = 30.0;
                for (i, &h) in halves.iter().enumerate() {
                    s.rods[i] = gameplay_rod(&mut rng, h, end);
                }
                s.hands = gameplay_hands(&mut rng, scene, end);
                s.ball = Some(ball_path(&mut rng, scene, end));
            }
            "sweep" => {
                end = 20.0;
                for (i, &h) in halves.iter().enumerate() {
                    let v = 4.0 * h / 16.0;
                    let mut p = TrackBuilder::new(0.0);
                    p.hold(0.5)
                        .move_to(-h, v, 200.0)
                        .move_to(h, v, 200.0)
                        .move_to(0.0, v, 200.0);
                    s.rods[i].position = p.build();
                    let mut a = TrackBuilder::new(0.0);
                    a.hold(0.5).spin(0.6, 0.5);
                    s.rods[i].angle = a.build();
                }
            }
            "poses" => {
                // Every frame a new random pose of every rod over its whole travel and any
                // angle, held still through the frame's exposure (absolute accuracy: nothing
                // to learn from frame to frame). Frame 0 is the reference pose.
                let frames = 40usize;
                let dt = 1.0 / s.fps;
                end = frames as f64 * dt;
                for (i, &h) in halves.iter().enumerate() {
                    let mut p = TrackBuilder::new(0.0);
                    let mut a = TrackBuilder::new(0.0);
                    p.hold(0.5 * dt);
                    a.hold(0.5 * dt);
                    for _ in 1..frames {
                        p.move_to(rng.range(-h, h), 1e9, 1e15).hold(dt);
                        a.move_to(rng.range(0.0, TAU), 1e9, 1e15).hold(dt);
                    }
                    s.rods[i].position = p.build();
                    s.rods[i].angle = a.build();
                }
            }
            "static" => {
                end = 5.0;
                for (i, &h) in halves.iter().enumerate() {
                    s.rods[i].position = Track::constant(rng.range(-0.8 * h, 0.8 * h));
                    s.rods[i].angle = Track::constant(rng.range(-1.2, 1.2));
                }
            }
            "ball" => {
                // The ball rolling at up to 2 m/s, bouncing off the walls, now and then at
                // rest; the rods wander slowly, so rods and figures pass over it.
                end = 10.0;
                for (i, &h) in halves.iter().enumerate() {
                    s.rods[i] = wander(&mut rng, h, end, 100.0, 1.0);
                }
                s.ball = Some(rolling_ball(&mut rng, scene, end, 2000.0));
            }
            "goals" => {
                // Shots from the figures' feet at 2.5 to 6 m/s: goals for both sides (the ball
                // put back at the centre), a miss bouncing off an end wall to rest, a rebound
                // out of a goal, a ball leaving the table; the truth events in `events`.
                end = 24.0;
                crate::goals::script(&mut rng, scene, &mut s, end, crate::goals::Kicks::GOALS);
            }
            "stretch" => {
                // The plays of `goals`, each kick at a figure's full stretch: the ball met
                // 78 mm ahead of the kicking rod's axis, nearer the next rod's (72 mm), which
                // stays still; for crediting the shot to the rod that swung.
                end = 24.0;
                crate::goals::script(&mut rng, scene, &mut s, end, crate::goals::Kicks::STRETCH);
            }
            "shots" => {
                // The plays of `goals` with hard shots, 8 to 15 m/s: the fast ball's streak.
                end = 24.0;
                crate::goals::script(&mut rng, scene, &mut s, end, crate::goals::Kicks::HARD);
            }
            "hands" => {
                // Hands and moving figures, no ball: for false detections.
                end = 30.0;
                for (i, &h) in halves.iter().enumerate() {
                    s.rods[i] = gameplay_rod(&mut rng, h, end);
                }
                s.hands = gameplay_hands(&mut rng, scene, end);
            }
            other => {
                return Err(SimError::UnknownScenario {
                    name: other.to_string(),
                    known: SCENARIO_NAMES.join(", "),
                })
            }
        }
        debug_assert_eq!(s.rods.len(), n);
        s.duration_s = end.max(0.1);
        Ok(s)
    }

    /// Overrides the duration.
    pub fn with_duration(mut self, duration_s: f64) -> Self {
        self.duration_s = duration_s.max(0.0);
        self
    }

    /// Overrides the duration by a number of frames.
    pub fn with_frames(mut self, frames: usize) -> Self {
        self.duration_s = frames as f64 / self.fps;
        self
    }

    /// Number of frames.
    pub fn frame_count(&self) -> usize {
        (self.duration_s * self.fps).round() as usize
    }
}

/// Slow random slides and occasional turns.
fn wander(rng: &mut Rng, h: f64, end: f64, v_mm_s: f64, w_rad_s: f64) -> RodMotion {
    let mut p = TrackBuilder::new(0.0);
    p.hold(rng.range(0.2, 1.0));
    while p.t_s < end {
        p.move_to(rng.range(-0.9 * h, 0.9 * h), v_mm_s, 1500.0)
            .hold(rng.range(0.2, 1.2));
    }
    let mut a = TrackBuilder::new(0.0);
    a.hold(rng.range(0.2, 1.0));
    while a.t_s < end {
        let target = a.value + rng.range(-2.5, 2.5);
        a.move_to(target, w_rad_s, 30.0).hold(rng.range(0.3, 1.5));
    }
    RodMotion {
        position: p.build(),
        angle: a.build(),
    }
}

/// Human-like play: quick blocks (slides), kicks (back-swing and strike), lifts, pauses.
fn gameplay_rod(rng: &mut Rng, h: f64, end: f64) -> RodMotion {
    let mut p = TrackBuilder::new(0.0);
    let mut a = TrackBuilder::new(0.0);
    let mut t = rng.range(0.1, 0.6);
    while t < end {
        p.t_s = p.t_s.max(t);
        a.t_s = a.t_s.max(t);
        match rng.below(10) {
            0..=3 => {
                // Block: a quick slide.
                let target = (p.value + rng.range(-0.8, 0.8) * 2.0 * h).clamp(-h, h);
                p.move_to(target, rng.range(600.0, 1500.0), rng.range(8000.0, 20000.0));
            }
            4..=6 => {
                // Kick: back-swing, strike, return.
                let back = -rng.range(0.4, 1.0);
                let strike = rng.range(0.9, 1.8);
                a.move_to(back, 15.0, 300.0)
                    .hold(rng.range(0.02, 0.15))
                    .move_to(strike, rng.range(20.0, 40.0), rng.range(1000.0, 2500.0))
                    .hold(0.03)
                    .move_to(rng.range(-0.15, 0.15), 10.0, 200.0);
            }
            7 => {
                // Lift the figures to let the ball pass, then put them down.
                let lift = if rng.below(2) == 0 { 1.6 } else { -1.6 };
                a.move_to(lift, 8.0, 100.0)
                    .hold(rng.range(0.3, 1.0))
                    .move_to(0.0, 8.0, 100.0);
            }
            _ => {
                p.hold(rng.range(0.1, 0.8));
            }
        }
        t = p.t_s.max(a.t_s) + rng.range(0.05, 0.5);
    }
    RodMotion {
        position: p.build(),
        angle: a.build(),
    }
}

fn gameplay_hands(rng: &mut Rng, scene: &SceneConfig, end: f64) -> Vec<HandPass> {
    let mut hands = Vec::new();
    let mut t = rng.range(1.0, 2.0);
    let len = scene.marker_len_mm();
    while t + 1.0 < end {
        let r = &scene.rods[rng.below(scene.rods.len() as u64) as usize];
        let y = r.marker_y(0.5 * len, 0.0) + rng.range(-25.0, 25.0);
        let z = rng.range(150.0, 300.0);
        let dx = rng.range(120.0, 220.0);
        let flip = if rng.below(2) == 0 { 1.0 } else { -1.0 };
        let dur = rng.range(0.6, 1.6);
        hands.push(HandPass {
            t0_s: t,
            t1_s: t + dur,
            from_mm: [r.x_mm - flip * dx, y, z],
            to_mm: [r.x_mm + flip * dx, y + rng.range(-40.0, 40.0), z],
            side: if y > 0.5 * scene.field_width_mm {
                1.0
            } else {
                -1.0
            },
        });
        t += dur + rng.range(1.0, 3.5);
    }
    hands
}

fn ball_path(rng: &mut Rng, scene: &SceneConfig, end: f64) -> BallPath {
    let m = 0.5 * scene.ball_diameter_mm + 5.0;
    let mut keys = vec![(0.0, 0.5 * scene.field_length_mm, 0.5 * scene.field_width_mm)];
    let mut t = 0.0;
    while t < end {
        t += rng.range(0.2, 1.2);
        keys.push((
            t,
            rng.range(m, scene.field_length_mm - m),
            rng.range(m, scene.field_width_mm - m),
        ));
    }
    BallPath::new(keys)
}

/// A ball rolling in straight lines at up to `v_max_mm_s`, reflected by the walls, with a new
/// speed and direction (or a rest) every 0.5 to 2 s.
fn rolling_ball(rng: &mut Rng, scene: &SceneConfig, end: f64, v_max_mm_s: f64) -> BallPath {
    let r = 0.5 * scene.ball_diameter_mm;
    let (lo, hi) = (
        [r + 1.0, r + 1.0],
        [
            scene.field_length_mm - r - 1.0,
            scene.field_width_mm - r - 1.0,
        ],
    );
    let mut p = [
        rng.range(lo[0] + 50.0, hi[0] - 50.0),
        rng.range(lo[1] + 50.0, hi[1] - 50.0),
    ];
    let mut t = 0.0;
    let mut keys = vec![(t, p[0], p[1])];
    while t < end {
        let seg_end = t + rng.range(0.5, 2.0);
        let speed = if rng.uniform() < 0.15 {
            0.0
        } else {
            rng.range(0.1, 1.0) * v_max_mm_s
        };
        let a = rng.range(0.0, std::f64::consts::TAU);
        let mut v = [speed * a.cos(), speed * a.sin()];
        if speed == 0.0 {
            t = seg_end;
            keys.push((t, p[0], p[1]));
            continue;
        }
        while t < seg_end {
            // Time to the next wall along each axis.
            let hit = |k: usize| -> f64 {
                if v[k] > 0.0 {
                    (hi[k] - p[k]) / v[k]
                } else if v[k] < 0.0 {
                    (lo[k] - p[k]) / v[k]
                } else {
                    f64::INFINITY
                }
            };
            let (tx, ty) = (hit(0).max(0.0), hit(1).max(0.0));
            let dt = tx.min(ty).min(seg_end - t);
            p = [p[0] + v[0] * dt, p[1] + v[1] * dt];
            t += dt;
            if dt == tx {
                v[0] = -v[0];
            }
            if dt == ty {
                v[1] = -v[1];
            }
            p = [p[0].clamp(lo[0], hi[0]), p[1].clamp(lo[1], hi[1])];
            keys.push((t, p[0], p[1]));
        }
    }
    BallPath::new(keys)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn durations_and_ranges() {
        let scene = SceneConfig::default();
        let expect = [
            ("exp1", 10.0, 20.0),
            ("exp2", 52.0, 56.0),
            ("exp3", 30.0, 80.0),
            ("spin600", 10.0, 10.0),
            ("spin3000", 10.0, 10.0),
            ("lighting", 20.0, 20.0),
            ("gameplay", 30.0, 30.0),
            ("sweep", 20.0, 20.0),
            ("static", 5.0, 5.0),
        ];
        for (name, lo, hi) in expect {
            let s = Scenario::by_name(name, &scene, 1).unwrap();
            assert!(
                s.duration_s >= lo - 1e-9 && s.duration_s <= hi + 1e-9,
                "{name}: {}",
                s.duration_s
            );
            assert_eq!(s.fps, 200.0);
            assert_eq!(s.frame_count(), (s.duration_s * 200.0).round() as usize);
            // Positions stay inside the travel.
            for (r, m) in scene.rods.iter().zip(&s.rods) {
                let h = r.half_travel_mm();
                for k in 0..2000 {
                    let t = s.duration_s * k as f64 / 2000.0;
                    let p = m.position.value(t);
                    assert!(p.abs() <= h + 1e-6, "{name}: {p} > {h}");
                }
            }
        }
        assert!(Scenario::by_name("nope", &scene, 1).is_err());
        let s = Scenario::by_name("exp2", &scene, 1)
            .unwrap()
            .with_frames(100);
        assert_eq!(s.frame_count(), 100);
        // exp2 turns 5 times and back.
        let e = Scenario::by_name("exp2", &scene, 1).unwrap();
        let peak = (0..1000)
            .map(|k| e.rods[0].angle.value(e.duration_s * k as f64 / 1000.0))
            .fold(0.0, f64::max);
        assert!((peak - 10.0 * PI).abs() < 1e-6);
    }
}
