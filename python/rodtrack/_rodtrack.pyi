"""Type stubs of rodtrack's native module (``rodtrack._rodtrack``)."""

import os
from types import TracebackType
from typing import Dict, Iterator, List, Optional, Sequence, Tuple, Type, Union

import numpy as np
import numpy.typing as npt

_Path = Union[str, "os.PathLike[str]"]

__version__: str
COLUMNS: Tuple[str, ...]
"""The row columns, in the order of the record and of the CSV files."""
STATUS_NAMES: Tuple[str, ...]
"""Status names by code: ``rows.status[i]`` indexes this tuple (0 = ``ok``)."""
FUSED: int
"""The camera code of fused rows (-1)."""
BALL_COLUMNS: Tuple[str, ...]
"""The ball's row columns, as ``rodtrack track --ball-out`` writes them (plus ``timestamp_ns``)."""
BALL_STATUS_NAMES: Tuple[str, ...]
"""Ball status names by code: ``ball.status[i]`` indexes this tuple (0 = ``ok``)."""
MODES: Tuple[str, ...]
"""The algorithms: ``enhanced``, ``paper``."""
CSV_DECIMALS: Dict[str, int]
"""Decimals of each number column in CSV files (``rodtrack track --out rows.csv``)."""

class RodtrackError(Exception):
    """An error of rodtrack; the message names the file, field, camera or rod."""

class CalibrationError(RodtrackError):
    """A calibration file or calibration inputs cannot be read, are malformed or invalid."""

class SessionClosed(RodtrackError):
    """The session was closed and cannot be used any more."""

class Rows:
    """Rows as numpy arrays, one entry per row (per rod for one camera's frame).

    Each attribute access returns a new array.
    """

    @property
    def frame(self) -> npt.NDArray[np.uint64]:
        """The camera's frame id."""
    @property
    def timestamp_s(self) -> npt.NDArray[np.float64]:
        """Capture time, seconds (``timestamp_ns * 1e-9``, as the CSV prints it)."""
    @property
    def timestamp_ns(self) -> npt.NDArray[np.uint64]:
        """Capture time, nanoseconds from the source's epoch: the exact value the record carries."""
    @property
    def camera(self) -> npt.NDArray[np.int64]:
        """The camera's index, or -1 (``FUSED``) for fused rows."""
    @property
    def rod(self) -> npt.NDArray[np.uint32]:
        """Rod id."""
    @property
    def position_mm(self) -> npt.NDArray[np.float64]:
        """Translation along the rod's axis from its calibrated zero, mm."""
    @property
    def angle_rad(self) -> npt.NDArray[np.float64]:
        """Rotation about the rod's axis, right-handed, in [0, 2 pi)."""
    @property
    def angle_unwrapped_rad(self) -> npt.NDArray[np.float64]:
        """Rotation counting whole turns, rad."""
    @property
    def velocity_mm_s(self) -> npt.NDArray[np.float64]:
        """Translation velocity, mm/s (0 when not estimated: raw rows)."""
    @property
    def angular_velocity_rad_s(self) -> npt.NDArray[np.float64]:
        """Angular velocity, rad/s (0 when not estimated: raw rows)."""
    @property
    def quality(self) -> npt.NDArray[np.float64]:
        """Confidence in [0, 1]."""
    @property
    def status(self) -> npt.NDArray[np.uint8]:
        """Whether to trust the values: an index into ``STATUS_NAMES`` (0 = ok)."""
    @property
    def turns_known(self) -> npt.NDArray[np.bool_]:
        """Whether ``angle_unwrapped_rad`` counts the whole turns for sure (false after a stretch in which the count could have slipped, until it is re-anchored)."""
    def to_dict(self) -> Dict[str, np.ndarray]:
        """Every column by name, as numpy arrays."""
    def status_names(self) -> List[str]:
        """The status of each row by name."""
    def __len__(self) -> int:
        """Number of rows."""

