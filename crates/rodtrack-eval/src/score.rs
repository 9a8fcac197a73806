//! Measurements against ground truth: error statistics per rod and overall.

use crate::{EvalError, Result};
use rodtrack_core::{CameraId, Measurement, Status};
use rodtrack_io::{read_measurements_csv, read_measurements_jsonl};
use std::collections::{BTreeMap, HashMap};
use std::f64::consts::TAU;
use std::fmt::Write as _;
use std::path::Path;

/// Error statistics of one rod (or all).
#[derive(Debug, Default, Clone, serde::Serialize)]
pub struct Stats {
    /// Rows compared (reported ok on a visible marker).
    pub n: usize,
    /// Visible truth rows.
    pub visible: usize,
    /// Position error mean, mm.
    pub pos_mean_mm: f64,
    /// Position error std, mm.
    pub pos_std_mm: f64,
    /// Largest position error, mm.
    pub pos_max_mm: f64,
    /// Angle error mean (wrapped), rad.
    pub ang_mean_rad: f64,
    /// Angle error std, rad.
    pub ang_std_rad: f64,
    /// Largest angle error, rad.
    pub ang_max_rad: f64,
    /// Rows whose angle is off by a Gray step (2 pi / 32) or more, or position by 5 mm.
    pub gross: usize,
    /// Share of visible rows reported ok.
    pub coverage: f64,
    /// Rows not visible but reported ok.
    pub false_ok: usize,
    /// Rows not visible, reported ok, and wrong (angle off by more than 0.2 rad or position by
    /// more than 5 mm): the confident wrong values a controller must never get.
    pub wrong_ok: usize,
    /// Silent turn slips: ok rows that claim a known turn count (`turns_known`) whose unwrapped
    /// angle has lost or gained whole turns against the truth since the count's anchor (the
    /// first such row of its camera and rod, and again the first after rows that said the count
    /// was unknown: a re-anchoring). A multi-turn encoder must count every turn it claims.
    pub turn_slips: usize,
    #[serde(skip)]
    acc: [f64; 4],
}

impl Stats {
    fn add(&mut self, ep: f64, ea: f64) {
        self.n += 1;
        self.acc[0] += ep;
        self.acc[1] += ep * ep;
        self.acc[2] += ea;
        self.acc[3] += ea * ea;
        self.pos_max_mm = self.pos_max_mm.max(ep.abs());
        self.ang_max_rad = self.ang_max_rad.max(ea.abs());
        if ea.abs() >= TAU / 32.0 || ep.abs() >= 5.0 {
            self.gross += 1;
        }
    }
    fn finish(&mut self) {
        let n = self.n.max(1) as f64;
        self.pos_mean_mm = self.acc[0] / n;
        self.pos_std_mm = (self.acc[1] / n - self.pos_mean_mm.powi(2)).max(0.0).sqrt();
        self.ang_mean_rad = self.acc[2] / n;
        self.ang_std_rad = (self.acc[3] / n - self.ang_mean_rad.powi(2))
            .max(0.0)
            .sqrt();
        self.coverage = if self.visible > 0 {
            self.n as f64 / self.visible as f64
        } else {
            0.0
        };
    }
}

/// Signed angle difference wrapped to (-pi, pi]: the core's
/// [`wrap_pi_fold`](rodtrack_core::angle::wrap_pi_fold).
pub use rodtrack_core::angle::wrap_pi_fold as wrap_angle;

/// Reads a measurement file by extension.
pub fn read_rows(path: &Path) -> Result<Vec<(Measurement, Option<bool>)>> {
    let r = if path
        .extension()
        .is_some_and(|e| e == "jsonl" || e == "json")
    {
        read_measurements_jsonl(path)
    } else {
        read_measurements_csv(path)
    };
    r.map_err(|source| EvalError::Read {
        path: path.to_path_buf(),
        source,
    })
}

