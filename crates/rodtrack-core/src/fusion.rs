//! Fusion of the cameras that see the same rod (SPEC 4 step 6, "network"): one row per rod and
//! trigger with camera [`CameraId::Fused`], checks that the cameras are in sync and agree.
//!
//! For one trigger (the rows of every camera for the same frame id):
//!
//! 1. **Sync.** Each camera's frame id and timestamp are compared with the reference camera's:
//!    the camera that agrees (same frame id, timestamps within `sync_window_s`) with the most
//!    others, the lowest camera first on a tie. A camera that differs is reported as
//!    [`OutOfSync`] and its rows are left out of the fusion (they stay valid per-camera rows).
//! 2. **Agreement.** Every pair of usable (`ok`, quality >= `min_quality`) rows of a rod is
//!    compared: positions, and angles on the circle. Two rows disagree when a difference exceeds
//!    `disagreement_sigma * sqrt(var_a + var_b) + tolerance` (the tolerance absorbs calibration
//!    differences between cameras); each such pair is reported as a [`Disagreement`].
//! 3. **Choice.** When all rows agree they are all fused. Otherwise the rows are split into
//!    groups that agree among themselves; a group is used only when the rod's filter accepts it
//!    (its prediction says which camera is right), or, without a filter, when it is a strict
//!    majority. When no group is clearly right the fused row is `conflict` with no value (the
//!    filter then carries its prediction, still `conflict`): an `ok` row is never fused from
//!    disagreeing cameras. The usable rows left out of the chosen group are listed by
//!    [`Fuser::overruled`] (none in a conflict: no camera won); [`Fuser::flag_overruled`] marks
//!    those cameras' rows `conflict` with quality 0.
//! 4. **Fusion.** Inverse-variance weights, variance `sigma^2 / quality^2` per row; the angle is
//!    averaged on the circle (weighted mean of the wrapped differences to the heaviest row). The
//!    fused quality is `min(1, sqrt(sum quality^2))`, which keeps `sigma^2 / quality^2` equal to
//!    the fused variance until it saturates: give the filter of fused rows a noise of
//!    `sigma / sqrt(cameras)` when several cameras usually see the rod.
//!
//! With two cameras of equal noise the fused std is `1 / sqrt(2)` of one camera's.
//!
//! [`Fuser::process`] then passes each fused row through the rod's [`RodFilter`] of a
//! [`FilterBank`]; a row fused from two or more agreeing cameras is corroborated, so that on
//! the run's first frame it is `ok` at once ([`RodFilter::update_corroborated`]). Nothing is
//! allocated per trigger once the scratch buffers have grown to the number of rows.
//!
//! [`RodFilter`]: crate::filter::RodFilter
//! [`RodFilter::update_corroborated`]: crate::filter::RodFilter::update_corroborated

use crate::angle::{wrap_2pi, wrap_pi};
use crate::filter::FilterBank;
use crate::measurement::{CameraId, Measurement, Status};
use crate::time::Timestamp;

/// Tuning of a [`Fuser`].
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct FusionConfig {
    /// Largest difference between the timestamps of the cameras for one trigger, s. Default
    /// 0.001 (hardware-synchronised cameras agree to microseconds; a camera that slipped by a
    /// frame is 5 ms off at 200 fps).
    pub sync_window_s: f64,
    /// One camera's position noise std at quality 1, mm. Default 0.1 (as [`FilterConfig`]).
    ///
    /// [`FilterConfig`]: crate::filter::FilterConfig
    pub position_noise_mm: f64,
    /// One camera's angle noise std at quality 1, rad. Default 0.004.
    pub angle_noise_rad: f64,
    /// Disagreement threshold in stds of the difference. Default 4.
    pub disagreement_sigma: f64,
    /// Added to the position threshold, mm: calibration differences between cameras. Default 1.0.
    pub position_tolerance_mm: f64,
    /// Added to the angle threshold, rad. Default 0.03 (the paper's angle error bound).
    pub angle_tolerance_rad: f64,
    /// Rows with a lower quality are not fused. Default 0.2.
    pub min_quality: f64,
}

