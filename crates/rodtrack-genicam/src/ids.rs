//! Camera frame ids extended to a monotonic `u64`, with gap counting.
//!
//! GigE Vision 1.x block ids are 16 bits and skip 0: they go 65534, 65535, 1, 2, ... (the
//! Aravis fake camera starts at 65401). USB3 Vision and GigE Vision 2 extended ids are 64 bits.
//! [`IdExtender`] turns either into a counter that only grows, counts the frames missing
//! between two ids, and can continue after a reconnection (the camera's counter restarts).

/// The period of a 16-bit GigE block id (1..=65535).
const GEV16_PERIOD: u64 = 65_535;

/// What one raw id means.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum IdStep {
    /// A new frame: its extended id, and how many frames are missing just before it.
    Next {
        /// The extended id.
        id: u64,
        /// Frames skipped since the previous one (0 when consecutive).
        missed: u64,
    },
    /// The same id as the previous frame, or an older one (a late duplicate): drop it.
    Stale,
}

/// Extends raw camera frame ids.
#[derive(Debug, Clone, Default)]
pub(crate) struct IdExtender {
    /// The previous raw id and its extended id.
    last: Option<(u64, u64)>,
    /// The extended id the next (re)started stream's first frame gets.
    start: u64,
    /// Raw ids above 16 bits were seen: no wrapping.
    wide: bool,
}

impl IdExtender {
    /// A new extender: the first frame gets extended id `start`.
    pub(crate) fn new(start: u64) -> Self {
        IdExtender {
            last: None,
            start,
            wide: false,
        }
    }

    /// The camera's counter restarts (reconnection): the next frame gets the id after the last
    /// one plus `skipped` (frames presumed lost meanwhile).
    pub(crate) fn restart(&mut self, skipped: u64) {
        if let Some((_, e)) = self.last.take() {
            self.start = e + 1 + skipped;
        }
    }

    /// The extended id of the last frame, if any.
    #[cfg(test)]
    pub(crate) fn last_id(&self) -> Option<u64> {
        self.last.map(|(_, e)| e)
    }

    /// Classifies a raw id.
    pub(crate) fn step(&mut self, raw: u64) -> IdStep {
        if raw > 0xFFFF {
            self.wide = true;
        }
        let Some((prev_raw, prev_ext)) = self.last else {
            self.last = Some((raw, self.start));
            return IdStep::Next {
                id: self.start,
                missed: 0,
            };
        };
        let delta = if self.wide {
            match raw.checked_sub(prev_raw) {
                Some(d) if d > 0 => d,
                _ => return IdStep::Stale,
            }
        } else {
            // Position in the 1..=65535 cycle (a 0 counts as 65535).
            let pos = |r: u64| (r + GEV16_PERIOD - 1) % GEV16_PERIOD;
            let d = (pos(raw) + GEV16_PERIOD - pos(prev_raw)) % GEV16_PERIOD;
            // More than half a cycle forward is really a step back (a late packet).
            if d == 0 || d > GEV16_PERIOD / 2 {
                return IdStep::Stale;
            }
            d
        };
        let id = prev_ext + delta;
        self.last = Some((raw, id));
        IdStep::Next {
            id,
            missed: delta - 1,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ids(ext: &mut IdExtender, raws: &[u64]) -> Vec<IdStep> {
        raws.iter().map(|&r| ext.step(r)).collect()
    }

    #[test]
    fn gige_ids_wrap_from_65535_to_1() {
        let mut e = IdExtender::new(0);
        let got = ids(&mut e, &[65_533, 65_534, 65_535, 1, 2]);
        let want: Vec<IdStep> = (0..5).map(|id| IdStep::Next { id, missed: 0 }).collect();
        assert_eq!(got, want);
        // Many wraps stay monotonic.
        let mut e = IdExtender::new(0);
        let mut raw = 65_401u64;
        let mut last = None;
        for k in 0..200_000u64 {
            match e.step(raw) {
                IdStep::Next { id, missed } => {
                    assert_eq!((id, missed), (k, 0));
                    last = Some(id);
                }
                IdStep::Stale => panic!("stale at {k}"),
            }
            raw = if raw == 65_535 { 1 } else { raw + 1 };
        }
        assert_eq!(last, Some(199_999));
    }

    #[test]
    fn gaps_are_counted_across_the_wrap() {
        let mut e = IdExtender::new(10);
        let got = ids(&mut e, &[65_530, 65_534, 3, 3, 2, 7]);
        assert_eq!(
            got,
            vec![
                IdStep::Next { id: 10, missed: 0 },
                IdStep::Next { id: 14, missed: 3 },
                // 65535, 1, 2 missing
                IdStep::Next { id: 18, missed: 3 },
                IdStep::Stale,
                IdStep::Stale,
                IdStep::Next { id: 22, missed: 3 },
            ]
        );
    }

    #[test]
    fn wide_ids_do_not_wrap() {
        let mut e = IdExtender::new(0);
        let got = ids(&mut e, &[70_000, 70_001, 70_005, 70_004]);
        assert_eq!(
            got,
            vec![
                IdStep::Next { id: 0, missed: 0 },
                IdStep::Next { id: 1, missed: 0 },
                IdStep::Next { id: 5, missed: 3 },
                IdStep::Stale,
            ]
        );
    }

    #[test]
    fn restart_continues_after_the_last_id() {
        let mut e = IdExtender::new(0);
        ids(&mut e, &[65_401, 65_402, 65_403]);
        assert_eq!(e.last_id(), Some(2));
        e.restart(5);
        // The restarted camera's counter begins anew at 65401.
        assert_eq!(e.step(65_401), IdStep::Next { id: 8, missed: 0 });
        assert_eq!(e.step(65_402), IdStep::Next { id: 9, missed: 0 });
    }
}
