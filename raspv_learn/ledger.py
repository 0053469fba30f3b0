"""The scoring ledger (``raspv_learn/ledger.jsonl``, kept in git): one line per scoring of a test
world with a model — evaluation and its sha256, world, configuration, seed, depth condition, the
model's sha256 and training time, when it was scored.

The rule (:func:`earlier_scorings`): a test world is not scored against a model trained after
that world was scored with another model of the same configuration — the second model could
have been shaped by the first one's score. ``raspv learn compare --rescore`` overrides it, the
entry then says ``rescore: true`` and the table marks the row.
"""
from __future__ import annotations

import json
from datetime import datetime, timezone
from pathlib import Path

LEDGER = Path(__file__).resolve().parent / "ledger.jsonl"


class LedgerError(ValueError):
    """A ledger that cannot be read (one line)."""


def read_ledger(path: str | Path = LEDGER) -> list[dict]:
    path = Path(path)
    if not path.exists():
        return []
    out = []
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip():
            continue
        try:
            entry = json.loads(line)
        except json.JSONDecodeError as exc:
            raise LedgerError(f"{path}:{n}: not JSON ({exc.msg})") from None
        if not isinstance(entry, dict) or not {"world", "configuration", "model", "scored_at"} <= set(entry):
            raise LedgerError(f"{path}:{n}: a ledger line needs world, configuration, model and scored_at")
        out.append(entry)
    return out


def _time(text: str) -> datetime:
    t = datetime.fromisoformat(text)
    return t if t.tzinfo else t.replace(tzinfo=timezone.utc)


def earlier_scorings(entries: list[dict], world: str, configuration: str, model: str, trained_at: str) -> list[dict]:
    """Scorings of ``world`` with another model of ``configuration`` made before ``model`` was
    trained (``trained_at``, ISO 8601): non-empty means scoring it now is a rescore."""
    trained = _time(trained_at)
    return [e for e in entries if e["world"] == world and e["configuration"] == configuration
            and e["model"] != model and _time(e["scored_at"]) < trained]


def append(entry: dict, path: str | Path = LEDGER) -> dict:
    """Add a scoring (``scored_at`` is now, UTC, unless given); returns the entry written."""
    entry = {**entry, "scored_at": entry.get("scored_at") or datetime.now(timezone.utc).isoformat(timespec="microseconds")}
    with open(path, "a") as f:
        f.write(json.dumps(entry, sort_keys=True) + "\n")
    return entry