impl Default for FusionConfig {
    fn default() -> Self {
        FusionConfig {
            sync_window_s: 0.001,
            position_noise_mm: 0.1,
            angle_noise_rad: 0.004,
            disagreement_sigma: 4.0,
            position_tolerance_mm: 1.0,
            angle_tolerance_rad: 0.03,
            min_quality: 0.2,
        }
    }
}

/// Two cameras whose values for a rod differ beyond their uncertainty.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Disagreement {
    /// The trigger's frame id.
    pub frame: u64,
    /// Rod id.
    pub rod: u32,
    /// The two cameras.
    pub cameras: [CameraId; 2],
    /// Position of the first minus the second, mm.
    pub position_diff_mm: f64,
    /// Angle of the first minus the second, wrapped to `(-pi, pi]`, rad.
    pub angle_diff_rad: f64,
}

/// A camera whose row for a trigger does not match the reference camera's frame id or time.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OutOfSync {
    /// The camera.
    pub camera: CameraId,
    /// Its frame id.
    pub frame: u64,
    /// The reference camera.
    pub reference: CameraId,
    /// The reference camera's frame id.
    pub reference_frame: u64,
    /// Its timestamp minus the reference's, s.
    pub offset_s: f64,
}

/// A camera's frame id and time within one trigger.
#[derive(Debug, Clone, Copy)]
struct CameraClock {
    camera: CameraId,
    frame: u64,
    timestamp_ns: Timestamp,
    in_sync: bool,
}

/// Most rows of one rod that are compared (one per camera).
const MAX_ROWS_PER_ROD: usize = 32;

/// Fuses the rows of all cameras for one trigger. Keep one per camera network and reuse it.
#[derive(Debug, Clone)]
pub struct Fuser {
    cfg: FusionConfig,
    rows: Vec<Measurement>,
    clocks: Vec<CameraClock>,
    fused: Vec<Measurement>,
    disagreements: Vec<Disagreement>,
    out_of_sync: Vec<OutOfSync>,
    /// Per fused row of the last call: how many cameras it combines.
    combined: Vec<u32>,
    /// The usable camera rows of the last call that the fusion left out: (camera, rod).
    overruled: Vec<(CameraId, u32)>,
}

impl Fuser {
    /// A fuser with scratch buffers sized for a table of cameras and rods (they grow, once,
    /// if a network needs more), so that fusing allocates nothing per frame.
    pub fn new(cfg: FusionConfig) -> Fuser {
        Fuser {
            cfg,
            rows: Vec::with_capacity(256),
            clocks: Vec::with_capacity(MAX_ROWS_PER_ROD),
            fused: Vec::with_capacity(64),
            disagreements: Vec::with_capacity(256),
            out_of_sync: Vec::with_capacity(MAX_ROWS_PER_ROD),
            combined: Vec::with_capacity(64),
            overruled: Vec::with_capacity(64),
        }
    }

    /// The configuration.
    pub fn config(&self) -> &FusionConfig {
        &self.cfg
    }

    /// The disagreements found by the last call.
    pub fn disagreements(&self) -> &[Disagreement] {
        &self.disagreements
    }

    /// The cameras found out of sync by the last call.
    pub fn out_of_sync(&self) -> &[OutOfSync] {
        &self.out_of_sync
    }

    /// The cameras whose usable rows the last call left out, as (camera, rod): they disagreed
    /// with the group of cameras the fused row took (a conflict without a winner has none).
    pub fn overruled(&self) -> &[(CameraId, u32)] {
        &self.overruled
    }

    /// Marks `conflict` (quality 0) each camera row of `rows` that the last call overruled
    /// ([`Fuser::overruled`]); its values stay the camera's own.
    pub fn flag_overruled(&self, rows: &mut [Measurement]) {
        flag_overruled_rows(&self.overruled, rows);
    }

