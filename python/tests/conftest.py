"""Shared fixtures: the rodtrack CLI and a simulated recording calibrated by it."""

import os
import subprocess
from pathlib import Path

import pytest

import rodtrack

REPO = Path(__file__).resolve().parents[2]


def _cli() -> Path:
    """The rodtrack binary: $RODTRACK_BIN, else the release build of this repository (built
    here when missing)."""
    env = os.environ.get("RODTRACK_BIN")
    if env:
        return Path(env)
    target = Path(os.environ.get("CARGO_TARGET_DIR", REPO / "target"))
    exe = target / "release" / "rodtrack"
    if not exe.exists():
        subprocess.run(
            ["cargo", "build", "--release", "-p", "rodtrack", "--bin", "rodtrack"],
            cwd=REPO,
            check=True,
        )
    return exe


@pytest.fixture(scope="session")
def cli():
    exe = _cli()

    def run(*args: str) -> None:
        subprocess.run([str(exe), *args], check=True, stdout=subprocess.DEVNULL)

    return run


@pytest.fixture(scope="session")
def sim():
    """Three frames of the simulator's gameplay scenario (seed 1), its truth and its
    calibration (valid for `sim://gameplay?...&seed=1` inputs too). Calibrating takes a while:
    made once for every test."""
    return rodtrack.simulate("gameplay", frames=3, seed=1)


@pytest.fixture(scope="session")
def recording(tmp_path_factory, cli):
    """A 40-frame exp3 recording of both simulated cameras (PNG frames, calibration inputs)
    made by `rodtrack simulate`, and the calibration `rodtrack calibrate` makes of it."""
    d = tmp_path_factory.mktemp("rec")
    rec = d / "rec"
    cli("simulate", "--scenario", "exp3", "--frames", "40", "--seed", "3", "--out", str(rec))
    calib = d / "calib.toml"
    cli(
        "calibrate",
        "--inputs", str(rec / "cam0.json"),
        "--inputs", str(rec / "cam1.json"),
        "--out", str(calib),
    )
    return {"dir": d, "rec": rec, "calib": calib, "cal": rodtrack.Calibration.load(calib)}


def read_csv(path: Path):
    """A CSV file of rows: (header, list of field lists)."""
    lines = path.read_text().splitlines()
    header = lines[0].split(",")
    return header, [line.split(",") for line in lines[1:]]


def _fixed(v: float, d: int) -> str:
    s = f"{v:.{d}f}"
    if s.startswith("-") and set(s[1:]) <= {"0", "."}:
        s = s[1:]
    return s


def as_csv_fields(rows: "rodtrack.Rows", header):
    """Rows formatted as the CLI's CSV formats them (its decimals, camera and status names),
    in `header`'s column order."""
    cols = rows.to_dict()
    n = len(rows)
    out = [[] for _ in range(n)]
    for name in header:
        values = cols[name]
        for i in range(n):
            v = values[i]
            if name == "camera":
                s = "fused" if int(v) == rodtrack.FUSED else str(int(v))
            elif name == "status":
                s = rodtrack.STATUS_NAMES[int(v)]
            elif name in rodtrack.CSV_DECIMALS:
                s = _fixed(float(v), rodtrack.CSV_DECIMALS[name])
            elif values.dtype == bool:
                s = "true" if v else "false"
            else:
                s = str(int(v))
            out[i].append(s)
    return out
