//! `rodtrack demo`: the whole job on the built-in simulator, with nothing to set up.

use crate::score::{print_table, score};
use anyhow::Result;
use rodtrack_core::{
    CameraId, CameraPipeline, FrameSetFilter, FrameView, Measurement, Mode, Status,
};
use std::io::{IsTerminal, Write};
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
        "default",
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
    // 2. Track every frame in both modes: rodtrack's and the paper's, on the same frames.
    let mut pipes: Vec<CameraPipeline> = cals
        .iter()
        .map(|c| CameraPipeline::new(c, Mode::Enhanced))
        .collect::<Result<_, _>>()?;
    // The console's overlays: the rods' constant parts, once per camera.
    let geometry: Vec<rodtrack_console::CameraOverlays> = pipes
        .iter()
        .map(|p| rodtrack_console::CameraOverlays::new(p.rods()))
        .collect();
    let mut paper: Vec<Option<CameraPipeline>> = cals
        .iter()
        .map(|c| CameraPipeline::new(c, Mode::Paper).ok())
        .collect();
    let mut bufs: Vec<Vec<u8>> = (0..ncam)
        .map(|c| sim.frame_bytes(c).map(|b| vec![0u8; b]))
        .collect::<Result<_, _>>()?;
    let mut rows: Vec<Measurement> = Vec::new();
    let mut filtered: Vec<Measurement> = Vec::new();
    let mut set_filter = FrameSetFilter::new(Mode::Enhanced, ncam > 1);
    let mut all_filtered: Vec<(Measurement, Option<bool>)> = Vec::new();
    let mut all_fused: Vec<(Measurement, Option<bool>)> = Vec::new();
    let mut all: Vec<(Measurement, Option<bool>)> = Vec::new();
    let mut all_paper: Vec<(Measurement, Option<bool>)> = Vec::new();
    let mut truth: Vec<(Measurement, Option<bool>)> = Vec::new();
    let mut proc_us: Vec<f64> = Vec::new();
    let mut render_s = 0.0;
    // Per-row errors for analysis, when asked for (RODTRACK_ERRORS_CSV=path).
    let mut errors_csv = match std::env::var_os("RODTRACK_ERRORS_CSV") {
        Some(p) => {
            let mut f = std::io::BufWriter::new(std::fs::File::create(&p)?);
            writeln!(f, "frame,camera,rod,true_position_mm,true_angle_rad,position_error_mm,angle_error_rad,theta_steps")?;
            Some(f)
        }
        None => None,
    };
    let console = match args.console {
        Some(addr) => {
            let c = rodtrack_console::Console::start(addr, None)?;
            println!("web console: {}", c.url());
            Some(c)
        }
        None => None,
    };
    let mut overlays = Vec::new();
    let tty = std::io::stdout().is_terminal() && console.is_none();
    let mut last_draw = Instant::now();
    let t_loop = Instant::now();
    let n = sim.frame_count();
    for f in 0..n {
        rows.clear();
        for c in 0..ncam {
            let t0 = Instant::now();
            let meta = sim.render(f, c, &mut bufs[c])?;
            render_s += t0.elapsed().as_secs_f64();
            let view = FrameView::new(&bufs[c], meta.width, meta.height, meta.stride, meta.format)?;
            let t1 = Instant::now();
            pipes[c].process(&view, meta.frame_id, meta.timestamp_s, &mut rows)?;
            proc_us.push(t1.elapsed().as_secs_f64() * 1e6);
            if std::env::var_os("RODTRACK_DEBUG").is_some() && f % 50 == 0 {
                for (tr, r) in pipes[c].rods().iter().zip(pipes[c].last_results()) {
                    eprintln!(
                        "frame {f} cam {c} rod {}: {} {} ncc {:.2} amp {:.2} edge std {:.3} step {} theta {:.2}",
                        tr.rod(), r.status, r.reason, r.ncc, r.amp_ratio, r.edge_std_mm, r.gray_step, r.theta_steps
                    );
                }
            }
            if let Some(p) = paper[c].as_mut() {
                let mut prow = Vec::new();
                p.process(&view, meta.frame_id, meta.timestamp_s, &mut prow)?;
                all_paper.extend(prow.into_iter().map(|m| (m, None)));
            }
            let tr_rows = sim.truth(f, c)?;
            if let Some(w) = errors_csv.as_mut() {
                for (tr, r) in pipes[c].rods().iter().zip(pipes[c].last_results()) {
                    let Some(t) = tr_rows.iter().find(|t| t.m.rod == tr.rod()) else {
                        continue;
                    };
                    if r.status == Status::Ok && t.visible {
                        writeln!(
                            w,
                            "{f},{c},{},{:.4},{:.5},{:.4},{:.5},{:.3}",
                            tr.rod(),
                            t.m.position_mm,
                            t.m.angle_rad,
                            r.position_mm - t.m.position_mm,
                            crate::score::wrap_angle(r.angle_rad - t.m.angle_rad),
                            r.theta_steps
                        )?;
                    }
                }
            }
            if std::env::var_os("RODTRACK_DEBUG").is_some() {
                for (tr, r) in pipes[c].rods().iter().zip(pipes[c].last_results()) {
                    let Some(t) = tr_rows.iter().find(|t| t.m.rod == tr.rod()) else {
                        continue;
                    };
                    let e = crate::score::wrap_angle(r.angle_rad - t.m.angle_rad);
                    if r.status == Status::Ok && e.abs() > 0.1 {
                        eprintln!(
                            "gross: frame {f} cam {c} rod {} err {e:.3} truth {:.3} w {:.1} rad/s step {} theta {:.2} amp {:.2} ncc {:.2} visible {}",
                            tr.rod(), t.m.angle_rad, t.m.angular_velocity_rad_s, r.gray_step, r.theta_steps, r.amp_ratio, r.ncc, t.visible
                        );
                    }
                }
            }
            for t in tr_rows {
                truth.push((t.m, Some(t.visible)));
            }
            // Last use of this frame: the console may take its buffer (a swap, no copy; the
            // buffer given back is rendered into next time).
            if let Some(con) = console.as_ref() {
                if con.wants_frame(c as u32) {
                    geometry[c].fill(pipes[c].last_results(), &mut overlays);
                    con.publish_frame_buffer(
                        c as u32,
                        &mut bufs[c],
                        meta.width,
                        meta.height,
                        meta.stride,
                        meta.format,
                        meta.frame_id,
                        meta.timestamp_s,
                        &overlays,
                    );
                }
            }
        }
        all.extend(rows.iter().map(|m| (*m, None)));
        filtered.clear();
        set_filter.process(&rows, &mut filtered);
        if let Some(con) = console.as_ref() {
            con.publish_rows(&filtered);
            if f % 50 == 0 {
                let mut recent = proc_us[proc_us.len().saturating_sub(100)..].to_vec();
                con.publish_stats(&rodtrack_console::PipelineStats {
                    frames: f as u64 + 1,
                    fps: (f + 1) as f64 / t_loop.elapsed().as_secs_f64().max(1e-9),
                    frame_time_us: median(&mut recent) * ncam as f64,
                    dropped_frames: 0,
                    bad_frames: 0,
                });
            }
        }
        for m in &filtered {
            if m.camera == CameraId::Fused {
                all_fused.push((*m, None));
            } else {
                all_filtered.push((*m, None));
            }
        }
        if last_draw.elapsed().as_millis() >= 100 || f + 1 == n {
            last_draw = Instant::now();
            let shown: Vec<Measurement> = if ncam > 1 {
                filtered
                    .iter()
                    .filter(|m| m.camera == CameraId::Fused)
                    .copied()
                    .collect()
            } else {
                filtered.clone()
            };
            draw_table(&shown, f, n, &proc_us, t_loop.elapsed().as_secs_f64(), tty);
        }
    }
    println!();
    println!(
        "rendered {} frames x {ncam} cameras in {:.1} s (simulator); tracking: median {:.1} us per camera frame (all rods)",
        n,
        render_s,
        median(&mut proc_us)
    );
    println!("\naccuracy against ground truth, rodtrack (enhanced mode), each camera's raw measurements:");
    print_table(&score(&truth, &all));
    println!("\nrodtrack, each camera through the temporal filter:");
    print_table(&score(&truth, &all_filtered));
    if ncam > 1 {
        println!("\nrodtrack, cameras fused and filtered (one row per rod):");
        print_table(&score(&truth, &all_fused));
    }
    println!("\nthe paper's algorithm on the same frames (paper mode):");
    print_table(&score(&truth, &all_paper));
    println!("\ndone in {:.1} s", t_start.elapsed().as_secs_f64());
    if let Some(con) = console {
        println!("web console still at {}: press Ctrl-C to quit", con.url());
        con.wait();
    }
    Ok(())
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return 0.0;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    v[v.len() / 2]
}

fn draw_table(
    rows: &[Measurement],
    f: usize,
    n: usize,
    proc_us: &[f64],
    elapsed_s: f64,
    tty: bool,
) {
    let mut out = String::new();
    if tty {
        out.push_str("\x1b[H\x1b[2J");
    }
    let recent = &proc_us[proc_us.len().saturating_sub(200)..];
    let mut r: Vec<f64> = recent.to_vec();
    let med = median(&mut r);
    out.push_str(&format!(
        "frame {:>5}/{n}   {:>6.1} frame sets/s   {:>6.1} us per camera frame (median of last 200)\n",
        f + 1,
        (f + 1) as f64 / elapsed_s.max(1e-9),
        med
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
