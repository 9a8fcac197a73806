//! The `goals` scenario: plays of shots, goals, misses and a ball leaving the table, with the
//! truth events scripted alongside the ball's path.
//!
//! A play starts with the ball at rest at the field's centre. It rolls (0.5 to 0.9 m/s) to a
//! foot of one of the attacking side's rods (32 mm ahead of the rod's axis, at one of its
//! figures), which swings and kicks it at 2.5 to 6 m/s:
//! - a **goal**: into the goal mouth (aimed within its width less a radius and 10 mm), on
//!   through the line; the ball is gone 1 s (in the goal), then back at the centre;
//! - a **miss**: at the end wall outside the mouth; it bounces (45 % of the speed along the
//!   table, 60 % across), rolls with 2 m/s^2 of friction, off the side walls, to rest for
//!   0.8 s, and is then picked up (0.4 s) and put at the centre;
//! - a **rebound**: into the mouth, wholly past the line (10 mm), off the goal's back and out
//!   again at 45 % of the speed, then as a miss: no goal;
//! - **out**: the ball rolls against a side wall and leaves the table (gone 1.5 s).
//!
//! The goal mouth's width is the events' reference default
//! ([`rodtrack_core::ball::events::EventConfig`]); the simulator's end walls have no
//! opening: a ball going through the mouth disappears under the wall, as it drops into a
//! goal. Truth events: a goal at the ball's centre crossing the line, a shot at the kick (its
//! speed, the kicking rod, the ball's position), a stop at the start of a rest, an out at the
//! last moment seen.

use crate::motion::TrackBuilder;
use crate::rng::Rng;
use crate::scenario::{BallPath, Scenario};
use crate::scene::SceneConfig;
use rodtrack_core::ball::events::{EventConfig, EventKind, Side};

/// The kick point's distance ahead of the rod's axis, mm (scenario `goals`).
const FOOT_AHEAD_MM: f64 = 32.0;

/// How the figures kick: where the ball is met and when the swing starts.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Kicks {
    /// The ball's centre at the kick, ahead of the kicking rod's axis, mm.
    pub foot_ahead_mm: f64,
    /// The forward swing starts this long before the kick, s.
    pub swing_lead_s: f64,
    /// The ball's speed after a kick, drawn uniformly from this range, mm/s.
    pub speed_mm_s: (f64, f64),
}

impl Kicks {
    /// Scenario `goals`: the ball met 32 mm ahead of the axis, early in the forward swing.
    pub(crate) const GOALS: Kicks = Kicks {
        foot_ahead_mm: FOOT_AHEAD_MM,
        swing_lead_s: 0.02,
        speed_mm_s: (2500.0, 6000.0),
    };

    /// Scenario `shots`: the plays of `goals` with hard shots, 8 to 15 m/s (the ball smeared
    /// over 4 to 7.5 mm within the simulated cameras' 0.5 ms exposure).
    pub(crate) const HARD: Kicks = Kicks {
        foot_ahead_mm: FOOT_AHEAD_MM,
        swing_lead_s: 0.02,
        speed_mm_s: (8000.0, 15000.0),
    };

    /// Scenario `stretch`: the ball met at full stretch, its centre 78 mm ahead of the axis
    /// (a figure's toe about 78 mm below its axis swung forward by 0.8 rad: 56 mm ahead and
    /// 26 mm above the field, on the ball's upper half, whose centre lies a radius further),
    /// late in the forward swing (still turning at about 30 rad/s). With rods 150 mm apart the
    /// next rod's axis is nearer the ball (72 mm) than the kicker's.
    pub(crate) const STRETCH: Kicks = Kicks {
        foot_ahead_mm: 78.0,
        swing_lead_s: 0.03,
        speed_mm_s: (2500.0, 6000.0),
    };
}
/// Rolling friction after a bounce, mm/s^2.
const FRICTION_MM_S2: f64 = 2000.0;
/// Time step of a rolling ball's keypoints, s.
const ROLL_STEP_S: f64 = 0.01;

struct Script<'a> {
    scene: &'a SceneConfig,
    r: f64,
    t: f64,
    p: [f64; 2],
    keys: Vec<(f64, f64, f64)>,
    hidden: Vec<(f64, f64)>,
    events: Vec<(f64, EventKind)>,
    score: [u32; 2],
}

