//! `rodtrack demo`: the whole job on the built-in simulator, with nothing to set up.

use crate::console_hooks::{ConsoleHooks, LiveHooks};
use anyhow::Result;
use rodtrack_core::{CameraId, Measurement, Status};
use rodtrack_eval::score::{format_table, score, wrap_angle};
use rodtrack_eval::sim_run;
use rodtrack_sdk::Hooks;
use std::io::{IsTerminal, Write};
use std::sync::Arc;
use std::time::Instant;

/// Arguments of `rodtrack demo`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenario to run.
    #[arg(long, default_value = "gameplay")]
    pub scenario: String,
    /// Number of frames per camera (200 fps: 600 frames are 3 s of play).
    #[arg(long, default_value_t = 600)]
    pub frames: usize,
    /// Seed.
    #[arg(long, default_value_t = 7)]
    pub seed: u64,
    /// The table as built: `default`, a named variation, `asbuilt:SEED` or `exposure:US`, or
    /// several joined by `+` (as `simulate --setup`).
    #[arg(long, default_value = "default")]
    pub setup: String,
    /// Also serve the web console at this address (e.g. 127.0.0.1:8620) while the demo runs,
    /// and keep serving it afterwards until Ctrl-C.
    #[arg(long)]
    pub console: Option<std::net::SocketAddr>,
}

