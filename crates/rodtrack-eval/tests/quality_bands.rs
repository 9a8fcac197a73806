//! A row's quality predicts its error: on random tables as built, through still scenes with a
//! lamp's glare on a Gray code, a hand resting over part of a marker, and gameplay (hands,
//! fast slides, a spin), the raw rows of both cameras:
//!
//! - no row `ok` has a gross error (0.2 rad or 5 mm off), whatever its quality (a reading
//!   that carries the whole evidence of a wrong Gray code, quality 0, is not `ok`);
//! - the angle error's p90 falls with the quality: that of the rows of quality >= 0.9 is no
//!   larger than that of the rows below when enough rows lie below, and band by band wherever
//!   bands hold enough rows.
//!
//! `cargo run --release -p rodtrack-eval --example quality_bands` prints the whole relation
//! over more tables and scenes (the table in `docs/quality.md`).
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_eval::quality::{bands, calibrate_table, format_bands, run_scene, Scene, ScoredRow};

/// Rows a band needs for its p90 to be compared.
const ENOUGH_ROWS: usize = 20;

#[test]
fn no_ok_row_is_grossly_wrong_and_quality_predicts_the_error() {
    let t0 = std::time::Instant::now();
    let mut rows = Vec::new();
    for seed in [1u64, 2] {
        let cal = calibrate_table(seed).unwrap();
        for kind in [Scene::Glare, Scene::PartCover, Scene::Gameplay] {
            rows.extend(run_scene(seed, &cal, kind, 30).unwrap());
        }
    }
    let b = bands(&rows);
    eprintln!(
        "{} rows ({} ok) in {:.1?}\n{}",
        rows.len(),
        rows.iter().filter(|r| r.ok).count(),
        t0.elapsed(),
        format_bands(&b)
    );
    let gross: Vec<_> = rows.iter().filter(|r| r.gross()).collect();
    assert!(
        gross.is_empty(),
        "{} rows ok with a gross error ({} of quality >= 0.9), first {:?}",
        gross.len(),
        gross.iter().filter(|r| r.quality >= 0.9).count(),
        gross.first()
    );
    // The angle error's p90 falls with the quality: rows of quality >= 0.9 against the
    // others, and band by band wherever two bands hold enough rows.
    let p90 = |mut v: Vec<f64>| -> f64 {
        v.sort_by(f64::total_cmp);
        v[((0.9 * v.len() as f64).ceil() as usize).clamp(1, v.len()) - 1]
    };
    let (high, low): (Vec<&ScoredRow>, Vec<&ScoredRow>) =
        rows.iter().filter(|r| r.ok).partition(|r| r.quality >= 0.9);
    assert!(
        high.len() >= ENOUGH_ROWS,
        "too few rows of quality >= 0.9: {}",
        high.len()
    );
    // Few rows below 0.9 are `ok` at all (most such readings are refused): compare only when
    // enough are.
    if low.len() >= ENOUGH_ROWS {
        let (p_high, p_low) = (
            p90(high.iter().map(|r| r.angle_error_rad).collect()),
            p90(low.iter().map(|r| r.angle_error_rad).collect()),
        );
        assert!(
            p_high <= p_low,
            "angle p90 {p_high:.4} rad at quality >= 0.9 above {p_low:.4} rad below it"
        );
    } else {
        eprintln!(
            "{} ok rows below quality 0.9: too few to compare",
            low.len()
        );
    }
    let filled: Vec<_> = b.iter().filter(|b| b.rows >= ENOUGH_ROWS).collect();
    for (i, upper) in filled.iter().enumerate() {
        for lower in &filled[..i] {
            assert!(
                upper.angle_rad[1] <= lower.angle_rad[1],
                "band [{:.2}, {:.2}]: angle p90 {:.4} rad above band [{:.2}, {:.2}): {:.4} rad",
                upper.lo,
                upper.hi,
                upper.angle_rad[1],
                lower.lo,
                lower.hi,
                lower.angle_rad[1]
            );
        }
    }
}
