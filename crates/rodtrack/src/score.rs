//! `rodtrack score`: measurements against ground truth (scored by [`rodtrack_eval::score`]).

use anyhow::{Context, Result};
use rodtrack_core::CameraId;
use rodtrack_eval::score::{format_table, read_rows, score};
use std::path::PathBuf;

/// Arguments of `rodtrack score`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Ground truth (CSV with a `visible` column, as `rodtrack simulate` writes).
    #[arg(long)]
    pub truth: PathBuf,
    /// Measurements (CSV or JSON Lines).
    #[arg(long)]
    pub measured: PathBuf,
    /// Write the table as JSON here too.
    #[arg(long)]
    pub json: Option<PathBuf>,
}

/// Runs the command.
pub fn run(args: Args) -> Result<()> {
    let truth = read_rows(&args.truth)?;
    let measured = read_rows(&args.measured)?;
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