/// Runs the demo.
pub fn run(args: Args) -> Result<()> {
    let t_start = Instant::now();
    println!(
        "rodtrack demo: two simulated 1440x1080 Bayer cameras over an 8-rod table, scenario `{}`",
        args.scenario
    );
    let mut sim = rodtrack_sim::build_simulation(
        &args.scenario,
        Some(args.frames),
        args.seed,
        false,
        &args.setup,
    )?;
    let ncam = sim.cameras().len();
    // 1. Calibrate every camera from the inputs an operator would give (clicked points with
    // about 1 px error) and a reference frame.
    let mut cals = Vec::new();
    for c in 0..ncam {
        let cal = rodtrack_sim::calibrate_sim_camera(&mut sim, c, args.seed)?.calibration;
        println!(
            "calibrated camera {c}: rods {:?}",
            cal.rods.iter().map(|r| r.rod).collect::<Vec<_>>()
        );
        cals.push(cal);
    }
    // With a ball in the scenario (`ball`, `goals`, `stretch`): the ball and its events too,
    // with the cameras' table frame and ball calibrated from the same clicks.
    let truth_events = sim.events_truth();
    let ball_cal = if sim.ball_truth(0).is_none() {
        None
    } else {
        Some(rodtrack_core::calib::CalibrationFile {
            version: rodtrack_core::calib::CALIBRATION_VERSION,
            cameras: (0..ncam)
                .map(|c| sim.calibrated_camera_with_ball(c, args.seed))
                .collect::<Result<_, _>>()?,
        })
    };
    let found_events = rodtrack_io::EventVecSink::default();
    let ball_rows = rodtrack_io::BallVecSink::default();
    // 2. Track every frame in both modes, rodtrack's and the paper's, on the same frames: the
    // simulated cameras through a session, the paper's algorithm in its frame hook.
    let console = match args.console {
        Some(addr) => {
            let c = rodtrack_console::Console::start(addr, None)?;
            println!("web console: {}", c.url());
            Some(Arc::new(c))
        }
        None => None,
    };
    let tty = std::io::stdout().is_terminal() && console.is_none();
    let n = sim.frame_count();
    let t_loop = Instant::now();
    let mut last_draw: Option<Instant> = None;
    let publish = console.clone();
    let on_rows: sim_run::RowsCallback = Box::new(move |rows, progress| {
        if let Some(c) = &publish {
            c.publish_rows(rows);
        }
        let Some(last) = rows.iter().map(|m| m.frame).max() else {
            return;
        };
        let f = last as usize;
        let fused = rows.iter().any(|m| m.camera == CameraId::Fused);
        // One table per frame set: on the fused rows, or on the camera rows without fusion.
        if (ncam > 1) != fused {
            return;
        }
        if last_draw.is_some_and(|t| t.elapsed().as_millis() < 100) && f + 1 != n {
            return;
        }
        last_draw = Some(Instant::now());
        let shown: Vec<Measurement> = rows
            .iter()
            .filter(|m| ncam == 1 || m.camera == CameraId::Fused)
            .copied()
            .collect();
        let us = progress.tracker_time.as_secs_f64() * 1e6 / progress.measured.max(1) as f64;
        draw_table(&shown, f, n, us, t_loop.elapsed().as_secs_f64(), tty);
    });
    // The console's live view and status line from the session's hooks.
    let hooks = console.clone().map(|c| -> sim_run::HooksFactory {
        Box::new(move |cameras| {
            Arc::new(LiveHooks(ConsoleHooks::new(c, cameras))) as Arc<dyn Hooks>
        })
    });
    let (rows, report) = sim_run::run_sim(
        &cals,
        sim_run::SimRun {
            sim: &sim,
            every: 1,
            paper: true,
            hooks,
            on_rows: Some(on_rows),
            ball: ball_cal.as_ref().map(|cal| {
                // The ball's rows and events to the console too (its top view, the score).
                let mut events = rodtrack_io::EventMultiSink::new();
                events.push(Box::new(found_events.clone()));
                let mut rows = rodtrack_io::BallMultiSink::new();
                rows.push(Box::new(ball_rows.clone()));
                if let Some(c) = &console {
                    events.push(Box::new(crate::console_hooks::ConsoleEvents(c.clone())));
                    rows.push(Box::new(crate::console_hooks::ConsoleBall(c.clone())));
                }
                sim_run::BallRun {
                    cal,
                    rows: Box::new(rows),
                    events: Box::new(events),
                }
            }),
        },
    )?;
    let loop_s = t_loop.elapsed().as_secs_f64();
    let mut truth: Vec<(Measurement, Option<bool>)> = Vec::new();
    for f in 0..n {
        for c in 0..ncam {
            for t in sim.truth(f, c)? {
                truth.push((t.m, Some(t.visible)));
            }
        }
    }
    let with_none = |v: &[Measurement]| -> Vec<(Measurement, Option<bool>)> {
        v.iter().map(|m| (*m, None)).collect()
    };
    if let Some(p) = std::env::var_os("RODTRACK_ERRORS_CSV") {
        write_errors(std::path::Path::new(&p), &truth, &rows.raw)?;
    }
    let p50_us = report
        .tracker
        .iter()
        .map(|t| t.p50.as_secs_f64() * 1e6)
        .fold(0.0, f64::max);
    println!();
    println!(
        "simulated and tracked {n} frames x {ncam} cameras in {loop_s:.1} s (the simulator renders on the CPU); tracking: median {p50_us:.1} us per camera frame (all rods)"
    );
    println!("\naccuracy against ground truth, rodtrack (enhanced mode), each camera's raw measurements:");
    print!("{}", format_table(&score(&truth, &with_none(&rows.raw))));
    println!("\nrodtrack, each camera through the temporal filter:");
    print!(
        "{}",
        format_table(&score(&truth, &with_none(&rows.filtered)))
    );
    if ncam > 1 {
        println!("\nrodtrack, cameras fused and filtered (one row per rod):");
        print!("{}", format_table(&score(&truth, &with_none(&rows.fused))));
    }
    println!("\nthe paper's algorithm on the same frames (paper mode):");
    print!("{}", format_table(&score(&truth, &with_none(&rows.paper))));
    if ball_cal.is_some() {
        if let Some(p) = std::env::var_os("RODTRACK_BALL_ERRORS_CSV") {
            write_ball_errors(std::path::Path::new(&p), &sim, &ball_rows.rows())?;
        }
        print_ball(&sim, &ball_rows.rows(), ncam);
        print_events(&truth_events, &found_events.events());
    }
    println!("\ndone in {:.1} s", t_start.elapsed().as_secs_f64());
    if let Some(con) = console {
        println!("web console still at {}: press Ctrl-C to quit", con.url());
        // The session and its hooks have ended: this is the last holder of the console.
        match Arc::try_unwrap(con) {
            Ok(c) => c.wait(),
            Err(_) => anyhow::bail!("the web console is still in use"),
        }
    }
    Ok(())
}

