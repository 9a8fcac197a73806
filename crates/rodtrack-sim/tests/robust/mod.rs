//! Shared by the robustness tests: a simulated table (a setup such as `asbuilt:N`), a
//! scenario, every camera calibrated as an operator would, tracked frame by frame in the
//! enhanced mode (the raw tracker rows and the camera's filtered rows), and every row held
//! against the ground truth.
#![allow(dead_code, clippy::unwrap_used)]

use rodtrack_core::angle::wrap_pi;
use rodtrack_core::pipeline::{CameraFilter, CameraPipeline};
use rodtrack_core::track::Mode;
use rodtrack_core::{FrameView, Measurement, RodResult, Status};
use rodtrack_sim::scene::Glare;
use rodtrack_sim::{
    apply_variation, calibrate_sim_camera, default_cameras, RenderMode, Scenario, SceneConfig,
    SimCamera, Simulation,
};
use std::f64::consts::TAU;

/// A row `ok` but this far off is a gross error (the definition).
pub const GROSS_ANGLE_RAD: f64 = 0.2;
pub const GROSS_POSITION_MM: f64 = 5.0;

/// The scene and cameras of a setup (`default`, a named variation or `asbuilt:SEED`).
pub fn table(setup: &str) -> (SceneConfig, Vec<SimCamera>) {
    let mut scene = SceneConfig::default();
    let mut cameras = default_cameras();
    apply_variation(setup, &mut scene, &mut cameras).unwrap();
    (scene, cameras)
}

/// A glare blob of `sigma_px` and `peak_dn` on rod `rod`'s top line at marker `u_mm`, with the
/// rod at `position_mm`, seen by `camera` only (or every camera).
pub fn glare_on_rod(
    scene: &SceneConfig,
    rod: usize,
    u_mm: f64,
    position_mm: f64,
    sigma_px: f64,
    peak_dn: f64,
    camera: Option<usize>,
) -> Glare {
    let r = &scene.rods[rod];
    Glare {
        at_mm: [
            r.x_mm,
            r.marker_y(u_mm, position_mm),
            r.z_mm + r.radius_mm(),
        ],
        sigma_px,
        peak_dn,
        camera,
    }
}

/// What is wrong with one camera's rows of one kind (raw or filtered).
#[derive(Debug, Clone, Default)]
pub struct Tally {
    /// Rows whose marker is wholly visible, and of those the ones reported `ok`.
    pub visible: usize,
    pub visible_ok: usize,
    /// Rows `ok` with a gross error: (frame, rod, angle error rad, position error mm, quality).
    pub gross: Vec<(u64, u32, f64, f64, f64)>,
    /// Rows `ok` while the marker is not wholly visible.
    pub false_ok: usize,
    /// The largest angle and position errors of the visible rows reported ok.
    pub max_angle_rad: f64,
    pub max_position_mm: f64,
    /// The longest run of visible frames not `ok` (counting from the rod's first `ok`), as
    /// (frames, rod, first frame of the run).
    pub longest_out: (usize, u32, u64),
    /// Rows `ok` claiming a known turn count (`turns_known`) whose `angle_unwrapped_rad` is a
    /// whole turn off the count fixed when it became known: (frame, rod, turns off).
    pub turn_slips: Vec<(u64, u32, i64)>,
}

impl Tally {
    pub fn coverage(&self) -> f64 {
        self.visible_ok as f64 / self.visible.max(1) as f64
    }
}

/// A raw row kept: the row, visible, angle and position errors, the tracker's result.
pub type KeptRow = (Measurement, bool, f64, f64, RodResult);

/// Per camera: the raw tracker's rows and the camera's filtered rows.
#[derive(Debug, Clone, Default)]
pub struct Outcome {
    pub raw: Vec<Tally>,
    pub filtered: Vec<Tally>,
    /// Per camera: the raw rows (for diagnostics).
    pub rows: Vec<Vec<KeptRow>>,
}

/// Options of a run.
#[derive(Debug, Clone, Default)]
pub struct RunOptions {
    /// Frame indices not delivered to the tracker (dropped frames).
    pub dropped: Vec<usize>,
    /// Keep every raw row in [`Outcome::rows`].
    pub keep_rows: bool,
    /// Print where the time goes.
    pub timing: bool,
    /// (camera, rod) whose marker may be glared over: not held to the recovery target.
    pub glared: Option<(usize, u32)>,
    /// Rows of rods turning faster than this (rad/s) are not held to the recovery target
    /// (blur); 0: no limit.
    pub max_rate_rad_s: f64,
}

/// A camera whose calibration refused the table (a rod's reference frame read as not `ok`).
#[derive(Debug, Clone, PartialEq)]
pub struct Refused {
    pub camera: usize,
    pub message: String,
}

