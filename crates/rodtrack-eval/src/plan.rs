//! What each scenario runs: which part of its timeline, and every how many frames.

/// Which part of a scenario's timeline is processed.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Span {
    /// The whole timeline, every `n`-th frame (slow motions: the camera at 200/n fps).
    Whole(usize),
    /// The first `n` frames at the full 200 fps.
    First(usize),
}

/// Default spans: about 9,300 frame sets in all (a few minutes on 2 cores).
const DEFAULT_SPANS: [(&str, Span); 9] = [
    ("exp1", Span::Whole(3)),
    ("exp2", Span::Whole(8)),
    ("exp3", Span::Whole(6)),
    ("spin600", Span::First(1000)),
    ("spin3000", Span::First(1000)),
    ("lighting", Span::Whole(5)),
    ("gameplay", Span::First(1200)),
    ("sweep", Span::Whole(5)),
    ("static", Span::First(600)),
];

/// What one scenario runs: `frames` of the timeline (200 fps), every `stride`-th processed.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct Plan {
    /// Scenario name.
    pub name: String,
    /// Frames of the timeline simulated (None: the whole scenario).
    pub frames: Option<usize>,
    /// Every `stride`-th frame is rendered and processed.
    pub stride: usize,
}

/// The plan of scenario `name` at frame scale `scale`: above 1, more frames (a smaller
/// stride); below 1, a shorter part of the timeline (the stride stays, so that the temporal
/// filter sees the same frame rate).
pub fn plan_for(name: &str, scale: f64, full_frames: usize) -> Plan {
    let span = DEFAULT_SPANS
        .iter()
        .find(|(n, _)| *n == name)
        .map_or(Span::First(600), |(_, s)| *s);
    let scale = if scale.is_finite() && scale > 0.0 {
        scale
    } else {
        1.0
    };
    let (frames, stride) = match span {
        Span::Whole(s) if scale >= 1.0 => (None, ((s as f64 / scale).round() as usize).max(1)),
        Span::Whole(s) => (Some((full_frames as f64 * scale).round() as usize), s),
        Span::First(n) => (Some((n as f64 * scale).round() as usize), 1),
    };
    Plan {
        name: name.to_string(),
        frames: frames.map(|n| n.clamp(4 * stride, full_frames.max(4 * stride))),
        stride,
    }
}

/// Frames of a scenario's whole timeline.
pub fn full_frames(name: &str, seed: u64) -> usize {
    let scene = rodtrack_sim::SceneConfig::default();
    rodtrack_sim::Scenario::by_name(name, &scene, seed).map_or(0, |s| s.frame_count())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn plans_scale() {
        assert_eq!(plan_for("exp2", 1.0, 11000).stride, 8);
        assert_eq!(plan_for("exp2", 2.0, 11000).stride, 4);
        assert_eq!(plan_for("exp2", 1.0, 11000).frames, None);
        let q = plan_for("exp2", 0.1, 11000);
        assert_eq!((q.frames, q.stride), (Some(1100), 8));
        assert_eq!(plan_for("gameplay", 0.1, 6000).frames, Some(120));
        assert_eq!(plan_for("gameplay", 10.0, 6000).frames, Some(6000));
        assert_eq!(plan_for("static", 1e-6, 1000).frames, Some(4));
    }
}