impl Script<'_> {
    fn centre(&self) -> [f64; 2] {
        [
            0.5 * self.scene.field_length_mm,
            0.5 * self.scene.field_width_mm,
        ]
    }

    /// World to table.
    fn table(&self, p: [f64; 2]) -> (f64, f64) {
        let c = self.centre();
        (p[0] - c[0], p[1] - c[1])
    }

    fn key(&mut self) {
        self.keys.push((self.t, self.p[0], self.p[1]));
    }

    /// Straight to `to` at `speed_mm_s`.
    fn go(&mut self, to: [f64; 2], speed_mm_s: f64) {
        let d = (to[0] - self.p[0]).hypot(to[1] - self.p[1]);
        self.t += d / speed_mm_s;
        self.p = to;
        self.key();
    }

    fn rest(&mut self, dt_s: f64) {
        self.t += dt_s;
        self.key();
    }

    /// Gone for `dt_s`, then at `at`.
    fn hide(&mut self, dt_s: f64, at: [f64; 2]) {
        self.hidden.push((self.t, self.t + dt_s));
        self.t += dt_s;
        self.p = at;
        self.key();
    }

    /// Rolls from the current place at `v`, slowed by friction, reflected by the walls,
    /// until it stops.
    fn roll(&mut self, mut v: [f64; 2]) {
        let (lo, hi) = (
            [self.r + 1.0, self.r + 1.0],
            [
                self.scene.field_length_mm - self.r - 1.0,
                self.scene.field_width_mm - self.r - 1.0,
            ],
        );
        loop {
            let s = v[0].hypot(v[1]);
            if s <= FRICTION_MM_S2 * ROLL_STEP_S {
                break;
            }
            let f = (s - FRICTION_MM_S2 * ROLL_STEP_S) / s;
            // The mean velocity over the step.
            let m = 0.5 * (1.0 + f);
            for k in 0..2 {
                self.p[k] += v[k] * m * ROLL_STEP_S;
                if self.p[k] < lo[k] {
                    self.p[k] = 2.0 * lo[k] - self.p[k];
                    v[k] = -v[k];
                } else if self.p[k] > hi[k] {
                    self.p[k] = 2.0 * hi[k] - self.p[k];
                    v[k] = -v[k];
                }
                v[k] *= f;
            }
            self.t += ROLL_STEP_S;
            self.key();
        }
    }
}

#[derive(Debug, Clone, Copy, PartialEq)]
enum Play {
    Goal,
    Miss,
    Rebound,
    Out,
}