/// Calibrates every camera on its reference frame (clicks drawn from `seed`), then tracks
/// every frame of `scenario` and scores each row against the truth. A camera whose
/// calibration fails stops the run with its message.
pub fn run(
    scene: SceneConfig,
    cameras: Vec<SimCamera>,
    scenario: Scenario,
    seed: u64,
    opts: &RunOptions,
) -> Result<Outcome, Refused> {
    let t0 = std::time::Instant::now();
    let mut sim = Simulation::new(scene, cameras, scenario, RenderMode::Fast)
        .unwrap()
        .with_seed(seed);
    let n_cam = sim.cameras().len();
    let mut out = Outcome::default();
    for c in 0..n_cam {
        let t1 = std::time::Instant::now();
        let cal = calibrate_sim_camera(&mut sim, c, seed)
            .map_err(|e| Refused {
                camera: c,
                message: e.to_string(),
            })?
            .calibration;
        if opts.timing {
            eprintln!(
                "sim ready {:?}, camera {c} calibrated in {:?}",
                t1 - t0,
                t1.elapsed()
            );
        }
        let mut pipe = CameraPipeline::new(&cal, Mode::Enhanced).unwrap();
        let mut filter = CameraFilter::new(Mode::Enhanced);
        let n_rod = cal.rods.len();
        let mut buf = vec![0u8; sim.frame_bytes(c).unwrap()];
        let (mut raw_t, mut fil_t) = (Tally::default(), Tally::default());
        // Per rod and kind: seen ok yet, the current run of visible not-ok frames.
        let mut state = vec![[(false, 0usize, 0u64); 2]; n_rod];
        // Per rod and kind: the whole turns between the reported and the true unwrapped angle,
        // fixed when the count became known (None while it is not).
        let mut turn_origin: Vec<[Option<i64>; 2]> = vec![[None; 2]; n_rod];
        let mut rows_kept = Vec::new();
        let (mut raw, mut filtered) = (Vec::new(), Vec::new());
        for f in 0..sim.frame_count() {
            if opts.dropped.contains(&f) {
                continue;
            }
            let meta = sim.render(f, c, &mut buf).unwrap();
            let view =
                FrameView::new(&buf, meta.width, meta.height, meta.stride, meta.format).unwrap();
            raw.clear();
            filtered.clear();
            pipe.process(&view, meta.frame_id, meta.timestamp_ns, &mut raw)
                .unwrap();
            filter.process(&raw, &mut filtered);
            let truth = sim.truth(f, c).unwrap();
            for (kind, rows, tally) in [(0, &raw, &mut raw_t), (1, &filtered, &mut fil_t)] {
                for m in rows.iter() {
                    let Some(t) = truth.iter().find(|t| t.m.rod == m.rod) else {
                        continue;
                    };
                    let ea = wrap_pi(m.angle_rad - t.m.angle_rad).abs();
                    let ep = (m.position_mm - t.m.position_mm).abs();
                    let ok = m.status == Status::Ok;
                    if kind == 0 && opts.keep_rows {
                        let i = cal.rods.iter().position(|r| r.rod == m.rod).unwrap();
                        rows_kept.push((*m, t.visible, ea, ep, pipe.last_results()[i]));
                    }
                    if ok && (ea > GROSS_ANGLE_RAD || ep > GROSS_POSITION_MM) {
                        tally.gross.push((m.frame, m.rod, ea, ep, m.quality));
                    }
                    let Some(ri) = cal.rods.iter().position(|r| r.rod == m.rod) else {
                        continue;
                    };
                    let origin = &mut turn_origin[ri][kind];
                    if !m.turns_known {
                        *origin = None;
                    } else if ok {
                        let turns = ((m.angle_unwrapped_rad - t.m.angle_unwrapped_rad) / TAU)
                            .round() as i64;
                        match *origin {
                            None => *origin = Some(turns),
                            Some(o) if o != turns => {
                                tally.turn_slips.push((m.frame, m.rod, turns - o));
                            }
                            Some(_) => {}
                        }
                    }
                    let st = &mut state[ri][kind];
                    if !t.visible {
                        tally.false_ok += ok as usize;
                        st.1 = 0;
                        continue;
                    }
                    let fast = opts.max_rate_rad_s > 0.0
                        && t.m.angular_velocity_rad_s.abs() > opts.max_rate_rad_s;
                    let measurable = !fast && opts.glared != Some((c, m.rod));
                    tally.visible += 1;
                    if ok {
                        tally.visible_ok += 1;
                        tally.max_angle_rad = tally.max_angle_rad.max(ea);
                        tally.max_position_mm = tally.max_position_mm.max(ep);
                        st.0 = true;
                        st.1 = 0;
                    } else if !measurable {
                        st.1 = 0;
                    } else if st.0 {
                        if st.1 == 0 {
                            st.2 = m.frame;
                        }
                        st.1 += 1;
                        if st.1 > tally.longest_out.0 {
                            tally.longest_out = (st.1, m.rod, st.2);
                        }
                    }
                }
            }
        }
        out.raw.push(raw_t);
        out.filtered.push(fil_t);
        out.rows.push(rows_kept);
    }
    Ok(out)
}

/// The first camera of a setup whose calibration refuses the table as built, without any
/// addition (glare, a spot) to its scenario.
pub fn refused_as_built(setup: &str, seed: u64) -> Option<Refused> {
    let (scene, cameras) = table(setup);
    let sc = Scenario::by_name("static", &scene, seed)
        .unwrap()
        .with_frames(1);
    let mut sim = Simulation::new(scene, cameras, sc, RenderMode::Fast)
        .unwrap()
        .with_seed(seed);
    (0..sim.cameras().len()).find_map(|c| {
        calibrate_sim_camera(&mut sim, c, seed)
            .err()
            .map(|e| Refused {
                camera: c,
                message: e.to_string(),
            })
    })
}

/// One line per camera and kind, for the test's output.
pub fn describe(name: &str, o: &Outcome) -> String {
    let mut s = String::new();
    for (c, (r, f)) in o.raw.iter().zip(&o.filtered).enumerate() {
        for (kind, t) in [("raw", r), ("filtered", f)] {
            s += &format!(
                "{name} camera {c} {kind}: visible {} coverage {:.4}, gross {} (first {:?}), \
                 false ok {}, max error {:.4} rad {:.3} mm, longest visible not ok {:?}, \
                 turn slips {}\n",
                t.visible,
                t.coverage(),
                t.gross.len(),
                t.gross.first(),
                t.false_ok,
                t.max_angle_rad,
                t.max_position_mm,
                t.longest_out,
                t.turn_slips.len()
            );
        }
    }
    s
}
