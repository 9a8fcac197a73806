//! The ball's events end to end on the simulator: scenario `goals` (shots, goals for both
//! sides, misses bouncing off the end walls, a ball leaving the table), calibrated from the
//! simulated clicks, tracked by a session with the ball and the events, against the
//! scenario's truth events.

#![allow(clippy::unwrap_used)]

use rodtrack_core::ball::events::{
    final_score, match_events, shot_agreement, BallEvent, EventConfig, TableGeometry,
};
use rodtrack_core::calib::CalibrationFile;
use rodtrack_io::{BallVecSink, EventVecSink, VecSink};
use rodtrack_sdk::{EventCounts, Session, SessionCamera, SessionOptions};
use rodtrack_sim::{build_simulation, Simulation};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

mod common;
use common::{calibrate, session_cameras};

/// The events of a session over every frame of `sim`, and the session's counts.
fn track_events(sim: &Simulation, cal: &CalibrationFile) -> (Vec<BallEvent>, EventCounts) {
    let cameras = session_cameras(sim, cal);
    let events = EventVecSink::default();
    let session = Session::from_cameras(cameras, SessionOptions::default())
        .with_ball(cal, Box::new(BallVecSink::default()))
        .unwrap()
        .with_events(cal, EventConfig::default(), Box::new(events.clone()))
        .unwrap();
    let (report, _) = session.run(VecSink::default()).unwrap();
    (events.events(), report.events.unwrap())
}

/// Goals within 0.1 s of the truth's crossing, shots within 0.15 s, outs within 0.1 s (at
/// 200 fps); stops within 24 frames: over the 5 runs of the notes (seeds 7, 3, 11, 12 and 13)
/// the 15 stops were found 0 to 23 frames after the truth's rest (median 4, 13 within 10; the
/// former rule, a 5 mm radius, found them up to 28 frames early, within 30).
const GOAL_TOLERANCE_FRAMES: u64 = 20;
const SHOT_TOLERANCE_FRAMES: u64 = 30;
const STOP_TOLERANCE_FRAMES: u64 = 24;
const OUT_TOLERANCE_FRAMES: u64 = 20;

#[test]
fn goals_scenario_every_goal_found_and_the_score_right() {
    goals_run(7, "default");
}

/// More seeds and as-built setups (cameras tilted and shifted, other lenses, rods off their
/// places): about 100 s each in release, so not in the default run
/// (`cargo test --release -p rodtrack-sdk --test events -- --ignored --nocapture`).
#[test]
#[ignore]
fn goals_scenario_over_seeds_and_as_built_setups() {
    for (seed, setup) in [
        (3, "default"),
        (11, "default"),
        (12, "asbuilt:12"),
        (13, "asbuilt:13"),
    ] {
        eprintln!("seed {seed}, setup {setup}:");
        goals_run(seed, setup);
    }
}

