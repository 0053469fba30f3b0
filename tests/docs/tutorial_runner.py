"""Runs the command and Python blocks of a docs page in order, in a fresh working folder, as a
user following it would (the environment's ``bin/`` first on the PATH, as after ``source
.venv/bin/activate``).

A ``bash`` block runs in one ``bash -e`` with job control on (``set -m``, as in a terminal:
``cmd &`` then ``kill -INT %1`` stops it as Ctrl-C would); a ``python`` block runs in a new
interpreter. Blocks read no keyboard (standard input is /dev/null). A block that fails or outlives its timeout fails the page with its output; every
process a block started is killed when it ends.
"""
from __future__ import annotations

import os
import re
import subprocess
import sys
import time
from dataclasses import dataclass
from pathlib import Path

import psutil

BLOCK = re.compile(r"^```(bash|python)\n(.*?)^```", re.S | re.M)


@dataclass
class BlockRun:
    lang: str
    code: str
    seconds: float
    output: str


def blocks(page: Path) -> list[tuple[str, str]]:
    """The page's ``bash`` and ``python`` blocks, in order."""
    return BLOCK.findall(page.read_text(encoding="utf-8"))


def _kill_tree(pid: int) -> None:
    try:
        proc = psutil.Process(pid)
        family = proc.children(recursive=True) + [proc]
    except psutil.NoSuchProcess:
        return
    for p in family:
        try:
            p.kill()
        except psutil.NoSuchProcess:
            pass
    psutil.wait_procs(family, timeout=10)


def run_block(lang: str, code: str, cwd: Path, env: dict[str, str], timeout: float) -> BlockRun:
    cmd = ["bash", "-e", "-o", "pipefail", "-c", "set -m\n" + code] if lang == "bash" else [sys.executable, "-c", code]
    t0 = time.perf_counter()
    proc = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=subprocess.DEVNULL, stdout=subprocess.PIPE,
                            stderr=subprocess.STDOUT, text=True,
                            start_new_session=True)
    descendants: set[int] = set()
    try:
        out, _ = proc.communicate(timeout=timeout)
    except subprocess.TimeoutExpired:
        _kill_tree(proc.pid)
        out, _ = proc.communicate()
        raise AssertionError(f"{lang} block did not finish in {timeout:.0f} s:\n{code}\n--- output ---\n{out[-4000:]}")
    finally:
        for p in psutil.process_iter(["pid", "environ"]):   # background jobs left by the block
            try:
                if (p.info["environ"] or {}).get("RASPV_TUTORIAL_RUN") == env["RASPV_TUTORIAL_RUN"]:
                    descendants.add(p.pid)
            except (psutil.NoSuchProcess, psutil.AccessDenied):
                continue
        for pid in descendants:
            _kill_tree(pid)
    seconds = time.perf_counter() - t0
    if proc.returncode != 0:
        raise AssertionError(f"{lang} block failed (exit {proc.returncode}):\n{code}\n--- output ---\n{out[-4000:]}")
    return BlockRun(lang, code, seconds, out)


def user_env(tag: str) -> dict[str, str]:
    """This environment as a user's shell after ``source .venv/bin/activate``; ``tag`` marks
    the processes its blocks start (killed when a block ends)."""
    env = dict(os.environ)
    env["PATH"] = f"{Path(sys.executable).parent}{os.pathsep}{env.get('PATH', '')}"
    env["RASPV_TUTORIAL_RUN"] = f"{os.getpid()}-{tag}-{time.monotonic_ns()}"
    env.pop("PYTHONPATH", None)
    return env


def run_page(page: Path, cwd: Path, timeout_per_block: float = 600.0) -> list[BlockRun]:
    """Every block of ``page`` in order in ``cwd``; the runs (AssertionError on the first failure)."""
    env = user_env(page.stem)
    runs = []
    for lang, code in blocks(page):
        runs.append(run_block(lang, code, cwd, env, timeout_per_block))
    return runs