class BallRows:
    """The ball's rows as numpy arrays, one entry per row (the table frame, mm).

    Each attribute access returns a new array.
    """

    @property
    def frame(self) -> npt.NDArray[np.uint64]:
        """The frame id."""
    @property
    def timestamp_s(self) -> npt.NDArray[np.float64]:
        """Capture time, seconds."""
    @property
    def timestamp_ns(self) -> npt.NDArray[np.uint64]:
        """Capture time, nanoseconds from the source's epoch."""
    @property
    def camera(self) -> npt.NDArray[np.int64]:
        """The camera's index, or -1 (``FUSED``) for fused rows."""
    @property
    def x_mm(self) -> npt.NDArray[np.float64]:
        """The ball's centre in the table frame, mm (x towards goal B)."""
    @property
    def y_mm(self) -> npt.NDArray[np.float64]:
        """The ball's centre in the table frame, mm (y across the table)."""
    @property
    def vx_mm_s(self) -> npt.NDArray[np.float64]:
        """Velocity, mm/s."""
    @property
    def vy_mm_s(self) -> npt.NDArray[np.float64]:
        """Velocity, mm/s."""
    @property
    def quality(self) -> npt.NDArray[np.float64]:
        """Fraction of the ball's outline measured, in [0, 1]."""
    @property
    def status(self) -> npt.NDArray[np.uint8]:
        """An index into ``BALL_STATUS_NAMES`` (0 = ok)."""
    def to_dict(self) -> Dict[str, np.ndarray]:
        """Every column by name, as numpy arrays."""
    def status_names(self) -> List[str]:
        """The status of each row by name."""
    def __len__(self) -> int:
        """Number of rows."""

class Calibration:
    """A validated calibration: every camera's rods, image size and pixel format."""

    @staticmethod
    def load(path: _Path) -> "Calibration":
        """Reads, parses and validates a calibration file (TOML); raises ``CalibrationError``."""
    def save(self, path: _Path) -> None:
        """Writes the calibration file (TOML), atomically."""
    @property
    def cameras(self) -> int:
        """Number of cameras."""
    def camera_name(self, camera: int = 0) -> str:
        """The camera's name (``cam0``)."""
    def rods(self, camera: int = 0) -> List[int]:
        """The rod ids the camera sees, in the order of its rows."""
    def pixel_format(self, camera: int = 0) -> str:
        """The camera's pixel format (``bayer_rggb8``, ``mono16``, ...)."""
    def image_size(self, camera: int = 0) -> Tuple[int, int]:
        """The camera's image size, ``(width, height)`` in pixels."""
    def fps(self, camera: int = 0) -> float:
        """The camera's frame rate, frames per second."""

class Tracker:
    """One camera's tracker: give it that camera's frames, one at a time, in order."""

    def __init__(
        self,
        calibration: Calibration,
        camera: int = 0,
        mode: str = "enhanced",
        filter: bool = True,
    ) -> None:
        """The camera's rods as calibrated, the algorithm ``mode``, and with ``filter`` the
        camera's temporal filter (else the raw measurements)."""
    def process(
        self,
        frame: np.ndarray,
        frame_id: int,
        timestamp_ns: Optional[int] = None,
    ) -> Rows:
        """Measures every rod in ``frame`` ((H, W) uint8/uint16, or (H, W, 3) uint8 for
        rgb8, borrowed without a copy); one row per rod. ``timestamp_ns`` defaults to
        ``frame_id / fps``. The GIL is released while tracking."""
    @property
    def rods(self) -> List[int]:
        """The rod ids, in the order of the rows."""
    @property
    def pixel_format(self) -> str:
        """The pixel format the frames must be in."""
    @property
    def shape(self) -> List[int]:
        """The frame shape wanted."""
    @property
    def last_process_ns(self) -> int:
        """Time the last ``process`` call spent in Rust tracking, nanoseconds."""

