"""Per-trial metrics from a trial's simulator log (raspv_sim/experiment_log.py), no rclpy.

From ``trajectory.csv`` (base and head at the log rate, sim time) and ``events.jsonl``
(collisions, goal):

- **success**: the goal region was reached before the time limit (and the trial not aborted);
  **completion time** [s]: from the start to reaching the goal (the trial's duration otherwise);
- **path length** [m]: walked by the base; **path efficiency**: the planner's shortest path from
  the start to the goal region (:mod:`raspv_experiments.world_geometry`) / path length, for
  successful trials (1 = the shortest path, lower = detours);
- **collisions**: count, and what was hit (``class:name``, in order) and per class;
- **minimum clearance** [m]: smallest distance between the body (a cylinder of the avatar's
  radius) and a static object along the trajectory (from the 5 cm occupancy map, ±3 cm along faces;
  people are not static and are counted by collisions only);
- **head rotation** [deg] and [deg/s]: total angle the head turned relative to the body (the
  angle between successive head orientations, summed) — sampled at the log rate, so faster
  oscillations are missed;
- the **trajectory** (t, x, y, yaw) itself.
"""
from __future__ import annotations

import math
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any

import numpy as np

from raspv_common.rotations import head_quaternion
from raspv_sim.experiment_log import read_events, read_trajectory, sim_time_at_start

OUTCOMES = ("goal", "time_limit", "aborted")


@dataclass
class TrialMetrics:
    outcome: str                    # goal, time_limit or aborted
    success: bool
    completion_time_s: float
    duration_s: float
    path_length_m: float
    shortest_path_m: float
    path_efficiency: float          # NaN unless successful
    collisions: int
    collided_with: list[str] = field(default_factory=list)
    collisions_by_class: dict[str, int] = field(default_factory=dict)
    min_clearance_m: float = float("nan")
    head_rotation_deg: float = 0.0
    head_rotation_deg_per_s: float = 0.0
    samples: int = 0

    def as_dict(self) -> dict[str, Any]:
        return asdict(self)


def head_rotation_deg(roll: np.ndarray, pitch: np.ndarray, yaw: np.ndarray) -> float:
    """Total angle [deg] between successive head orientations (roll/pitch/yaw samples, rad)."""
    if len(roll) < 2:
        return 0.0
    q = np.array([head_quaternion(r, p, y) for r, p, y in zip(roll, pitch, yaw)])
    dots = np.clip(np.abs(np.sum(q[1:] * q[:-1], axis=1)), 0.0, 1.0)
    return float(np.degrees(2.0 * np.arccos(dots)).sum())


def trajectory_arrays(run_dir: str | Path, t0: float, t1: float) -> dict[str, np.ndarray]:
    """Trajectory columns between sim times t0 and t1 [s] as arrays (``t`` in sim time)."""
    cols = {k: np.asarray(v, dtype=float) for k, v in read_trajectory(run_dir).items()}
    cols["t"] = cols["t"] + sim_time_at_start(run_dir)
    keep = (cols["t"] >= t0 - 1e-6) & (cols["t"] <= t1 + 1e-6)
    return {k: v[keep] for k, v in cols.items()}


def trial_metrics(run_dir: str | Path, start_t: float, end_t: float, aborted: bool, time_limit: float,
                  goal_name: str, shortest_path_m: float, geometry=None, body_radius: float = 0.25) -> TrialMetrics:
    """Metrics of the trial logged in ``run_dir`` that ran from sim time ``start_t`` to ``end_t``
    [s]; ``goal_name`` is the name its goal has in the log's goal events; ``geometry`` a
    :class:`~raspv_experiments.world_geometry.WorldGeometry` for the clearance (None: NaN)."""
    traj = trajectory_arrays(run_dir, start_t, end_t)
    offset = sim_time_at_start(run_dir)
    events = [{**e, "t": e["t"] + offset} for e in read_events(run_dir) if isinstance(e.get("t"), (int, float))]
    events = [e for e in events if start_t - 1e-6 <= e["t"] <= end_t + 1e-6]
    goal_t = next((e["t"] for e in events if e.get("event") == "goal" and e.get("name") == goal_name), None)
    reached = goal_t is not None and goal_t - start_t <= time_limit + 1e-6
    outcome = "goal" if reached else ("aborted" if aborted else "time_limit")
    duration = max(0.0, end_t - start_t)
    completion = (goal_t - start_t) if reached else duration
    path = traj["path_length"]
    length = float(path[-1] - path[0]) if len(path) else 0.0
    if reached and len(path):      # walked up to the goal only
        upto = traj["t"] <= goal_t + 1e-6
        length = float(path[upto][-1] - path[0])
    efficiency = (shortest_path_m / length) if reached and length > 1e-6 and math.isfinite(shortest_path_m) else float("nan")
    collisions = [e for e in events if e.get("event") == "collision"]
    by_class: dict[str, int] = {}
    for e in collisions:
        by_class[e["class"]] = by_class.get(e["class"], 0) + 1
    clearance = float("nan")
    if geometry is not None and len(traj["x"]):
        c = geometry.clearance(np.column_stack([traj["x"], traj["y"]]), body_radius)
        if np.isfinite(c).any():
            clearance = float(np.nanmin(c))
    rotation = head_rotation_deg(traj["head_roll"], traj["head_pitch"], traj["head_yaw"])
    return TrialMetrics(outcome=outcome, success=reached, completion_time_s=round(completion, 3),
                        duration_s=round(duration, 3), path_length_m=round(length, 3),
                        shortest_path_m=round(shortest_path_m, 3) if math.isfinite(shortest_path_m) else float("nan"),
                        path_efficiency=round(efficiency, 4) if math.isfinite(efficiency) else float("nan"),
                        collisions=len(collisions), collided_with=[f"{e['class']}:{e['name']}" for e in collisions],
                        collisions_by_class=by_class, min_clearance_m=round(clearance, 3) if math.isfinite(clearance) else float("nan"),
                        head_rotation_deg=round(rotation, 2),
                        head_rotation_deg_per_s=round(rotation / duration, 3) if duration > 0 else 0.0,
                        samples=int(len(traj["t"])))


def trajectory_record(run_dir: str | Path, start_t: float, end_t: float) -> dict[str, list[float]]:
    """The trajectory for the trial record: t [s from the start], x, y [m, W], yaw [rad], head yaw/pitch [rad]."""
    traj = trajectory_arrays(run_dir, start_t, end_t)
    return {"t": [round(float(v - start_t), 3) for v in traj["t"]],
            "x": [round(float(v), 3) for v in traj["x"]], "y": [round(float(v), 3) for v in traj["y"]],
            "yaw": [round(float(v), 4) for v in traj["yaw"]],
            "head_yaw": [round(float(v), 4) for v in traj["head_yaw"]],
            "head_pitch": [round(float(v), 4) for v in traj["head_pitch"]]}
