//! Commands to a running session ([`SessionControl`]): re-anchoring a rod's turn count by hand
//! while it tracks, as `rodtrack track --reanchor FRAME:ROD:TURNS` does at a given frame.
//!
//! The control side appends a command to a list under a mutex and bumps a counter; each
//! filter (one per camera, one for the fused rows) checks the counter once per frame (one
//! atomic load) and, only when it moved, takes the list with `try_lock` (if the control side
//! holds it, it tries again on the next frame), turns the new commands meant for it into
//! [`TurnAnchor`]s at the frame it is filtering and hands them to the filter the way
//! [`crate::SessionOptions::turn_anchors`] are. Nothing is locked or allocated on a frame
//! without a new command.

use crate::SdkError;
use rodtrack_core::{CameraId, TurnAnchor};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// A re-anchoring asked for while the session runs.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reanchor {
    /// The camera whose filter is re-anchored; `None`: every camera and the fused rows.
    pub camera: Option<u32>,
    /// Rod id.
    pub rod: u32,
    /// The rod's whole turn from the next frame on (`angle_unwrapped_rad = 2 pi turns +
    /// angle_rad`).
    pub turns: i64,
}

#[derive(Debug, Default)]
struct Shared {
    /// Commands given so far (append only).
    commands: Mutex<Vec<Reanchor>>,
    /// `commands.len()`, published after each push.
    given: AtomicU64,
}

/// A handle to a running [`crate::Session`]'s filters, from [`crate::Session::control`]:
/// clone it, send it to another thread (a web console, a control program) and call
/// [`SessionControl::reanchor`] while the session runs.
///
/// ```
/// # use rodtrack_sdk::{Session, SessionCamera, SessionOptions};
/// # let mut sim = rodtrack_sim::build_simulation("exp3", Some(3), 1, false, "default").unwrap();
/// # let cal = rodtrack_sim::calibrate_sim_camera(&mut sim, 0, 1).unwrap().calibration;
/// # let mut sources = rodtrack_sim::SimSource::for_simulation(&sim, Default::default()).unwrap();
/// # let camera = SessionCamera {
/// #     label: "camera 0".into(),
/// #     source: Box::new(sources.remove(0)),
/// #     pipe: rodtrack_core::CameraPipeline::new(&cal, rodtrack_core::Mode::Enhanced).unwrap(),
/// # };
/// let session = Session::from_cameras(vec![camera], SessionOptions::default());
/// let control = session.control();
/// // Rod 1 is at whole turn -2 from the next frame on, in every camera and the fused rows.
/// control.reanchor(None, 1, -2).unwrap();
/// assert!(control.reanchor(None, 99, 0).is_err()); // no rod 99
/// assert!(control.reanchor(Some(7), 1, 0).is_err()); // no camera 7
/// ```
#[derive(Debug, Clone)]
pub struct SessionControl {
    shared: Arc<Shared>,
    /// (camera index, its rod ids) of the session.
    cameras: Arc<Vec<(u32, Vec<u32>)>>,
}

impl SessionControl {
    pub(crate) fn new(cameras: Vec<(u32, Vec<u32>)>) -> SessionControl {
        SessionControl {
            shared: Arc::default(),
            cameras: Arc::new(cameras),
        }
    }

    /// Sets rod `rod`'s turn count to `turns` from the next frame the filters see (of camera
    /// `camera`, or of every camera and the fused rows): the rows from then on have
    /// `angle_unwrapped_rad = 2 pi turns + angle_rad` and `turns_known` true. A rod without a
    /// track at that frame takes the count when its next track is confirmed. Errors name the
    /// camera or rod the session does not have.
    pub fn reanchor(&self, camera: Option<u32>, rod: u32, turns: i64) -> Result<(), SdkError> {
        let has_rod = |rods: &Vec<u32>| rods.contains(&rod);
        match camera {
            Some(c) => {
                let Some((_, rods)) = self.cameras.iter().find(|(i, _)| *i == c) else {
                    return Err(SdkError::Invalid(format!(
                        "camera: the session has no camera {c} (cameras: {})",
                        list(self.cameras.iter().map(|(i, _)| *i))
                    )));
                };
                if !has_rod(rods) {
                    return Err(SdkError::Invalid(format!(
                        "rod: camera {c} has no rod {rod} (rods: {})",
                        list(rods.iter().copied())
                    )));
                }
            }
            None => {
                if !self.cameras.iter().any(|(_, rods)| has_rod(rods)) {
                    let mut all: Vec<u32> =
                        self.cameras.iter().flat_map(|(_, r)| r.clone()).collect();
                    all.sort_unstable();
                    all.dedup();
                    return Err(SdkError::Invalid(format!(
                        "rod: the session has no rod {rod} (rods: {})",
                        list(all.into_iter())
                    )));
                }
            }
        }
        let mut cmds = self
            .shared
            .commands
            .lock()
            .map_err(|_| SdkError::Runtime("the session's command list is poisoned".into()))?;
        cmds.push(Reanchor { camera, rod, turns });
        self.shared
            .given
            .store(cmds.len() as u64, Ordering::Release);
        Ok(())
    }

