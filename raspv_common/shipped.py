"""Where the shipped data folders are: ``config/`` (graphs, devices, layouts, middleware
profiles) and ``experiments/`` (protocols, sweeps, their worlds).

In a repository checkout (an editable install) they are the checkout's own folders; an
installed wheel carries copies under ``raspv_common/shipped/`` (setup.py puts them there), so
``raspv demo`` works from any folder without the repository.
"""
from __future__ import annotations

from pathlib import Path

CHECKOUT_ROOT = Path(__file__).resolve().parents[1]
PACKAGED = Path(__file__).resolve().parent / "shipped"
FOLDERS = ("config", "experiments")


def shipped_dir(name: str) -> Path:
    """The shipped folder ``name`` (one of :data:`FOLDERS`): the checkout's, else the wheel's copy."""
    if name not in FOLDERS:
        raise ValueError(f"{name}: not a shipped folder ({', '.join(FOLDERS)})")
    in_checkout = CHECKOUT_ROOT / name
    return in_checkout if in_checkout.is_dir() else PACKAGED / name


CONFIG_DIR = shipped_dir("config")
EXPERIMENTS_DIR = shipped_dir("experiments")
