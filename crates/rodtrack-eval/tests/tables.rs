//! `rodtrack evaluate`'s tables as built, one table through the whole path (recorded,
//! calibrated from its files with known poses, raw rows, scored per camera): both cameras
//! scored, within the accuracy issue's targets, the frames removed afterwards.
#![allow(missing_docs, clippy::unwrap_used)]

use rodtrack_eval::tables::{format_tables, run_tables, KnownPoses};

#[test]
fn one_table_as_built_is_scored_per_camera_within_the_targets() {
    let work = std::env::temp_dir().join(format!("rodtrack-tables-{}", std::process::id()));
    let r = run_tables(&[1], KnownPoses::WithAngle, &work).unwrap();
    let md = format_tables(std::slice::from_ref(&r));
    eprintln!("{md}");
    assert_eq!(r.cameras.len(), 2, "both cameras of asbuilt:1");
    for c in &r.cameras {
        let s = &c.stats;
        assert!(
            s.visible > 200,
            "camera {}: {} visible rows",
            c.camera,
            s.visible
        );
        assert_eq!(s.coverage, 1.0, "camera {}", c.camera);
        assert_eq!(s.gross + s.wrong_ok, 0, "camera {}", c.camera);
        assert!(
            s.pos_std_mm <= 0.03 && s.pos_max_mm <= 0.15,
            "camera {}: {s:?}",
            c.camera
        );
        assert!(
            s.ang_std_rad <= 0.002 && s.ang_max_rad <= 0.01,
            "camera {}: {s:?}",
            c.camera
        );
    }
    assert!(md.contains("| with angle | asbuilt:1 | 1 |"));
    assert!(
        !work.join("asbuilt-1-known").exists(),
        "the frames are removed"
    );
    let _ = std::fs::remove_dir_all(&work);
}