    /// Fuses, then filters: appends one filtered row per rod (camera `Fused`, rod order) to
    /// `out`, each fused row passed through its rod's filter in `bank`. The filters also decide
    /// between disagreeing cameras.
    pub fn process(
        &mut self,
        rows: &[Measurement],
        bank: &mut FilterBank,
        out: &mut Vec<Measurement>,
    ) {
        let mut fused = std::mem::take(&mut self.fused);
        fused.clear();
        self.fuse(rows, Some(bank), &mut fused);
        for (m, &n) in fused.iter().zip(&self.combined) {
            let mut f = bank.update_corroborated(m, n >= 2);
            if m.status == Status::Conflict && f.status != Status::BadFrame {
                // The filter's prediction (its turn count as for `predicted`), but the row
                // says that the cameras disagree.
                f.status = Status::Conflict;
            }
            out.push(f);
        }
        self.fused = fused;
    }

    /// Appends one fused row per rod (camera `Fused`, rod order) to `out`, unfiltered.
    /// `referee`, when given, decides between disagreeing cameras by its filters' predictions.
    /// Rows whose camera is already `Fused` are ignored.
    pub fn fuse(
        &mut self,
        rows: &[Measurement],
        referee: Option<&FilterBank>,
        out: &mut Vec<Measurement>,
    ) {
        self.disagreements.clear();
        self.out_of_sync.clear();
        self.combined.clear();
        self.overruled.clear();
        self.rows.clear();
        self.rows.extend(
            rows.iter()
                .filter(|m| m.camera != CameraId::Fused)
                .map(|m| m.sanitized()),
        );
        if self.rows.is_empty() {
            return;
        }
        self.rows
            .sort_unstable_by_key(|m| (m.rod, camera_key(m.camera)));
        let reference = self.check_sync();

        let mut start = 0;
        while start < self.rows.len() {
            let rod = self.rows[start].rod;
            let end = start
                + self.rows[start..]
                    .iter()
                    .position(|m| m.rod != rod)
                    .unwrap_or(self.rows.len() - start);
            let (row, n) = self.fuse_rod(start, end, reference, referee);
            out.push(row);
            self.combined.push(n);
            start = end;
        }
    }

    /// Finds the reference clock, marks and reports cameras out of sync.
    fn check_sync(&mut self) -> CameraClock {
        self.clocks.clear();
        for m in &self.rows {
            if !self.clocks.iter().any(|c| c.camera == m.camera) {
                self.clocks.push(CameraClock {
                    camera: m.camera,
                    frame: m.frame,
                    timestamp_ns: m.timestamp_ns,
                    in_sync: true,
                });
            }
        }
        self.clocks.sort_unstable_by_key(|c| camera_key(c.camera));
        let w = self.cfg.sync_window_s;
        let agree = |a: &CameraClock, b: &CameraClock| {
            a.frame == b.frame && a.timestamp_ns.seconds_since(b.timestamp_ns).abs() <= w
        };
        let mut best = 0;
        let mut best_n = 0;
        for (i, a) in self.clocks.iter().enumerate() {
            let n = self.clocks.iter().filter(|b| agree(a, b)).count();
            if n > best_n {
                best = i;
                best_n = n;
            }
        }
        let reference = self.clocks[best];
        for c in &mut self.clocks {
            if !agree(c, &reference) {
                c.in_sync = false;
                self.out_of_sync.push(OutOfSync {
                    camera: c.camera,
                    frame: c.frame,
                    reference: reference.camera,
                    reference_frame: reference.frame,
                    offset_s: c.timestamp_ns.seconds_since(reference.timestamp_ns),
                });
            }
        }
        reference
    }

    fn in_sync(&self, camera: CameraId) -> bool {
        self.clocks
            .iter()
            .find(|c| c.camera == camera)
            .is_some_and(|c| c.in_sync)
    }