/// Scores rows against truth: per rod and overall (`None` key).
pub fn score(
    truth: &[(Measurement, Option<bool>)],
    measured: &[(Measurement, Option<bool>)],
) -> BTreeMap<Option<u32>, Stats> {
    let key = |m: &Measurement| {
        let cam = match m.camera {
            CameraId::Camera(c) => c as i64,
            CameraId::Fused => -1,
        };
        (m.frame, cam, m.rod)
    };
    let mut t: HashMap<(u64, i64, u32), (Measurement, bool)> = HashMap::new();
    let mut t_any: HashMap<(u64, u32), (Measurement, bool)> = HashMap::new();
    for (m, vis) in truth {
        let v = vis.unwrap_or(true);
        t.insert(key(m), (*m, v));
        let e = t_any.entry((m.frame, m.rod)).or_insert((*m, v));
        e.1 |= v;
    }
    let mut out: BTreeMap<Option<u32>, Stats> = BTreeMap::new();
    // Coverage counts visible truth rows per camera for camera rows, and per (frame, rod) seen
    // by any camera for fused rows.
    let fused_only =
        !measured.is_empty() && measured.iter().all(|(m, _)| m.camera == CameraId::Fused);
    if fused_only {
        for ((_, rod), (_, v)) in &t_any {
            if *v {
                out.entry(Some(*rod)).or_default().visible += 1;
                out.entry(None).or_default().visible += 1;
            }
        }
    } else {
        for (m, vis) in truth {
            if vis.unwrap_or(true) {
                out.entry(Some(m.rod)).or_default().visible += 1;
                out.entry(None).or_default().visible += 1;
            }
        }
    }
    for (m, _) in measured {
        let found = match m.camera {
            CameraId::Fused => t_any.get(&(m.frame, m.rod)).copied(),
            _ => t.get(&key(m)).copied(),
        };
        let Some((tm, visible)) = found else { continue };
        if m.status != Status::Ok {
            continue;
        }
        if !visible {
            let wrong = (m.position_mm - tm.position_mm).abs() > 5.0
                || wrap_angle(m.angle_rad - tm.angle_rad).abs() > 0.2;
            for k in [Some(m.rod), None] {
                let e = out.entry(k).or_default();
                e.false_ok += 1;
                if wrong {
                    e.wrong_ok += 1;
                }
            }
            continue;
        }
        let ep = m.position_mm - tm.position_mm;
        let ea = wrap_angle(m.angle_rad - tm.angle_rad);
        out.entry(Some(m.rod)).or_default().add(ep, ea);
        out.entry(None).or_default().add(ep, ea);
    }
    // Turn counting: per (camera, rod), the unwrapped angle against the truth's, with the whole
    // turns between them fixed at the first ok row that claims a known count, and fixed again at
    // the first such row after rows that said the count was unknown (a re-anchoring).
    let mut origin: HashMap<(i64, u32), f64> = HashMap::new();
    for (m, _) in measured {
        if m.status != Status::Ok {
            continue;
        }
        if !m.turns_known {
            origin.remove(&(key(m).1, m.rod));
            continue;
        }
        let found = match m.camera {
            CameraId::Fused => t_any.get(&(m.frame, m.rod)).copied(),
            _ => t.get(&key(m)).copied(),
        };
        let Some((tm, _)) = found else { continue };
        let d = m.angle_unwrapped_rad - tm.angle_unwrapped_rad;
        let k = (key(m).1, m.rod);
        let o = *origin
            .entry(k)
            .or_insert(rodtrack_core::angle::whole_turns(d));
        if (d - o).abs() > std::f64::consts::PI {
            out.entry(Some(m.rod)).or_default().turn_slips += 1;
            out.entry(None).or_default().turn_slips += 1;
        }
    }
    for s in out.values_mut() {
        s.finish();
    }
    out
}

