"""A gymnasium-style environment whose observation is the table's state from rodtrack: an
array of 8 rods x [slide (mm), cos(angle), sin(angle)], from the simulator's frames tracked by
rodtrack (no gymnasium dependency: a plain class with the same `reset` / `step` shape; wrap
it in `gymnasium.Env` if you use gymnasium). The ball joins the observation once the
simulator reports it.

Run: python gym_observation.py
"""
from typing import Any, Dict, Optional, Tuple

import numpy as np

import rodtrack

RODS = 8


class RodtrackObservationEnv:
    """Replays a simulated scenario through rodtrack's tracker; each step is one frame set.

    observation: float32 array (8, 3): per rod [position_mm, cos(angle_rad), sin(angle_rad)];
    a rod no camera measured keeps its last value. info: the status names and the truth.
    The action is ignored (the simulator's motion is scripted): plug your own table in.
    """

    def __init__(self, scenario: str = "exp3", frames: int = 60, seed: int = 1):
        self.scenario, self.frames, self.seed = scenario, frames, seed
        self.sim: Optional[rodtrack.Simulation] = None
        self.obs = np.zeros((RODS, 3), np.float32)

    def reset(self, seed: Optional[int] = None) -> Tuple[np.ndarray, Dict[str, Any]]:
        self.seed = self.seed if seed is None else seed
        self.sim = rodtrack.simulate(self.scenario, frames=self.frames, seed=self.seed)
        self.session = rodtrack.open(self.sim.calibration, inputs=[
            f"sim://{self.scenario}?camera={c}&frames={self.frames}&seed={self.seed}"
            for c in range(self.sim.calibration.cameras)])
        self.frame_sets = iter(self.session)
        self.obs[:] = (0.0, 1.0, 0.0)
        return self.step(None)[0], {}

    def step(self, action: Any) -> Tuple[np.ndarray, float, bool, bool, Dict[str, Any]]:
        frame_set = next(self.frame_sets, None)
        if frame_set is None:
            self.session.close()
            return self.obs.copy(), 0.0, True, False, {}
        rows = frame_set.fused
        ok = rows.status != rodtrack.STATUS_NAMES.index("lost")
        rods = rows.rod[ok]
        self.obs[rods, 0] = rows.position_mm[ok]
        self.obs[rods, 1] = np.cos(rows.angle_rad[ok])
        self.obs[rods, 2] = np.sin(rows.angle_rad[ok])
        info = {"frame": frame_set.frame, "status": rows.status_names()}
        return self.obs.copy(), 0.0, False, False, info


if __name__ == "__main__":
    env = RodtrackObservationEnv()
    obs, _ = env.reset()
    steps = 0
    while True:
        obs, reward, terminated, truncated, info = env.step(action=None)
        if terminated or truncated:
            break
        steps += 1
    print(f"{steps} steps; last observation (rod: slide mm, cos, sin):")
    for rod, (slide, c, s) in enumerate(obs):
        print(f"  rod {rod}: {slide:+8.2f} {c:+.3f} {s:+.3f}")