    fn variances(&self, m: &Measurement) -> (f64, f64) {
        let q = m.quality.clamp(self.cfg.min_quality.max(1e-3), 1.0);
        let sp = self.cfg.position_noise_mm / q;
        let sa = self.cfg.angle_noise_rad / q;
        (sp * sp, sa * sa)
    }

    /// Fuses the rows `start..end` (one rod) into one row; with the number of cameras fused.
    fn fuse_rod(
        &mut self,
        start: usize,
        end: usize,
        reference: CameraClock,
        referee: Option<&FilterBank>,
    ) -> (Measurement, u32) {
        let rod = self.rows[start].rod;
        let mut empty = Measurement::empty(
            reference.frame,
            reference.timestamp_ns,
            CameraId::Fused,
            rod,
            Status::NotFound,
        );
        // Usable rows, as indices into self.rows.
        let mut usable = [0usize; MAX_ROWS_PER_ROD];
        let mut n = 0;
        let mut status_rank = 0;
        for i in start..end {
            let m = &self.rows[i];
            if !self.in_sync(m.camera) {
                continue;
            }
            if m.status == Status::Ok && m.quality >= self.cfg.min_quality {
                if n < MAX_ROWS_PER_ROD {
                    usable[n] = i;
                    n += 1;
                }
            } else {
                let rank = missing_rank(m.status);
                if rank > status_rank {
                    status_rank = rank;
                    empty.status = m.status;
                }
            }
        }
        if n == 0 {
            return (empty, 0);
        }
        let usable = &usable[..n];

        // Pairwise agreement, as bit masks.
        let mut agree = [0u32; MAX_ROWS_PER_ROD];
        for a in 0..n {
            agree[a] |= 1 << a;
            for b in a + 1..n {
                let (ma, mb) = (&self.rows[usable[a]], &self.rows[usable[b]]);
                let (vpa, vaa) = self.variances(ma);
                let (vpb, vab) = self.variances(mb);
                let dp = ma.position_mm - mb.position_mm;
                let da = wrap_pi(ma.angle_rad - mb.angle_rad);
                let k = self.cfg.disagreement_sigma;
                let ok_p = dp.abs() <= k * (vpa + vpb).sqrt() + self.cfg.position_tolerance_mm;
                let ok_a = da.abs() <= k * (vaa + vab).sqrt() + self.cfg.angle_tolerance_rad;
                if ok_p && ok_a {
                    agree[a] |= 1 << b;
                    agree[b] |= 1 << a;
                } else {
                    self.disagreements.push(Disagreement {
                        frame: reference.frame,
                        rod,
                        cameras: [ma.camera, mb.camera],
                        position_diff_mm: dp,
                        angle_diff_rad: da,
                    });
                }
            }
        }
        let all = if n == 32 { u32::MAX } else { (1u32 << n) - 1 };
        if (0..n).all(|a| agree[a] == all) {
            return (self.combine(usable, all, reference), n as u32);
        }

        // Groups that agree among themselves: each row with the rows it agrees with, kept when
        // they all agree pairwise.
        let is_group = |g: u32| (0..n).all(|a| g & (1 << a) == 0 || agree[a] & g == g);
        let mut best: Option<(u32, bool)> = None; // (group, tie)
        let consider = |g: u32, best: &mut Option<(u32, bool)>| match *best {
            None => *best = Some((g, false)),
            Some((b, _)) if b == g => {}
            Some((b, _)) if g.count_ones() > b.count_ones() => *best = Some((g, false)),
            Some((b, _)) if g.count_ones() == b.count_ones() => *best = Some((b, true)),
            Some(_) => {}
        };
        match referee {
            Some(bank) => {
                for &g in &agree[..n] {
                    if is_group(g) {
                        let m = self.combine(usable, g, reference);
                        if bank.check(&m).is_ok() {
                            consider(g, &mut best);
                        }
                    }
                }
            }
            None => {
                for &g in &agree[..n] {
                    if is_group(g) && 2 * g.count_ones() as usize > n {
                        consider(g, &mut best);
                    }
                }
            }
        }
        let chosen = match best {
            Some((g, false)) => g,
            _ => 0,
        };
        if chosen == 0 {
            // No winner, so no loser: only the fused row reports the conflict.
            empty.status = Status::Conflict;
            return (empty, 0);
        }
        for (a, &i) in usable.iter().enumerate() {
            if chosen & (1 << a) == 0 {
                self.overruled.push((self.rows[i].camera, rod));
            }
        }
        (self.combine(usable, chosen, reference), chosen.count_ones())
    }

