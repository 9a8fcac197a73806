//! [`FilterBank`]: one [`RodFilter`] per rod.

use super::{FilterConfig, Rejection, RodFilter, TurnStats};
use crate::measurement::Measurement;

/// One [`RodFilter`] per rod, found by rod id. Filters are created the first time a rod is seen
/// (the only allocation); give it the rods up front with [`FilterBank::with_rods`] to avoid even
/// that.
#[derive(Debug, Clone)]
pub struct FilterBank {
    cfg: FilterConfig,
    filters: Vec<(u32, RodFilter)>,
}

impl FilterBank {
    /// An empty bank.
    pub fn new(cfg: FilterConfig) -> FilterBank {
        FilterBank {
            cfg,
            filters: Vec::new(),
        }
    }

    /// A bank with a filter for each of `rods`.
    pub fn with_rods(cfg: FilterConfig, rods: impl IntoIterator<Item = u32>) -> FilterBank {
        let mut b = FilterBank::new(cfg);
        for r in rods {
            b.filter_mut(r);
        }
        b
    }

    /// The filter of `rod`, if it exists.
    pub fn filter(&self, rod: u32) -> Option<&RodFilter> {
        self.filters.iter().find(|(r, _)| *r == rod).map(|(_, f)| f)
    }

    /// The filter of `rod`, created when missing.
    pub fn filter_mut(&mut self, rod: u32) -> &mut RodFilter {
        let i = match self.filters.iter().position(|(r, _)| *r == rod) {
            Some(i) => i,
            None => {
                self.filters.push((rod, RodFilter::new(self.cfg)));
                self.filters.len() - 1
            }
        };
        &mut self.filters[i].1
    }

    /// Filters one row through its rod's filter. The row of a bad frame stays `bad_frame`
    /// (quality 0) after the filter: the filter coasts through it, but the output must say
    /// that the frame was unusable.
    pub fn update(&mut self, m: &Measurement) -> Measurement {
        self.update_corroborated(m, false)
    }

    /// [`FilterBank::update`] with [`RodFilter::update_corroborated`].
    pub fn update_corroborated(&mut self, m: &Measurement, corroborated: bool) -> Measurement {
        let mut out = self.filter_mut(m.rod).update_corroborated(m, corroborated);
        if m.status == crate::Status::BadFrame {
            out.status = crate::Status::BadFrame;
            out.quality = 0.0;
        }
        out
    }

    /// Checks a row against its rod's filter (see [`RodFilter::check`]).
    pub fn check(&self, m: &Measurement) -> Result<(), Rejection> {
        match self.filter(m.rod) {
            Some(f) => f.check(m),
            None => Err(Rejection::Unconfirmed),
        }
    }

    /// Re-anchors `rod`'s turn count by hand (see [`RodFilter::reanchor_turns`]).
    pub fn reanchor_turns(&mut self, rod: u32, turns: i64) {
        self.filter_mut(rod).reanchor_turns(turns);
    }

    /// The turn count's counters of every rod together.
    pub fn turn_stats(&self) -> TurnStats {
        let mut t = TurnStats::default();
        for (_, f) in &self.filters {
            t.add(&f.turn_stats());
        }
        t
    }
}