    /// The commands' follower for one filter (`target`: a camera or the fused rows), holding
    /// the anchors given before the run (`anchors`).
    pub(crate) fn follower(&self, target: CameraId, anchors: &[TurnAnchor]) -> Follower {
        let mut all = Vec::with_capacity(anchors.len() + 16);
        all.extend_from_slice(anchors);
        Follower {
            shared: self.shared.clone(),
            target,
            seen: 0,
            anchors: all,
        }
    }
}

fn list(ids: impl Iterator<Item = u32>) -> String {
    ids.map(|i| i.to_string()).collect::<Vec<_>>().join(", ")
}

/// One filter's side of [`SessionControl`].
pub(crate) struct Follower {
    shared: Arc<Shared>,
    target: CameraId,
    /// Commands already taken.
    seen: u64,
    /// The filter's anchors: the session's, then one per command taken.
    anchors: Vec<TurnAnchor>,
}

impl Follower {
    /// When new commands were given: the filter's anchors with those meant for this filter at
    /// frame `frame` (pass them to the filter's `set_turn_anchors`). `None` (one atomic load)
    /// when nothing changed, or the list is being written (then on a later frame).
    pub(crate) fn poll(&mut self, frame: u64) -> Option<&[TurnAnchor]> {
        if self.shared.given.load(Ordering::Acquire) == self.seen {
            return None;
        }
        let cmds = self.shared.commands.try_lock().ok()?;
        let mut changed = false;
        for c in cmds.iter().skip(self.seen as usize) {
            let mine = match (c.camera, self.target) {
                (None, _) => true,
                (Some(a), CameraId::Camera(b)) => a == b,
                (Some(_), CameraId::Fused) => false,
            };
            if mine {
                self.anchors.push(TurnAnchor {
                    frame,
                    rod: c.rod,
                    turns: c.turns,
                });
                changed = true;
            }
        }
        self.seen = cmds.len() as u64;
        drop(cmds);
        changed.then_some(self.anchors.as_slice())
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn commands_reach_the_filters_they_name_once() {
        let c = SessionControl::new(vec![(0, vec![1, 2]), (1, vec![1, 2])]);
        let mut cam0 = c.follower(CameraId::Camera(0), &[]);
        let mut cam1 = c.follower(CameraId::Camera(1), &[]);
        let mut fused = c.follower(CameraId::Fused, &[]);
        assert!(cam0.poll(1).is_none());
        c.reanchor(Some(1), 2, 3).unwrap_or_else(|e| panic!("{e}"));
        assert!(cam0.poll(2).is_none());
        assert!(fused.poll(2).is_none());
        let a = cam1.poll(2).map(|a| a.to_vec());
        assert_eq!(
            a,
            Some(vec![TurnAnchor {
                frame: 2,
                rod: 2,
                turns: 3
            }])
        );
        assert!(cam1.poll(3).is_none(), "a command is taken once");
        c.reanchor(None, 1, -1).unwrap_or_else(|e| panic!("{e}"));
        for f in [&mut cam0, &mut cam1, &mut fused] {
            let a = f.poll(4).map(|a| a.to_vec()).unwrap_or_default();
            assert_eq!(
                a.last().map(|a| (a.frame, a.rod, a.turns)),
                Some((4, 1, -1))
            );
        }
    }

    #[test]
    fn unknown_cameras_and_rods_are_refused_by_name() {
        let c = SessionControl::new(vec![(0, vec![1, 2])]);
        let e = c.reanchor(Some(3), 1, 0).map_err(|e| e.to_string());
        assert!(
            e.as_ref().is_err_and(|e| e.contains("no camera 3")),
            "{e:?}"
        );
        let e = c.reanchor(None, 9, 0).map_err(|e| e.to_string());
        assert!(e.as_ref().is_err_and(|e| e.contains("no rod 9")), "{e:?}");
        assert!(c.reanchor(Some(0), 2, 5).is_ok());
    }
}