    /// The inverse-variance fusion of the usable rows selected by `mask`.
    fn combine(&self, usable: &[usize], mask: u32, reference: CameraClock) -> Measurement {
        let mut heaviest = usable[0];
        let mut heaviest_w = 0.0;
        for (a, &i) in usable.iter().enumerate() {
            if mask & (1 << a) != 0 {
                let w = 1.0 / self.variances(&self.rows[i]).1;
                if w > heaviest_w {
                    heaviest = i;
                    heaviest_w = w;
                }
            }
        }
        let r = &self.rows[heaviest];
        let (mut wp_sum, mut p_sum, mut wa_sum, mut a_sum) = (0.0, 0.0, 0.0, 0.0);
        let (mut v_sum, mut av_sum, mut q2) = (0.0, 0.0, 0.0);
        for (a, &i) in usable.iter().enumerate() {
            if mask & (1 << a) == 0 {
                continue;
            }
            let m = &self.rows[i];
            let (vp, va) = self.variances(m);
            let (wp, wa) = (1.0 / vp, 1.0 / va);
            wp_sum += wp;
            p_sum += wp * m.position_mm;
            v_sum += wp * m.velocity_mm_s;
            wa_sum += wa;
            a_sum += wa * wrap_pi(m.angle_rad - r.angle_rad);
            av_sum += wa * m.angular_velocity_rad_s;
            q2 += m.quality * m.quality;
        }
        let da = a_sum / wa_sum;
        Measurement {
            frame: reference.frame,
            timestamp_ns: reference.timestamp_ns,
            camera: CameraId::Fused,
            rod: r.rod,
            position_mm: p_sum / wp_sum,
            angle_rad: wrap_2pi(r.angle_rad + da),
            angle_unwrapped_rad: r.angle_unwrapped_rad + da,
            velocity_mm_s: v_sum / wp_sum,
            angular_velocity_rad_s: av_sum / wa_sum,
            quality: q2.sqrt().min(1.0),
            status: Status::Ok,
            turns_known: r.turns_known,
        }
        .sanitized()
    }
}

/// Marks `conflict` (quality 0) each `ok` or `predicted` row of `rows` whose (camera, rod) is
/// in `overruled` (a list from [`Fuser::overruled`]); its values stay the camera's own.
pub fn flag_overruled_rows(overruled: &[(CameraId, u32)], rows: &mut [Measurement]) {
    for m in rows {
        if overruled.contains(&(m.camera, m.rod))
            && matches!(m.status, Status::Ok | Status::Predicted)
        {
            m.status = Status::Conflict;
            m.quality = 0.0;
        }
    }
}

/// Sort key of a camera: cameras by index, the fused row last.
fn camera_key(c: CameraId) -> u64 {
    match c {
        CameraId::Camera(i) => i as u64,
        CameraId::Fused => u64::MAX,
    }
}

/// Which missing-measurement status a fused row without value reports: the most informative.
fn missing_rank(s: Status) -> u8 {
    match s {
        Status::Occluded => 5,
        Status::NotFound => 4,
        Status::OutOfView => 3,
        Status::Predicted => 2,
        Status::Lost => 1,
        Status::Conflict => 6,
        Status::BadFrame | Status::Ok => 0,
    }
}