/// Scenario `goals` with `seed` on `setup`, tracked and scored: every goal found, none false,
/// the final score the truth's; shots, stops and outs as guarded below.
fn goals_run(seed: u64, setup: &str) {
    let mut sim = build_simulation("goals", None, seed, false, setup).unwrap();
    let truth = sim.events_truth();
    let cal = calibrate(&mut sim, seed);
    let (found, counts) = track_events(&sim, &cal);
    if std::env::var_os("RODTRACK_PRINT_EVENTS").is_some() {
        for e in &truth {
            eprintln!("truth: {}", e.json_line());
        }
        for e in &found {
            eprintln!("found: {}", e.json_line());
        }
    }
    let truth_score = final_score(&truth);
    let goals = match_events(&truth, &found, "goal", GOAL_TOLERANCE_FRAMES);
    let shots = match_events(&truth, &found, "shot", SHOT_TOLERANCE_FRAMES);
    let stops = match_events(&truth, &found, "ball_stopped", STOP_TOLERANCE_FRAMES);
    let outs = match_events(&truth, &found, "ball_out", OUT_TOLERANCE_FRAMES);
    for (name, m) in [
        ("goals", &goals),
        ("shots", &shots),
        ("ball_stopped", &stops),
        ("ball_out", &outs),
    ] {
        eprintln!(
            "{name}: truth {}, found {}, missed {}, false {}",
            m.truth, m.found, m.missed, m.false_events
        );
    }
    // The stops' timing: found minus truth, frames.
    let stop_errors: Vec<i64> = stops
        .pairs
        .iter()
        .map(|&(i, j)| found[j].frame as i64 - truth[i].frame as i64)
        .collect();
    eprintln!("ball_stopped timing (found - truth, frames): {stop_errors:?}");
    // The shots' rods and speeds.
    let (rod_right, worst_speed) = shot_agreement(&truth, &found, &shots);
    eprintln!(
        "shots: rod right {rod_right}/{}, speed error worst {:.1} %, score {:?} (truth {:?})",
        shots.pairs.len(),
        100.0 * worst_speed,
        counts.score,
        truth_score
    );
    assert!(
        goals.truth >= 6,
        "the scenario scores goals: {}",
        goals.truth
    );
    assert!(
        truth_score[0] >= 2 && truth_score[1] >= 2,
        "goals for both sides: {truth_score:?}"
    );
    assert_eq!(goals.missed, 0, "missed goals");
    assert_eq!(goals.false_events, 0, "false goals");
    assert_eq!(counts.score, truth_score, "the final score");
    assert_eq!(counts.goals as usize, goals.truth);
    // Shots: found and credited to the right rod (guarded below what was measured).
    assert!(
        shots.found * 10 >= shots.truth * 9 && shots.false_events == 0,
        "shots: {shots:?}"
    );
    assert!(
        rod_right * 10 >= shots.found * 9,
        "rods: {rod_right}/{}",
        shots.found
    );
    assert!(worst_speed <= 0.03, "the issue's speed target: 3 %");
    assert_eq!((outs.missed, outs.false_events), (0, 0), "ball out");
    assert_eq!((stops.missed, stops.false_events), (0, 0), "ball stopped");
}

/// The table the events see, from a simulated calibration: every rod's axis within 3 mm of the
/// simulator's (table frame), the reference field; a session asked for events without the ball
/// is refused, naming the order.
#[test]
fn the_table_s_rods_come_from_the_calibration() {
    let seed = 3;
    let mut sim = build_simulation("static", Some(2), seed, false, "default").unwrap();
    let cal = calibrate(&mut sim, seed);
    let geom = TableGeometry::from_calibration(&cal, &EventConfig::default()).unwrap();
    let scene = sim.scene();
    assert_eq!(geom.rods.len(), scene.rods.len(), "{:?}", geom.rods);
    for (&(rod, x), truth) in geom.rods.iter().zip(&scene.rods) {
        let want = truth.x_mm - 0.5 * scene.field_length_mm;
        eprintln!("rod {rod}: axis x {x:.2} mm, truth {want:.2} mm");
        assert!((x - want).abs() < 3.0, "rod {rod}: {x:.2} vs {want:.2}");
    }
    assert_eq!((geom.x_min_mm, geom.x_max_mm), (-600.0, 600.0));
    // A field configured too small for the clicked corners is refused.
    let small = EventConfig {
        field_length_mm: 1000.0,
        ..EventConfig::default()
    };
    let err = TableGeometry::from_calibration(&cal, &small).unwrap_err();
    assert!(err.to_string().contains("field"), "{err}");
    let cameras = session_cameras(&sim, &cal);
    let err = Session::from_cameras(cameras, SessionOptions::default())
        .with_events(
            &cal,
            EventConfig::default(),
            Box::new(EventVecSink::default()),
        )
        .err()
        .unwrap();
    assert!(err.to_string().contains("with_ball"), "{err}");
}