/// The ball's rows against the truth: the fused ones with several cameras (camera 0's with
/// one): detected on the frames where a camera sees at least half of it, and the position
/// error (and, for fast balls, the speed error) per band of the true speed.
fn print_ball(sim: &rodtrack_sim::Simulation, rows: &[rodtrack_core::ball::BallRow], ncam: usize) {
    use rodtrack_core::ball::BallStatus;
    let shown = if ncam > 1 {
        CameraId::Fused
    } else {
        CameraId::Camera(0)
    };
    // (label, true speed range mm/s): the bands, at rest or rolling, and hard shots.
    let bands = [
        ("all speeds", 0.0, f64::INFINITY),
        ("at rest or rolling at up to 2 m/s", 0.0, 2000.0),
        ("at 8 m/s or more", 8000.0, f64::INFINITY),
    ];
    println!(
        "
the ball ({shown} rows, table frame):"
    );
    for (label, lo, hi) in bands {
        let (mut errs, mut half, mut found, mut speed_errs) =
            (Vec::new(), 0usize, 0usize, Vec::new());
        for r in rows.iter().filter(|r| r.camera == shown) {
            let Some(t) = sim.ball_truth(r.frame as usize) else {
                continue;
            };
            let v = t.vx_mm_s.hypot(t.vy_mm_s);
            if !(lo..=hi).contains(&v) {
                continue;
            }
            let ok = r.status == BallStatus::Ok;
            if t.visible.iter().any(|&f| f >= 0.5) {
                half += 1;
                found += usize::from(ok);
            }
            if ok {
                errs.push((r.x_mm - t.x_mm, r.y_mm - t.y_mm));
                if v > 0.0 {
                    speed_errs.push((r.vx_mm_s.hypot(r.vy_mm_s) - v).abs() / v);
                }
            }
        }
        if half == 0 && errs.is_empty() {
            continue;
        }
        let n = errs.len().max(1) as f64;
        let mean = |f: fn(&(f64, f64)) -> f64| errs.iter().map(f).sum::<f64>() / n;
        let (mx, my) = (mean(|e| e.0), mean(|e| e.1));
        let std = (errs
            .iter()
            .map(|e| (e.0 - mx).powi(2) + (e.1 - my).powi(2))
            .sum::<f64>()
            / n)
            .sqrt();
        let max = errs.iter().map(|e| e.0.hypot(e.1)).fold(0.0, f64::max);
        // The rows' speed: the filter restarts at a kick, so the first rows after it are slow;
        // the shots' speed is in the events below.
        let speed = if lo > 0.0 && !speed_errs.is_empty() {
            speed_errs.sort_by(f64::total_cmp);
            format!(
                ", rows' speed error median {:.1} %",
                100.0 * speed_errs[speed_errs.len() / 2]
            )
        } else {
            String::new()
        };
        println!(
            "  {label}: ok on {found} of the {half} frames where a camera sees at least half of it; position error std {std:.2} mm, max {max:.2} mm over {} ok rows{speed}",
            errs.len()
        );
    }
}

/// The goals found against the scenario's, and the final scores.
fn print_events(
    truth: &[rodtrack_core::ball::events::BallEvent],
    found: &[rodtrack_core::ball::events::BallEvent],
) {
    use rodtrack_core::ball::events::{final_score, match_events, shot_agreement};
    let goals = match_events(truth, found, "goal", 20);
    let shots = match_events(truth, found, "shot", 20);
    let (st, sf) = (final_score(truth), final_score(found));
    let (rods, worst) = shot_agreement(truth, found, &shots);
    println!(
        "\nthe ball's events: goals {} of {} found, {} false; score {}:{} (truth {}:{}); shots {} of {} found, {} false, {rods} with the right rod, speed error at most {:.1} %",
        goals.found, goals.truth, goals.false_events, sf[0], sf[1], st[0], st[1],
        shots.found, shots.truth, shots.false_events, 100.0 * worst
    );
}

