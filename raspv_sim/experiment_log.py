"""Per-run experiment logs, written line by line so nothing is lost if the run is killed (no rclpy).

A run directory ``<log_dir>/<world>-<YYYYmmdd-HHMMSS>/`` (or ``<log_dir>/<run_name>/``) holds

- ``meta.json``       world (name and file), start time, ``sim_time_at_start`` [s] (the
  simulator's clock when the log started), configuration, goals — written at start;
- ``trajectory.csv``  base and head at a fixed rate: ``t`` [s since the log started, sim time],
  base ``x, y, z`` [m, W],
  ``yaw`` [rad], head ``roll, pitch, yaw`` relative to the base [rad], camera position in W [m],
  commanded ``linear`` [m/s] and ``angular`` [rad/s], cumulative ``path_length`` [m];
- ``events.jsonl``    one JSON object per line: ``collision`` (object name and class, contact
  point, normal, speed, count) and ``goal`` (name) events with their time ``t`` (since the start);
- ``gaze.csv``        every eye-gaze sample received (``/gaze/direction``), when there are any: ``t``
  [s since the log started, sim time of receipt], ``stamp`` [s, the sample's own time: its
  intervals are the eye tracker's], unit direction ``x, y, z`` in the head frame (x forward, y
  left, z up; empty when invalid), ``valid`` (0/1);
- ``summary.json`` and ``trajectory.png`` — written when the run ends, and rebuilt from the
  files above by :func:`summarize_run` / ``raspv sim plot RUN_DIR`` after a killed run.

Every line is flushed to the operating system as soon as it is written.
"""
from __future__ import annotations

import csv
import datetime as _dt
import json
import math
import threading
from dataclasses import asdict, dataclass
from pathlib import Path
from typing import Any, TextIO

from raspv_sim.collision_events import CollisionEvent

GAZE_FIELDS = ("t", "stamp", "x", "y", "z", "valid")
TRAJECTORY_FIELDS = ("t", "x", "y", "z", "yaw", "head_roll", "head_pitch", "head_yaw", "camera_x", "camera_y",
                     "camera_z", "linear", "angular", "path_length")


@dataclass(frozen=True)
class TrajectorySample:
    t: float
    x: float
    y: float
    z: float
    yaw: float
    head_roll: float
    head_pitch: float
    head_yaw: float
    camera_x: float
    camera_y: float
    camera_z: float
    linear: float
    angular: float
    path_length: float


class ExperimentLog:
    """Writes one run. ``rate`` [Hz] is the trajectory sampling rate (sim time)."""

    def __init__(self, log_dir: str | Path, world_name: str, meta: dict[str, Any], rate: float = 10.0,
                 run_name: str | None = None, t0: float = 0.0):
        if not rate > 0:
            raise ValueError(f"trajectory rate must be positive, got {rate}")
        self.rate = float(rate)
        stamp = _dt.datetime.now().strftime("%Y%m%d-%H%M%S")
        base = Path(log_dir).expanduser()
        base.mkdir(parents=True, exist_ok=True)
        name = run_name or f"{world_name}-{stamp}"        # run_name: the caller's folder name
        run = base / name
        k = 1
        while (run / "trajectory.csv").exists() or (run.exists() and not run.is_dir()):   # another run's: a new one
            k += 1
            run = base / f"{name}-{k}"
        run.mkdir(exist_ok=True)                          # (a folder a recorder started in first is this run's)
        self.dir = run
        self.t0 = float(t0)                              # sim time [s] of the start: times are relative to it
        info = {"world": world_name, "started": _dt.datetime.now().astimezone().isoformat(timespec="seconds"),
                "sim_time_at_start": self.t0, "trajectory_rate_hz": self.rate, **meta}
        (run / "meta.json").write_text(json.dumps(info, indent=2, default=str) + "\n")
        self._traj: TextIO = open(run / "trajectory.csv", "w", newline="", buffering=1)
        self._csv = csv.writer(self._traj)
        self._csv.writerow(TRAJECTORY_FIELDS)
        self._traj.flush()
        self._events: TextIO = open(run / "events.jsonl", "w", buffering=1)
        self._next_t = 0.0
        self._last_t = -math.inf
        self._gaze: TextIO | None = None          # gaze.csv, opened with the first sample
        self._gaze_lock = threading.Lock()        # samples are written from another thread than close()
        self.closed = False

    def sample(self, s: TrajectorySample, force: bool = False) -> bool:
        """Write ``s`` if its time reached the next sampling instant (or ``force``); True if written."""
        if self.closed or (not force and s.t + 1e-9 < self._next_t) or s.t <= self._last_t:
            return False
        self._last_t = s.t
        row = asdict(s)
        row["t"] = s.t - self.t0
        self._csv.writerow([f"{v:.4f}" if isinstance(v, float) else v for v in row.values()])
        self._traj.flush()
        self._next_t = (math.floor(s.t * self.rate + 1e-6) + 1) / self.rate
        return True

    def _event(self, record: dict[str, Any]) -> None:
        if self.closed:
            return
        self._events.write(json.dumps(record) + "\n")
        self._events.flush()

    def collision(self, e: CollisionEvent) -> None:
        self._event({"t": round(e.t - self.t0, 4), "event": "collision", "name": e.name, "class": e.cls,
                     "position": [round(v, 4) for v in e.position], "normal": [round(v, 4) for v in e.normal],
                     "speed": round(e.speed, 4), "count": e.count})

    def gaze(self, t: float, stamp: float, direction: tuple[float, float, float] | None) -> None:
        """One eye-gaze sample received at sim time ``t``, stamped ``stamp`` [s]; ``direction`` a unit
        vector in the head frame, None when invalid."""
        xyz = ",".join(f"{v:.6f}" for v in direction) if direction is not None else ",,"
        with self._gaze_lock:
            if self.closed:
                return
            if self._gaze is None:
                self._gaze = open(self.dir / "gaze.csv", "w", buffering=1)
                self._gaze.write(",".join(GAZE_FIELDS) + "\n")
            self._gaze.write(f"{t - self.t0:.4f},{stamp:.6f},{xyz},{int(direction is not None)}\n")
            self._gaze.flush()

    def goal(self, name: str, t: float) -> None:
        self._event({"t": round(t - self.t0, 4), "event": "goal", "name": name})

    def close(self) -> dict[str, Any]:
        """Close the files and write ``summary.json``; returns the summary."""
        if self.closed:
            return summarize_run(self.dir)
        with self._gaze_lock:
            self.closed = True
            if self._gaze is not None:
                self._gaze.close()
        self._traj.close()
        self._events.close()
        return summarize_run(self.dir)