/// Scenario `stretch` (the plays of `goals`, every kick at a figure's full stretch: the ball
/// met 78 mm ahead of the kicking rod's axis, 72 mm from the next rod's, which stays still),
/// 12 s: every shot found and credited to the rod that swung, though another rod's axis is
/// nearer the ball (checked on the truth, with the calibrated axes). The nearest axis within
/// reach, without the rods' swings, credits none of them.
#[test]
fn stretch_kicks_are_credited_to_the_rod_that_swung() {
    let seed = 5;
    let mut sim = build_simulation("stretch", Some(2400), seed, false, "default").unwrap();
    let truth = sim.events_truth();
    let cal = calibrate(&mut sim, seed);
    let geom = TableGeometry::from_calibration(&cal, &EventConfig::default()).unwrap();
    let (found, _) = track_events(&sim, &cal);
    let shots = match_events(&truth, &found, "shot", SHOT_TOLERANCE_FRAMES);
    let (rod_right, worst_speed) = shot_agreement(&truth, &found, &shots);
    for &(i, j) in &shots.pairs {
        eprintln!(
            "truth {}\nfound {}",
            truth[i].json_line(),
            found[j].json_line()
        );
    }
    eprintln!(
        "stretch: shots truth {}, found {}, false {}, rod right {rod_right}, speed error worst \
         {:.1} %",
        shots.truth,
        shots.found,
        shots.false_events,
        100.0 * worst_speed
    );
    assert!(shots.truth >= 4, "{shots:?}");
    for e in &truth {
        if let rodtrack_core::ball::events::EventKind::Shot {
            rod: Some(rod),
            x_mm,
            ..
        } = e.kind
        {
            let nearest = geom.nearest_rod(x_mm, f64::INFINITY);
            assert_ne!(
                nearest,
                Some(rod),
                "the case: another axis is nearer, {e:?}"
            );
        }
    }
    assert_eq!((shots.missed, shots.false_events), (0, 0), "{shots:?}");
    assert_eq!(rod_right, shots.found, "every shot to the rod that kicked");
}

/// A camera's source that counts the frames it read (`read`), and, with `wait`, stops
/// before its frame `wait.0` until the other camera's source read `wait.2` frames (a disk or a
/// scheduler that keeps its thread waiting) or stopped reading, then goes on.
struct Stall {
    inner: Box<dyn rodtrack_io::FrameSource>,
    read: Arc<AtomicU64>,
    wait: Option<(u64, Arc<AtomicU64>, u64)>,
    /// The other camera's frames read when this one went on.
    released_at: Arc<AtomicU64>,
}

impl rodtrack_io::FrameSource for Stall {
    fn info(&self) -> rodtrack_io::source::SourceInfo {
        self.inner.info()
    }
    fn next_frame(
        &mut self,
        buf: &mut rodtrack_io::FrameBuffer,
    ) -> Result<Option<()>, rodtrack_io::SourceError> {
        if let Some((at, other, until)) = &self.wait {
            if self.read.load(Ordering::SeqCst) == *at {
                // Until the other camera read `until` frames, or stopped reading for 0.3 s
                // (it waits for this one).
                let (mut seen, mut since) = (other.load(Ordering::SeqCst), Instant::now());
                while seen < *until && since.elapsed() < Duration::from_millis(300) {
                    std::thread::sleep(Duration::from_millis(1));
                    let now = other.load(Ordering::SeqCst);
                    if now != seen {
                        (seen, since) = (now, Instant::now());
                    }
                }
                self.released_at.store(seen, Ordering::SeqCst);
            }
        }
        let r = self.inner.next_frame(buf);
        self.read.fetch_add(1, Ordering::SeqCst);
        r
    }
}

/// The ball rows (frame, camera, status, position, velocity) and events of a session over
/// `sim`; with `stall`, camera 1's source stops at its frame 200 until camera 0's read all
/// but 50 of its frames.
fn track_stalled(
    sim: &Simulation,
    cal: &CalibrationFile,
    stall: bool,
) -> (Vec<String>, Vec<String>, u64) {
    let frames = sim.frame_count() as u64;
    let read0 = Arc::new(AtomicU64::new(0));
    let released_at = Arc::new(AtomicU64::new(0));
    let cameras: Vec<SessionCamera> = session_cameras(sim, cal)
        .into_iter()
        .enumerate()
        .map(|(i, c)| SessionCamera {
            source: Box::new(Stall {
                inner: c.source,
                read: if i == 0 {
                    read0.clone()
                } else {
                    Arc::default()
                },
                wait: (i == 1 && stall).then(|| (200, read0.clone(), frames - 50)),
                released_at: released_at.clone(),
            }),
            ..c
        })
        .collect();
    let rows = BallVecSink::default();
    let events = EventVecSink::default();
    let session = Session::from_cameras(cameras, SessionOptions::default())
        .with_ball(cal, Box::new(rows.clone()))
        .unwrap()
        .with_events(cal, EventConfig::default(), Box::new(events.clone()))
        .unwrap();
    session.run(VecSink::default()).unwrap();
    let rows = rows
        .rows()
        .iter()
        .map(|r| {
            format!(
                "{} {} {:?} {} {} {} {}",
                r.frame, r.camera, r.status, r.x_mm, r.y_mm, r.vx_mm_s, r.vy_mm_s
            )
        })
        .collect();
    let events = events.events().iter().map(|e| e.json_line()).collect();
    (rows, events, released_at.load(Ordering::SeqCst))
}

