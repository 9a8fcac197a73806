//! `rodtrack score`: measurements against ground truth (scored by [`rodtrack_eval::score`]),
//! and the ball's events against the truth's (paired by
//! [`rodtrack_core::ball::events::match_events`]).

use anyhow::{bail, Context, Result};
use rodtrack_core::ball::events::{final_score, match_events, shot_agreement, BallEvent};
use rodtrack_core::CameraId;
use rodtrack_eval::score::{format_table, read_rows, score};
use std::path::PathBuf;

/// Arguments of `rodtrack score`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Ground truth (CSV with a `visible` column, as `rodtrack simulate` writes).
    #[arg(long, requires = "measured")]
    pub truth: Option<PathBuf>,
    /// Measurements (CSV or JSON Lines).
    #[arg(long, requires = "truth")]
    pub measured: Option<PathBuf>,
    /// The truth's events (`events_truth.jsonl`, as `rodtrack simulate` writes).
    #[arg(long, requires = "events")]
    pub events_truth: Option<PathBuf>,
    /// The events found (`track --events-out`), scored against --events-truth.
    #[arg(long, requires = "events_truth")]
    pub events: Option<PathBuf>,
    /// Events within this many frames of the truth's are the same event (0.12 s at 200 fps:
    /// goals, shots and outs are found within a frame of the truth's, stops 0 to 23 frames
    /// late in the simulator's `goals` runs; docs/ball.md).
    #[arg(long, default_value_t = 24)]
    pub events_tolerance_frames: u64,
    /// Write the table as JSON here too.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    if let (Some(t), Some(f)) = (&args.events_truth, &args.events) {
        let truth = rodtrack_io::read_events_jsonl(t)?;
        let found = rodtrack_io::read_events_jsonl(f)?;
        print!(
            "{}",
            events_table(&truth, &found, args.events_tolerance_frames)
        );
    }
    let (Some(truth), Some(measured)) = (&args.truth, &args.measured) else {
        if args.events.is_none() {
            bail!("give --truth and --measured (rows), or --events-truth and --events");
        }
        return Ok(());
    };
    let truth = read_rows(truth)?;
    let measured = read_rows(measured)?;
    // Camera rows and fused rows are scored apart (fused rows have their own coverage).
    let (fused, cams): (Vec<_>, Vec<_>) = measured
        .into_iter()
        .partition(|(m, _)| m.camera == CameraId::Fused);
    if !fused.is_empty() && !cams.is_empty() {
        println!("each camera:");
        print!("{}", format_table(&score(&truth, &cams)));
        println!("\nfused:");
    }
    let table = if fused.is_empty() {
        score(&truth, &cams)
    } else {
        score(&truth, &fused)
    };
    print!("{}", format_table(&table));
    if let Some(p) = args.json {
        let v: Vec<_> = table
            .iter()
            .map(|(k, s)| serde_json::json!({"rod": k, "stats": s}))
            .collect();
        std::fs::write(&p, serde_json::to_string_pretty(&v)?)
            .with_context(|| format!("writing {}", p.display()))?;
    }
    Ok(())
}

/// The events found against the truth's, per kind: truth, found, missed, false; the final
/// scores; the shots' rods and speeds.
fn events_table(truth: &[BallEvent], found: &[BallEvent], tolerance_frames: u64) -> String {
    let mut out = format!("events (within {tolerance_frames} frames):\n");
    out.push_str("event          truth  found  missed  false\n");
    for name in ["goal", "shot", "ball_out", "ball_stopped"] {
        let m = match_events(truth, found, name, tolerance_frames);
        out.push_str(&format!(
            "{name:<13} {:>6} {:>6} {:>7} {:>6}\n",
            m.truth, m.found, m.missed, m.false_events
        ));
        if name == "shot" && !m.pairs.is_empty() {
            let (rods, worst) = shot_agreement(truth, found, &m);
            out.push_str(&format!(
                "  shots paired: rod right {rods}/{}, speed error at most {:.1} %\n",
                m.pairs.len(),
                100.0 * worst
            ));
        }
    }
    let (st, sf) = (final_score(truth), final_score(found));
    out.push_str(&format!(
        "final score (a:b): {}:{} found, {}:{} truth{}\n",
        sf[0],
        sf[1],
        st[0],
        st[1],
        if st == sf { "" } else { "  <- differs" }
    ));
    out
}