def read_trajectory(run_dir: str | Path) -> dict[str, list[float]]:
    """Columns of ``trajectory.csv`` as float lists (a last line cut by a kill is skipped)."""
    cols: dict[str, list[float]] = {k: [] for k in TRAJECTORY_FIELDS}
    with open(Path(run_dir) / "trajectory.csv", newline="") as f:
        reader = csv.reader(f)
        header = next(reader, None)
        if header is None or tuple(header) != TRAJECTORY_FIELDS:
            raise ValueError(f"{run_dir}/trajectory.csv: unexpected header {header}")
        for row in reader:
            if len(row) != len(TRAJECTORY_FIELDS):
                continue
            try:
                values = [float(v) for v in row]
            except ValueError:
                continue
            for k, v in zip(TRAJECTORY_FIELDS, values):
                cols[k].append(v)
    return cols


def read_gaze(run_dir: str | Path) -> dict[str, list[float]]:
    """``gaze.csv`` as columns (``t`` since the log started, ``stamp``, ``x``, ``y``, ``z`` NaN when
    invalid, ``valid`` 0/1); empty columns when the run logged no gaze. A last line cut by a kill is skipped."""
    path = Path(run_dir) / "gaze.csv"
    out: dict[str, list[float]] = {k: [] for k in GAZE_FIELDS}
    if not path.is_file():
        return out
    with open(path, newline="") as f:
        rows = csv.reader(f)
        next(rows, None)
        for row in rows:
            if len(row) != len(GAZE_FIELDS):
                continue
            try:
                values = [float(v) if v != "" else math.nan for v in row]
            except ValueError:
                continue
            for k, v in zip(GAZE_FIELDS, values):
                out[k].append(v)
    return out


def read_events(run_dir: str | Path) -> list[dict[str, Any]]:
    """Events of ``events.jsonl`` (a last line cut by a kill is skipped)."""
    out = []
    for line in (Path(run_dir) / "events.jsonl").read_text().splitlines():
        try:
            out.append(json.loads(line))
        except json.JSONDecodeError:
            continue
    return out


def sim_time_at_start(run_dir: str | Path) -> float:
    """The simulator's clock [s] when the log started (0 for logs from before it was recorded, whose
    times were the simulator's clock)."""
    try:
        return float(json.loads((Path(run_dir) / "meta.json").read_text()).get("sim_time_at_start", 0.0))
    except (OSError, ValueError):
        return 0.0


def summarize_run(run_dir: str | Path) -> dict[str, Any]:
    """Summary of a run from its files (also after a kill); written to ``summary.json``."""
    run_dir = Path(run_dir)
    meta = json.loads((run_dir / "meta.json").read_text())
    traj = read_trajectory(run_dir)
    events = read_events(run_dir)
    collisions = [e for e in events if e.get("event") == "collision"]
    goals = {e["name"]: e["t"] for e in events if e.get("event") == "goal"}
    by_class: dict[str, int] = {}
    for e in collisions:
        by_class[e["class"]] = by_class.get(e["class"], 0) + 1
    summary = {
        "world": meta.get("world"),
        "duration_s": round(traj["t"][-1] - traj["t"][0], 4) if traj["t"] else 0.0,
        "path_length_m": traj["path_length"][-1] if traj["path_length"] else 0.0,
        "samples": len(traj["t"]),
        "collisions": len(collisions),
        "collisions_by_class": by_class,
        "goals_reached": goals,
        "goals_missed": [g["name"] for g in meta.get("goals", []) if g["name"] not in goals],
    }
    (run_dir / "summary.json").write_text(json.dumps(summary, indent=2) + "\n")
    return summary
