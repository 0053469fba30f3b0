"""A session's folder and its records, written so that nothing is lost when anything is killed
(no rclpy).

``<out>/<protocol name>/<subject>/``

- ``protocol.yaml``        the protocol file as it was run (its sha256 is in session.json);
- ``session.json``         subject, protocol, software version (raspv, git commit, Python,
                           platform), the graph's nodes with their parameters, the planned order;
- ``trials.jsonl``         one line per finished trial (flushed and fsync'ed before the next
                           starts): plan (block, condition, task, repetition), parameters applied,
                           outcome and metrics (:mod:`raspv_experiments.metrics`), trajectory;
- ``events.jsonl``         session events: started, resumed, paused, repeated, skipped, interrupted;
- ``trials/<slug>-a<attempt>/``   the simulator's log of each attempt (trajectory.csv,
                           events.jsonl, summary.json) and its bag when recorded.

``--resume`` continues at the first planned trial without a ``completed`` or ``skipped``
record; an attempt cut by a kill has a log folder but no record, and is run again.
"""
from __future__ import annotations

import datetime as _dt
import json
import os
import platform
import subprocess
import sys
from dataclasses import asdict
from pathlib import Path
from typing import Any

from raspv_experiments.design import PlannedTrial
from raspv_experiments.protocol import Protocol

DONE_STATUSES = ("completed", "skipped")


class SessionError(Exception):
    """A session that cannot start or resume; the message says why and what to do."""


def now_iso() -> str:
    return _dt.datetime.now().astimezone().isoformat(timespec="seconds")


def append_jsonl(path: Path, record: dict[str, Any]) -> None:
    """One JSON line, flushed to disk (fsync) before returning."""
    line = json.dumps(record, default=_jsonable, allow_nan=True) + "\n"
    with open(path, "a+b") as f:
        if f.tell() > 0:                       # a line cut by a kill must not swallow this record
            f.seek(-1, os.SEEK_END)
            if f.read(1) != b"\n":
                line = "\n" + line
        f.write(line.encode("utf-8"))
        f.flush()
        os.fsync(f.fileno())


def _jsonable(value: Any) -> Any:
    if hasattr(value, "tolist"):
        return value.tolist()
    if isinstance(value, Path):
        return str(value)
    raise TypeError(f"cannot write {type(value).__name__} to JSON")


def read_jsonl(path: Path) -> list[dict[str, Any]]:
    """Records of a JSONL file; a last line cut by a kill is skipped."""
    if not path.exists():
        return []
    out = []
    for line in path.read_text(encoding="utf-8", errors="replace").splitlines():
        try:
            rec = json.loads(line)
        except json.JSONDecodeError:
            continue
        if isinstance(rec, dict):
            out.append(rec)
    return out


def software_version() -> dict[str, Any]:
    """raspv version, git commit (and whether the tree had changes), Python, platform."""
    from importlib import metadata

    root = Path(__file__).resolve().parents[1]
    info: dict[str, Any] = {"python": sys.version.split()[0], "platform": platform.platform()}
    try:
        info["raspv"] = metadata.version("raspv")
    except metadata.PackageNotFoundError:
        info["raspv"] = "unknown"
    try:
        commit = subprocess.run(["git", "-C", str(root), "rev-parse", "HEAD"], capture_output=True, text=True,
                                timeout=5).stdout.strip()
        dirty = subprocess.run(["git", "-C", str(root), "status", "--porcelain", "--untracked-files=no"],
                               capture_output=True, text=True, timeout=5).stdout.strip()
        if commit:
            info["git_commit"], info["git_dirty"] = commit, bool(dirty)
    except (OSError, subprocess.TimeoutExpired):
        pass
    return info


class SessionFolder:
    """The files of one subject's session of one protocol."""

    def __init__(self, root: Path) -> None:
        self.root = Path(root)
        self.trials_path = self.root / "trials.jsonl"
        self.events_path = self.root / "events.jsonl"
        self.info_path = self.root / "session.json"

    @classmethod
    def for_subject(cls, out: Path, protocol: Protocol, subject: str) -> "SessionFolder":
        return cls(Path(out) / protocol.name / subject)

    def exists(self) -> bool:
        return self.info_path.exists()

    def records(self) -> list[dict[str, Any]]:
        return read_jsonl(self.trials_path)

    def done(self) -> set[int]:
        """Indices of planned trials that need not run again."""
        return {r["index"] for r in self.records() if r.get("status") in DONE_STATUSES and "index" in r}

    def create(self, protocol: Protocol, subject: str, plan: list[PlannedTrial], extra: dict[str, Any]) -> None:
        self.root.mkdir(parents=True, exist_ok=True)
        (self.root / "trials").mkdir(exist_ok=True)
        (self.root / "protocol.yaml").write_text(protocol.text)
        info = {"protocol": protocol.name, "protocol_file": str(protocol.path), "protocol_sha256": protocol.sha256,
                "subject": subject, "created": now_iso(), "software": software_version(),
                "graph": [{"name": n.name, "kind": n.kind, "params": n.params} for n in protocol.graph.nodes],
                "conditions": {c.name: c.params for c in protocol.conditions}, "factors": protocol.factors,
                "plan": [asdict(t) for t in plan], **extra}
        tmp = self.info_path.with_suffix(".tmp")
        tmp.write_text(json.dumps(info, indent=2, default=_jsonable) + "\n")
        os.replace(tmp, self.info_path)

    def check_resumable(self, protocol: Protocol, subject: str) -> dict[str, Any]:
        """session.json of an existing session of this protocol and subject, or SessionError."""
        try:
            info = json.loads(self.info_path.read_text())
        except (OSError, json.JSONDecodeError) as exc:
            raise SessionError(f"{self.info_path}: cannot read the session ({exc}); start a new one with --out") from None
        if info.get("subject") != subject:
            raise SessionError(f"{self.root} is subject {info.get('subject')!r}'s session, not {subject!r}")
        if info.get("protocol_sha256") != protocol.sha256:
            raise SessionError(f"{protocol.path} changed since this session started ({self.root}/protocol.yaml is "
                               "the version that ran); restore it or start a new session with --out")
        return info

    def event(self, kind: str, **fields: Any) -> None:
        append_jsonl(self.events_path, {"time": now_iso(), "event": kind, **fields})

    def attempt_dir(self, trial: PlannedTrial) -> tuple[str, int]:
        """(run name, attempt number) of the next attempt at ``trial`` (kills leave older ones)."""
        base = self.root / "trials"
        base.mkdir(parents=True, exist_ok=True)
        attempt = 1 + sum(1 for p in base.glob(f"{trial.slug}-a*") if p.is_dir())
        return f"{trial.slug}-a{attempt}", attempt

    def record(self, record: dict[str, Any]) -> None:
        append_jsonl(self.trials_path, record)
