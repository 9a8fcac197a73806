"""rodtrack: visual encoders for table-football rods.

The tracker itself, as a native module (Rust, through PyO3): measure the slide (mm) and the
turn (rad) of every rod a camera sees, frame by frame, from numpy arrays; run whole sessions
(recordings, the simulator, cameras) in a background thread and iterate their fused rows;
calibrate from calibration inputs; render the simulator's frames and truth.

    import rodtrack
    calib = rodtrack.Calibration.load("calib.toml")
    tracker = rodtrack.Tracker(calib, camera=0, mode="enhanced")
    rows = tracker.process(frame, frame_id=17)      # frame: numpy (H, W) uint8 / uint16
    rows.position_mm, rows.angle_rad, rows.status    # numpy arrays, one entry per rod

    with rodtrack.open(calib, inputs=["rec/cam0", "rec/cam1"], events=True) as session:
        for frame_set in session:
            print(frame_set.fused.position_mm, frame_set.ball_fused.x_mm, frame_set.events)

See ``docs/python.md`` in the repository for the whole API.
"""

from ._rodtrack import (
    BALL_COLUMNS,
    BALL_STATUS_NAMES,
    COLUMNS,
    CSV_DECIMALS,
    FUSED,
    MODES,
    STATUS_NAMES,
    BallRows,
    Calibration,
    CalibrationError,
    FrameSet,
    RodtrackError,
    Rows,
    Session,
    SessionClosed,
    Simulation,
    Tracker,
    __version__,
    calibrate,
    open,
    read_frame,
    simulate,
)

__all__ = [
    "BALL_COLUMNS",
    "BALL_STATUS_NAMES",
    "COLUMNS",
    "CSV_DECIMALS",
    "FUSED",
    "MODES",
    "STATUS_NAMES",
    "BallRows",
    "Calibration",
    "CalibrationError",
    "FrameSet",
    "RodtrackError",
    "Rows",
    "Session",
    "SessionClosed",
    "Simulation",
    "Tracker",
    "__version__",
    "calibrate",
    "open",
    "read_frame",
    "simulate",
]