/// A recording gives the same ball rows and events however the cameras' threads are
/// scheduled: camera 1 stalled at frame 200 until camera 0 is 1000 frames ahead writes what
/// a run without the stall writes, every frame's rows in order, none late.
#[test]
fn a_stalled_camera_changes_no_ball_row_and_no_event() {
    let seed = 7;
    let mut sim = build_simulation("goals", Some(1250), seed, false, "default").unwrap();
    let cal = calibrate(&mut sim, seed);
    let (rows, events, _) = track_stalled(&sim, &cal, false);
    let (stalled_rows, stalled_events, lead) = track_stalled(&sim, &cal, true);
    // The case: camera 0 ran more than the 400 rows the writer holds ahead of camera 1.
    eprintln!("camera 0 read {lead} frames while camera 1 stood at frame 200");
    assert!(lead >= 600, "camera 0 ahead: {lead}");
    assert_eq!(
        rows.len(),
        3 * 1250,
        "both cameras and the fused row per frame"
    );
    let first_difference = rows.iter().zip(&stalled_rows).position(|(a, b)| a != b);
    assert_eq!(first_difference, None, "the ball rows");
    assert_eq!(rows.len(), stalled_rows.len());
    assert_eq!(events, stalled_events, "the events");
}

/// A hand stops the ball rolling towards goal A, 100 mm before the goal line, and holds it
/// there under the palm for 2.6 s (longer than the goal's grace time), then lifts: the ball
/// never crossed the line, so no goal. (The tracker predicts a ball it stops seeing for 0.1 s
/// along its last velocity: at 1.5 m/s that path crosses the line.)
#[test]
fn a_hand_holding_the_ball_before_the_goal_mouth_is_no_goal() {
    use rodtrack_sim::scenario::{BallPath, HandPass, Scenario};
    use rodtrack_sim::scene::SceneConfig;
    use rodtrack_sim::{default_cameras, render::RenderMode};
    let seed = 5;
    let scene = SceneConfig::default();
    let mut sc = Scenario::by_name("ball", &scene, seed).unwrap();
    // World frame: goal A's line at x = 0, the mouth's middle at y = W / 2.
    let y = 0.5 * scene.field_width_mm + 20.0;
    let stop_x = 117.5;
    sc.ball = Some(BallPath::new(vec![
        (0.0, 417.5, y),
        (0.2, stop_x, y),
        (3.0, stop_x, y),
        (3.4, 417.5, y),
        (4.0, 417.5, y),
    ]));
    let palm_z = scene.ball_diameter_mm + 0.5 * scene.hand.palm_mm[2] + 5.0;
    let above = [stop_x, y, 250.0];
    let on = [stop_x, y, palm_z];
    sc.hands = vec![
        HandPass {
            t0_s: 0.0,
            t1_s: 0.17,
            from_mm: above,
            to_mm: on,
            side: 1.0,
        },
        HandPass {
            t0_s: 0.17,
            t1_s: 2.8,
            from_mm: on,
            to_mm: on,
            side: 1.0,
        },
        HandPass {
            t0_s: 2.8,
            t1_s: 3.0,
            from_mm: on,
            to_mm: above,
            side: 1.0,
        },
    ];
    sc.events.clear();
    let sc = sc.with_frames(800);
    let mut sim = Simulation::new(scene, default_cameras(), sc, RenderMode::Fast)
        .unwrap()
        .with_seed(seed);
    // The ball is hidden while the hand holds it.
    let t = sim.ball_truth(300).unwrap();
    assert!(t.visible.iter().all(|&v| v < 0.25), "{:?}", t.visible);
    let cal = calibrate(&mut sim, seed);
    let (found, counts) = track_events(&sim, &cal);
    for e in &found {
        eprintln!("found: {}", e.json_line());
    }
    let goals: Vec<_> = found.iter().filter(|e| e.kind.name() == "goal").collect();
    assert!(goals.is_empty(), "false goals: {goals:?}");
    assert_eq!(counts.goals, 0);
}