/// Fills `s` with the plays up to `end_s`: the ball's path, the kicking rods' swings, the
/// truth events. Every rod stays at position 0; the figures hang down except in a kick.
pub(crate) fn script(
    rng: &mut Rng,
    scene: &SceneConfig,
    s: &mut Scenario,
    end_s: f64,
    kicks: Kicks,
) {
    let goal_width_mm = EventConfig::default().goal_width_mm;
    let mut sc = Script {
        scene,
        r: 0.5 * scene.ball_diameter_mm,
        t: 0.0,
        p: [0.0; 2],
        keys: Vec::new(),
        hidden: Vec::new(),
        events: Vec::new(),
        score: [0, 0],
    };
    sc.p = sc.centre();
    sc.key();
    let mut angles: Vec<TrackBuilder> = scene.rods.iter().map(|_| TrackBuilder::new(0.0)).collect();
    let keeper_team = scene.rods.first().map(|r| r.team);
    // Goals 3:3 in the first 9 plays (about 22 s).
    let plays = [
        (Side::A, Play::Goal),
        (Side::B, Play::Goal),
        (Side::A, Play::Rebound),
        (Side::B, Play::Goal),
        (Side::A, Play::Goal),
        (Side::B, Play::Miss),
        (Side::A, Play::Out),
        (Side::B, Play::Goal),
        (Side::A, Play::Goal),
    ];
    let mut k = 0usize;
    while sc.t + 3.5 < end_s {
        let (side, play) = plays[k % plays.len()];
        k += 1;
        sc.rest(0.25);
        if play == Play::Out {
            let y = if rng.below(2) == 0 {
                scene.field_width_mm - sc.r - 3.0
            } else {
                sc.r + 3.0
            };
            let x = sc.p[0] + rng.range(-200.0, 200.0);
            sc.go([x, y], rng.range(500.0, 900.0));
            sc.rest(0.05);
            let last = sc.table(sc.p);
            sc.events.push((
                sc.t,
                EventKind::BallOut {
                    x_mm: last.0,
                    y_mm: last.1,
                },
            ));
            let c = sc.centre();
            sc.hide(1.5, c);
            continue;
        }
        // Side A (the team of the goalkeeper at world x = 0) shoots towards +x.
        let dir = if side == Side::A { 1.0 } else { -1.0 };
        let kickers: Vec<usize> = scene
            .rods
            .iter()
            .enumerate()
            .filter(|(i, r)| {
                let ours = (Some(r.team) == keeper_team) == (side == Side::A);
                let keeper = *i == 0 || *i + 1 == scene.rods.len();
                ours && !keeper
            })
            .map(|(i, _)| i)
            .collect();
        if kickers.is_empty() {
            break;
        }
        let rod = kickers[rng.below(kickers.len() as u64) as usize];
        let rc = &scene.rods[rod];
        let figs: Vec<f64> = rc
            .figure_y_mm
            .iter()
            .copied()
            .filter(|y| *y > 80.0 && *y < scene.field_width_mm - 80.0)
            .collect();
        let fy = if figs.is_empty() {
            0.5 * scene.field_width_mm
        } else {
            figs[rng.below(figs.len() as u64) as usize]
        };
        let foot = [rc.x_mm + dir * kicks.foot_ahead_mm, fy];
        sc.go(foot, rng.range(500.0, 900.0));
        // The kick: back-swing, strike through the ball's moment, back down.
        let t_kick = sc.t;
        let a = &mut angles[rod];
        a.hold((t_kick - 0.1 - a.t_s).max(0.0))
            .move_to(-0.6 * dir, 20.0, 800.0);
        a.hold((t_kick - kicks.swing_lead_s - a.t_s).max(0.0))
            .move_to(0.9 * dir, 60.0, 6000.0)
            .hold(0.05)
            .move_to(0.0, 10.0, 200.0);
        let speed = rng.range(kicks.speed_mm_s.0, kicks.speed_mm_s.1);
        let kicked = sc.table(foot);
        sc.events.push((
            t_kick,
            EventKind::Shot {
                speed_mm_s: speed,
                rod: Some(rc_index(rod)),
                x_mm: kicked.0,
                y_mm: kicked.1,
            },
        ));
        let line = if side == Side::A {
            scene.field_length_mm
        } else {
            0.0
        };
        let cy = 0.5 * scene.field_width_mm;
        match play {
            Play::Goal => {
                let half = 0.5 * goal_width_mm - sc.r - 10.0;
                let ty = cy + rng.range(-half, half);
                let target = [line + dir * (sc.r + 10.0), ty];
                let t0 = sc.t;
                let x0 = sc.p[0];
                let v = speed / (target[0] - x0).hypot(target[1] - sc.p[1]);
                sc.go(target, speed);
                // The centre crosses the line at this time.
                let t_cross = t0 + (line - x0).abs() / ((target[0] - x0).abs() * v);
                sc.score[side.index()] += 1;
                sc.events.push((
                    t_cross,
                    EventKind::Goal {
                        side,
                        goal: side.other(),
                        score: sc.score,
                    },
                ));
                let c = sc.centre();
                sc.hide(1.0, c);
            }
            Play::Miss | Play::Rebound | Play::Out => {
                let d;
                if play == Play::Rebound {
                    // Into the mouth, 10 mm past the line (the ball wholly in), off the goal's
                    // back and out again: no goal.
                    let half = 0.5 * goal_width_mm - sc.r - 10.0;
                    let ty = cy + rng.range(-half, half);
                    let back = [line + dir * (sc.r + 10.0), ty];
                    d = [back[0] - sc.p[0], back[1] - sc.p[1]];
                    sc.go(back, speed);
                    let out = [line - dir * (sc.r + 1.0), ty];
                    sc.go(out, 0.45 * speed);
                } else {
                    let off = rng.range(
                        0.5 * goal_width_mm + sc.r + 15.0,
                        0.5 * scene.field_width_mm - sc.r - 20.0,
                    );
                    let ty = if rng.below(2) == 0 {
                        cy + off
                    } else {
                        cy - off
                    };
                    let target = [line - dir * (sc.r + 1.0), ty];
                    d = [target[0] - sc.p[0], target[1] - sc.p[1]];
                    sc.go(target, speed);
                }
                let n = d[0].hypot(d[1]);
                sc.roll([-0.45 * speed * d[0] / n, 0.6 * speed * d[1] / n]);
                let rest = sc.table(sc.p);
                sc.events.push((
                    sc.t,
                    EventKind::BallStopped {
                        x_mm: rest.0,
                        y_mm: rest.1,
                    },
                ));
                sc.rest(0.8);
                let c = sc.centre();
                sc.hide(0.4, c);
            }
        }
    }
    // At rest at the centre to the end.
    if end_s - sc.t >= 0.7 {
        let c = sc.table(sc.p);
        sc.events.push((
            sc.t,
            EventKind::BallStopped {
                x_mm: c.0,
                y_mm: c.1,
            },
        ));
    }
    sc.rest((end_s - sc.t).max(0.0));
    for (i, a) in angles.iter().enumerate() {
        if let Some(m) = s.rods.get_mut(i) {
            m.angle = a.build();
        }
    }
    s.ball = Some(BallPath {
        keys: sc.keys,
        hidden: sc.hidden,
    });
    s.events = sc.events;
}