class FrameSet:
    """The rows of one frame set: every camera's rows for one frame id, then the fused rows."""

    @property
    def frame(self) -> int:
        """The frame id."""
    @property
    def rows(self) -> Rows:
        """Every row, in CSV order: camera 0's, camera 1's, ..., then the fused rows."""
    @property
    def fused(self) -> Rows:
        """The fused rows, one per rod (with one camera or no filter: camera 0's rows)."""
    def camera(self, index: int) -> Rows:
        """Camera ``index``'s rows."""
    @property
    def ball(self) -> BallRows:
        """The ball's rows the set carries: this frame's (each camera's, then the fused one), after older frames' that came late."""
    @property
    def ball_fused(self) -> BallRows:
        """This frame's fused ball row (with one camera, the camera's); empty without one."""
    @property
    def events(self) -> List[Dict[str, object]]:
        """The ball's events decided since the previous set, each as a line of ``--events-out``."""
    def __len__(self) -> int:
        """Number of rows."""

class Session:
    """A running session: iterate it for frame sets; ``with`` it or ``close()`` it."""

    def __enter__(self) -> "Session": ...
    def __exit__(
        self,
        exc_type: Optional[Type[BaseException]],
        exc: Optional[BaseException],
        tb: Optional[TracebackType],
    ) -> bool: ...
    def __iter__(self) -> Iterator[FrameSet]: ...
    def __next__(self) -> FrameSet: ...
    def close(self) -> None:
        """Stops the session and waits for its threads; raises the session's error."""
    @property
    def is_open(self) -> bool:
        """True until closed."""
    @property
    def is_live(self) -> bool:
        """True when a source is live."""
    @property
    def dropped_sets(self) -> int:
        """Frame sets dropped because the Python loop was behind (live sources only)."""
    @property
    def final_events(self) -> List[Dict[str, object]]:
        """The events decided after the last frame set, once the session has ended or been closed."""
    @property
    def dropped_ball_rows(self) -> int:
        """Ball rows dropped because no frame set took them in time."""
    @property
    def summary(self) -> Optional[str]:
        """The session's report once it has ended or been closed."""
    @property
    def cameras(self) -> int:
        """Number of cameras."""

class Simulation:
    """A simulated recording: frames, ground truth and calibration."""

    @property
    def frames(self) -> npt.NDArray[np.uint8]:
        """Shape ``(cameras, frames, height, width)``, raw Bayer RGGB."""
    @property
    def truth(self) -> Rows:
        """Ground truth, one row per (frame, camera, rod)."""
    @property
    def visible(self) -> npt.NDArray[np.bool_]:
        """Per truth row: the whole marker is in the frame and unhidden."""
    @property
    def frame_ids(self) -> npt.NDArray[np.uint64]:
        """The frame ids."""
    @property
    def timestamps_ns(self) -> npt.NDArray[np.uint64]:
        """The trigger times, nanoseconds."""
    @property
    def calibration(self) -> Calibration:
        """Every camera calibrated as an operator would."""
    @property
    def ball_truth(self) -> Optional[Dict[str, np.ndarray]]:
        """The ball's truth per frame (``frame``, ``timestamp_s``, ``x_mm``, ``y_mm``, ``vx_mm_s``, ``vy_mm_s``, ``visible`` per camera), or ``None`` without a ball."""
    @property
    def events_truth(self) -> List[Dict[str, object]]:
        """The scenario's scripted events within the simulation's frames, each as a line of ``--events-out``."""

def calibrate(inputs: Sequence[_Path]) -> Calibration:
    """Calibrates camera ``i`` from calibration-inputs JSON file ``inputs[i]``."""

def open(
    calibration: Calibration,
    inputs: Sequence[str],
    mode: str = "enhanced",
    filter: bool = True,
    max_frames: Optional[int] = None,
    queue: int = 64,
    ball: bool = False,
    events: bool = False,
    goal_width_mm: Optional[float] = None,
) -> Session:
    """Opens one input per camera and starts tracking them (and the ball, its events) in a background thread."""

def simulate(
    scenario: str = "exp3",
    frames: Optional[int] = None,
    seed: int = 1,
    setup: str = "default",
) -> Simulation:
    """Renders the simulator's frames, truth and calibration."""

def read_frame(path: _Path, pixel_format: Optional[str] = None) -> np.ndarray:
    """Reads an image file as a camera frame (a numpy array)."""
