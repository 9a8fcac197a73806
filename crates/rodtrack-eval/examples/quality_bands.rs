//! What a row's quality says about its error: `asbuilt:SEED` tables for SEED in
//! `FIRST..FIRST+TABLES`, each through every scene of `rodtrack_eval::quality` (`FRAMES`
//! frames each, both cameras), the raw rows grouped by quality band, and the coverage of
//! visible rows on the still and slow scenes per table (worst, median).
//!
//! ```text
//! cargo run --release -p rodtrack-eval --example quality_bands -- [TABLES [FRAMES [FIRST]]]
//! ```
//!
//! Defaults: 12 tables, 60 frames, first seed 1. `QUALITY_ROWS=1` prints the worst rows of
//! the top bands; `QUALITY_CSV=FILE`
//! writes every row with the tracker's diagnostics.

use rodtrack_eval::quality::{
    bands, calibrate_table, coverage, format_bands, run_scene, Scene, ScoredRow,
};

/// One table's coverage of one scene: (seed, coverage, visible rows).
type TableCoverage = (u64, f64, usize);

fn arg(i: usize, default: u64) -> Result<u64, String> {
    match std::env::args().nth(i) {
        None => Ok(default),
        Some(v) => v
            .parse()
            .map_err(|_| format!("argument {i}: `{v}` is not a whole number")),
    }
}

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let tables = arg(1, 12)?;
    let frames = arg(2, 60)? as usize;
    let first = arg(3, 1)?;
    let t0 = std::time::Instant::now();
    let mut all: Vec<ScoredRow> = Vec::new();
    // Per scene: each table's coverage of visible rows.
    let mut cov: Vec<(Scene, Vec<TableCoverage>)> =
        Scene::ALL.iter().map(|&s| (s, Vec::new())).collect();
    for seed in first..first + tables {
        let cal = calibrate_table(seed)?;
        eprintln!("asbuilt:{seed} calibrated, {:.1?}", t0.elapsed());
        for (kind, c) in cov.iter_mut() {
            let rows = run_scene(seed, &cal, *kind, frames)?;
            let vis = rows.iter().filter(|r| r.visible).count();
            c.push((seed, coverage(&rows), vis));
            eprintln!("  {} {:.1?}", kind.name(), t0.elapsed());
            all.extend(rows);
        }
        eprintln!("asbuilt:{seed} done, {:.1?}", t0.elapsed());
    }
    println!(
        "{tables} tables as built (asbuilt:{first}..{}), {frames} frames per scene and camera, \
         raw rows of both cameras ({} rows, {} ok)\n",
        first + tables - 1,
        all.len(),
        all.iter().filter(|r| r.ok).count()
    );
    print!("{}", format_bands(&bands(&all)));
    println!("\ncoverage of visible rows per table (visible rows ok / visible rows):\n");
    println!("| scene | visible rows | worst | median | worst table |\n|---|---|---|---|---|");
    for (kind, c) in &cov {
        let mut v: Vec<f64> = c.iter().map(|x| x.1).collect();
        v.sort_by(f64::total_cmp);
        let worst = c
            .iter()
            .min_by(|a, b| a.1.total_cmp(&b.1))
            .map_or(0, |x| x.0);
        let vis: usize = c.iter().map(|x| x.2).sum();
        println!(
            "| {} | {vis} | {:.4} | {:.4} | asbuilt:{worst} |",
            kind.name(),
            v.first().copied().unwrap_or(1.0),
            v.get(v.len() / 2).copied().unwrap_or(1.0)
        );
    }
    if std::env::var("QUALITY_ROWS").is_ok() {
        let mut top: Vec<&ScoredRow> = all.iter().filter(|r| r.ok && r.quality >= 0.8).collect();
        top.sort_by(|a, b| b.angle_error_rad.total_cmp(&a.angle_error_rad));
        println!("\nworst ok rows of quality >= 0.8:");
        for r in top.iter().take(20) {
            println!("{r:?}");
        }
        let mut miss: Vec<&ScoredRow> = all.iter().filter(|r| r.visible && !r.ok).collect();
        miss.sort_by_key(|r| (r.scene.name(), r.result.reason));
        println!("\nvisible rows not ok: {}", miss.len());
        for r in miss.iter().take(30) {
            println!("{r:?}");
        }
    }
    if let Ok(path) = std::env::var("QUALITY_CSV") {
        let mut text = String::from(
            "seed,scene,camera,rod,frame,quality,ok,visible,angle_error_rad,position_error_mm,\
             amp_ratio,stripe_share,edge_std_mm,code_disagreement,ncc,reason\n",
        );
        for r in &all {
            let x = &r.result;
            text += &format!(
                "{},{},{},{},{},{:.5},{},{},{:.6},{:.5},{:.4},{:.4},{:.5},{:.4},{:.4},{}\n",
                r.seed,
                r.scene.name(),
                r.camera,
                r.rod,
                r.frame,
                r.quality,
                r.ok as u8,
                r.visible as u8,
                r.angle_error_rad,
                r.position_error_mm,
                x.amp_ratio,
                x.stripe_share,
                x.edge_std_mm,
                x.code_disagreement,
                x.ncc,
                x.reason
            );
        }
        std::fs::write(&path, text)?;
    }
    eprintln!("total {:.1?}", t0.elapsed());
    Ok(())
}
