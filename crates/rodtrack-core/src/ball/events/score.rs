//! Events against the truth: each truth event paired with the nearest found event of the
//! same kind within a tolerance in frames.

use super::{BallEvent, EventKind};

/// How the found events of one kind compare with the truth's.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct EventMatch {
    /// Truth events.
    pub truth: usize,
    /// Truth events with a found event paired.
    pub found: usize,
    /// Truth events without one.
    pub missed: usize,
    /// Found events paired with no truth event.
    pub false_events: usize,
    /// The pairs: `(index in truth, index in found)`.
    pub pairs: Vec<(usize, usize)>,
}

/// True when `a` and `b` are the same kind of event (for goals: into the same goal).
pub fn same_kind(a: &EventKind, b: &EventKind) -> bool {
    match (a, b) {
        (EventKind::Goal { goal: ga, .. }, EventKind::Goal { goal: gb, .. }) => ga == gb,
        _ => a.name() == b.name(),
    }
}

/// Pairs the events named `name` (`goal`, `shot`, ...): in the truth's order, each truth event
/// takes the nearest unpaired found event of the same kind ([`same_kind`]) within
/// `tolerance_frames`; found events left over are false.
///
/// ```
/// use rodtrack_core::ball::events::{match_events, BallEvent, EventKind, Side};
/// use rodtrack_core::Timestamp;
/// let goal = |frame, goal| BallEvent {
///     frame,
///     timestamp_ns: Timestamp(0),
///     kind: EventKind::Goal { side: goal, goal, score: [0, 0] },
/// };
/// let truth = [goal(100, Side::B), goal(500, Side::A)];
/// let found = [goal(103, Side::B), goal(505, Side::B)];
/// let m = match_events(&truth, &found, "goal", 10);
/// assert_eq!((m.found, m.missed, m.false_events), (1, 1, 1));
/// ```
pub fn match_events(
    truth: &[BallEvent],
    found: &[BallEvent],
    name: &str,
    tolerance_frames: u64,
) -> EventMatch {
    let mut m = EventMatch::default();
    let mut used = vec![false; found.len()];
    for (i, t) in truth
        .iter()
        .enumerate()
        .filter(|(_, e)| e.kind.name() == name)
    {
        m.truth += 1;
        let best = found
            .iter()
            .enumerate()
            .filter(|(j, f)| !used[*j] && same_kind(&t.kind, &f.kind))
            .map(|(j, f)| (j, f.frame.abs_diff(t.frame)))
            .filter(|&(_, d)| d <= tolerance_frames)
            .min_by_key(|&(_, d)| d);
        match best {
            Some((j, _)) => {
                used[j] = true;
                m.found += 1;
                m.pairs.push((i, j));
            }
            None => m.missed += 1,
        }
    }
    m.false_events = found
        .iter()
        .enumerate()
        .filter(|(j, f)| f.kind.name() == name && !used[*j])
        .count();
    m
}

/// The score after the last goal of `events` (`[a, b]`; `[0, 0]` without a goal).
pub fn final_score(events: &[BallEvent]) -> [u32; 2] {
    events
        .iter()
        .filter_map(|e| match e.kind {
            EventKind::Goal { score, .. } => Some(score),
            _ => None,
        })
        .next_back()
        .unwrap_or([0, 0])
}

/// Over the paired shots of `m` (from [`match_events`] with `"shot"`): how many name the
/// truth's rod, and the worst relative speed error (0 without a pair).
pub fn shot_agreement(truth: &[BallEvent], found: &[BallEvent], m: &EventMatch) -> (usize, f64) {
    let (mut rods, mut worst) = (0usize, 0.0f64);
    for &(i, j) in &m.pairs {
        if let (
            EventKind::Shot {
                rod: rt,
                speed_mm_s: st,
                ..
            },
            EventKind::Shot {
                rod: rf,
                speed_mm_s: sf,
                ..
            },
        ) = (truth[i].kind, found[j].kind)
        {
            rods += usize::from(rt == rf);
            if st > 0.0 {
                worst = worst.max(((sf - st) / st).abs());
            }
        }
    }
    (rods, worst)
}