/// Writes every ball row beside its truth (`RODTRACK_BALL_ERRORS_CSV=path`, for analysis).
fn write_ball_errors(
    path: &std::path::Path,
    sim: &rodtrack_sim::Simulation,
    rows: &[rodtrack_core::ball::BallRow],
) -> Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        w,
        "frame,camera,status,x_mm,y_mm,speed_mm_s,true_x_mm,true_y_mm,true_speed_mm_s,visible,error_mm"
    )?;
    for r in rows {
        let Some(t) = sim.ball_truth(r.frame as usize) else {
            continue;
        };
        let visible: Vec<String> = t.visible.iter().map(|v| format!("{v:.2}")).collect();
        writeln!(
            w,
            "{},{},{},{:.3},{:.3},{:.1},{:.3},{:.3},{:.1},{},{:.3}",
            r.frame,
            r.camera,
            r.status,
            r.x_mm,
            r.y_mm,
            r.vx_mm_s.hypot(r.vy_mm_s),
            t.x_mm,
            t.y_mm,
            t.vx_mm_s.hypot(t.vy_mm_s),
            visible.join("/"),
            (r.x_mm - t.x_mm).hypot(r.y_mm - t.y_mm)
        )?;
    }
    Ok(())
}

/// Writes each `ok` row's error against the truth (`RODTRACK_ERRORS_CSV=path`, for analysis).
fn write_errors(
    path: &std::path::Path,
    truth: &[(Measurement, Option<bool>)],
    raw: &[Measurement],
) -> Result<()> {
    let mut w = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        w,
        "frame,camera,rod,true_position_mm,true_angle_rad,position_error_mm,angle_error_rad"
    )?;
    let index: std::collections::HashMap<(u64, CameraId, u32), &Measurement> = truth
        .iter()
        .filter(|(_, v)| *v == Some(true))
        .map(|(m, _)| ((m.frame, m.camera, m.rod), m))
        .collect();
    for r in raw.iter().filter(|r| r.status == Status::Ok) {
        if let Some(t) = index.get(&(r.frame, r.camera, r.rod)) {
            writeln!(
                w,
                "{},{},{},{:.4},{:.5},{:.4},{:.5}",
                r.frame,
                r.camera,
                r.rod,
                t.position_mm,
                t.angle_rad,
                r.position_mm - t.position_mm,
                wrap_angle(r.angle_rad - t.angle_rad)
            )?;
        }
    }
    Ok(())
}

fn draw_table(
    rows: &[Measurement],
    f: usize,
    n: usize,
    us_per_frame: f64,
    elapsed_s: f64,
    tty: bool,
) {
    let mut out = String::new();
    if tty {
        out.push_str("\x1b[H\x1b[2J");
    }
    out.push_str(&format!(
        "frame {:>5}/{n}   {:>6.1} frame sets/s   {:>6.1} us per camera frame (mean)\n",
        f + 1,
        (f + 1) as f64 / elapsed_s.max(1e-9),
        us_per_frame
    ));
    out.push_str(" cam rod  position_mm  angle_rad  turns  quality  status\n");
    for m in rows {
        let flag = if m.status == Status::Ok { "" } else { " <" };
        out.push_str(&format!(
            " {:>3} {:>3}  {:>11.2}  {:>9.3}  {:>5.1}  {:>7.2}  {}{}\n",
            m.camera.to_string(),
            m.rod,
            m.position_mm,
            m.angle_rad,
            m.angle_unwrapped_rad / std::f64::consts::TAU,
            m.quality,
            m.status,
            flag
        ));
    }
    if tty || f + 1 == n {
        print!("{out}");
        let _ = std::io::stdout().flush();
    }
}