/// The rod's index in the calibration (the simulator's rod order).
fn rc_index(rod: usize) -> u32 {
    u32::try_from(rod).unwrap_or(u32::MAX)
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The scripted events agree with the ball's path: a goal's centre crosses its line
    /// within the mouth at the event's time and the ball is gone right after; a shot's speed is
    /// the path's just after the kick, from the kicking rod's foot; a stopped ball does not
    /// move for 0.5 s; goals for both sides, the score counting up by one.
    #[test]
    fn the_truth_events_agree_with_the_ball_s_path() {
        let scene = SceneConfig::default();
        let half_mouth = 0.5 * EventConfig::default().goal_width_mm;
        let cy = 0.5 * scene.field_width_mm;
        for seed in [1, 7, 42] {
            let s = Scenario::by_name("goals", &scene, seed).unwrap();
            let path = s.ball.as_ref().unwrap();
            let mut score = [0u32; 2];
            for &(t, e) in &s.events {
                match e {
                    EventKind::Goal {
                        side,
                        goal,
                        score: after,
                    } => {
                        score[side.index()] += 1;
                        assert_eq!(after, score, "seed {seed}: t {t}");
                        assert_eq!(goal, side.other());
                        let line = if goal == Side::B {
                            scene.field_length_mm
                        } else {
                            0.0
                        };
                        let (xa, ya) = path.at(t - 1e-3).unwrap();
                        let (xb, _) = path.at(t + 1e-3).unwrap();
                        assert!(
                            (xa - line).signum() != (xb - line).signum(),
                            "seed {seed}: the goal at {t} s crosses the line ({xa} -> {xb})"
                        );
                        assert!((ya - cy).abs() < half_mouth, "seed {seed}: y {ya}");
                        assert!(path.at(t + 0.05).is_none(), "seed {seed}: gone after {t} s");
                    }
                    EventKind::Shot {
                        speed_mm_s, rod, ..
                    } => {
                        let (vx, vy) = path.velocity(t + 1e-3);
                        assert!((vx.hypot(vy) - speed_mm_s).abs() < 1e-6 * speed_mm_s);
                        let r = &scene.rods[rod.unwrap() as usize];
                        let (x, _) = path.at(t).unwrap();
                        assert!(((x - r.x_mm).abs() - FOOT_AHEAD_MM).abs() < 1e-6);
                    }
                    EventKind::BallStopped { .. } => {
                        let a = path.at(t).unwrap();
                        let b = path.at(t + 0.5).unwrap();
                        assert!((a.0 - b.0).hypot(a.1 - b.1) < 1e-6, "seed {seed}: at {t} s");
                    }
                    EventKind::BallOut { .. } => {
                        assert!(path.at(t + 0.01).is_none() && path.at(t + 1.2).is_none());
                    }
                }
            }
            assert!(
                score[0] >= 3 && score[1] >= 3,
                "seed {seed}: goals for both sides, {score:?}"
            );
        }
    }
}