/// A score table as text, one line per rod then `all`, and a note on the columns (each line
/// ends with a newline).
pub fn format_table(table: &BTreeMap<Option<u32>, Stats>) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "{:>5} {:>7} {:>9} {:>9} {:>9} {:>10} {:>10} {:>10} {:>6} {:>8} {:>8}",
        "rod",
        "rows",
        "pos mean",
        "pos std",
        "pos max",
        "ang mean",
        "ang std",
        "ang max",
        "gross",
        "coverage",
        "false ok"
    );
    let mut rows: Vec<_> = table.iter().filter(|(k, _)| k.is_some()).collect();
    rows.extend(table.iter().filter(|(k, _)| k.is_none()));
    for (k, s) in rows {
        let name = k.map_or("all".to_string(), |r| r.to_string());
        let _ = writeln!(
        out,
            "{:>5} {:>7} {:>9.3} {:>9.3} {:>9.3} {:>10.4} {:>10.4} {:>10.4} {:>6} {:>7.1}% {:>8} {:>8} {:>6}",
            name,
            s.n,
            s.pos_mean_mm,
            s.pos_std_mm,
            s.pos_max_mm,
            s.ang_mean_rad,
            s.ang_std_rad,
            s.ang_max_rad,
            s.gross,
            100.0 * s.coverage,
            s.false_ok,
            s.wrong_ok,
            s.turn_slips
        );
    }
    let _ = writeln!(
        out,
        "(mm and rad; gross: angle off by >= 2pi/32 or position by >= 5 mm, on visible rows; \
         false ok: reported ok while the marker is not wholly visible; wrong ok: those off by \
         > 0.2 rad or > 5 mm; turns: ok rows whose claimed turn count slipped)"
    );
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn row(frame: u64, rod: u32, pos: f64, ang: f64, status: Status) -> Measurement {
        let mut m = Measurement::empty(
            frame,
            rodtrack_core::Timestamp::from_frame(frame, 200.0),
            CameraId::Camera(0),
            rod,
            status,
        );
        m.position_mm = pos;
        m.angle_rad = ang;
        m.angle_unwrapped_rad = ang;
        m.turns_known = true;
        m
    }

    #[test]
    fn wraps_angles_into_minus_pi_pi() {
        assert!((wrap_angle(TAU + 0.25) - 0.25).abs() < 1e-12);
        assert!((wrap_angle(-0.25) + 0.25).abs() < 1e-12);
        assert!((wrap_angle(std::f64::consts::PI) - std::f64::consts::PI).abs() < 1e-12);
    }

    #[test]
    fn scores_errors_coverage_and_false_ok() {
        let truth = vec![
            (row(0, 1, 10.0, 0.1, Status::Ok), Some(true)),
            (row(1, 1, 10.0, 0.1, Status::Ok), Some(true)),
            (row(2, 1, 10.0, 0.1, Status::Ok), Some(false)),
            (row(3, 1, 10.0, 0.1, Status::Ok), Some(true)),
        ];
        let measured = vec![
            (row(0, 1, 10.5, 0.1 + TAU, Status::Ok), None),
            (row(1, 1, 9.5, 0.1, Status::Ok), None),
            // Not visible, reported ok and wrong.
            (row(2, 1, 30.0, 0.1, Status::Ok), None),
            (row(3, 1, 0.0, 0.0, Status::Occluded), None),
        ];
        let t = score(&truth, &measured);
        let all = &t[&None];
        assert_eq!(
            (all.n, all.visible, all.false_ok, all.wrong_ok),
            (2, 3, 1, 1)
        );
        assert!(all.pos_mean_mm.abs() < 1e-12 && (all.pos_std_mm - 0.5).abs() < 1e-12);
        assert!(all.ang_max_rad < 1e-9 && all.gross == 0);
        assert!((all.coverage - 2.0 / 3.0).abs() < 1e-12);
        // Frame 0's unwrapped angle is a whole turn ahead: the turn count is fixed there, so
        // the ok rows after it (frames 1 and 2, visible or not) have slipped a turn.
        assert_eq!(all.turn_slips, 2);
        let text = format_table(&t);
        let lines: Vec<&str> = text.lines().collect();
        assert_eq!(lines.len(), 4, "{text}");
        assert!(lines[0].trim_start().starts_with("rod"));
        assert!(lines[1].trim_start().starts_with("1 "));
        assert!(lines[2].trim_start().starts_with("all "));
        assert!(lines[3].starts_with("(mm and rad"));
    }

    #[test]
    fn only_claimed_turn_counts_slip() {
        let truth: Vec<_> = (0..6)
            .map(|f| (row(f, 1, 0.0, 0.1, Status::Ok), Some(true)))
            .collect();
        // Frame 2 says its count is unknown; from frame 3 the count is re-anchored a turn
        // ahead: not a silent slip. Frame 5 slips a turn while claiming its count.
        let ang = [0.1, 0.1, 0.1 + TAU, 0.1 + TAU, 0.1 + TAU, 0.1 + 2.0 * TAU];
        let measured: Vec<_> = (0..6)
            .map(|f| {
                let mut m = row(f, 1, 0.0, 0.1, Status::Ok);
                m.angle_unwrapped_rad = ang[f as usize];
                m.turns_known = f != 2;
                (m, None)
            })
            .collect();
        assert_eq!(score(&truth, &measured)[&None].turn_slips, 1);
    }
}
