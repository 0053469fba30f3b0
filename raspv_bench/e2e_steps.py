"""`raspv bench e2e`, one row per head step: what each step waited for (no rclpy).

The p95 of a 40-step run is its second or third slowest step, so a run that misses a target
is judged by those steps: when did the display's *levels* (``/spv/frame``, what the display
asks of the implant) get half-way to the new view, from which camera frame (re-projected from
one taken before the step, or filled from a remembered view; or one taken after it), when the
simulator's first frame looking the new way was taken and how long after the one before it
(a camera period is 50 ms at 20 Hz; more is a late or dropped frame), when scene perception
and the display had it, and the client's half-way beside the model's own half-way for the step.

All times in ms from the send time of the step's first head message (server clock).
"""
from __future__ import annotations

import math

import numpy as np

HALF = 0.5


def _first(items, predicate):
    return next((x for x in items if predicate(x)), None)


def _ms(t: float | None, t0: float) -> float | None:
    return None if t is None else 1e3 * (t - t0)


def _d(a: np.ndarray, b: np.ndarray) -> float:
    return float(np.mean(np.abs(a.astype(np.float32) - b.astype(np.float32))))


def save_probe_log(log, path) -> None:
    """The probe's messages to ``path`` (.npz): head, pose, scene stamps; the display's frames'
    stamps, source stamps and levels (for a look at single steps afterwards)."""
    with log.lock:
        frames = list(log.frames)
        arrays = {name: np.array(getattr(log, name), float).reshape(-1, 2) for name in ("heads", "poses", "scenes")}
    shapes = {f[2].shape for f in frames}
    levels = np.stack([f[2] for f in frames]) if len(shapes) == 1 and frames else np.zeros((0, 0), np.uint8)
    np.savez_compressed(path, frame_stamps=np.array([[f[0], f[1], _scene_stamp(f)] for f in frames]).reshape(-1, 3),
                        levels=levels, **arrays)


def _scene_stamp(frame) -> float:
    """The depth frame whose scene result a logged display frame used [s] (0: none, or not logged)."""
    return frame[3] if len(frame) > 3 else 0.0


def step_rows(log, results, step_times, step_yaws, amplitude: float, model_halfway: list | None = None,
              system_onset: list | None = None) -> list[dict]:
    """One dict per counted step (``results`` of :func:`raspv_bench.motion_latency.analyse_steps`),
    from the probe's ``log`` (:class:`raspv_bench.e2e.ProbeLog`). Keys (ms from the send time
    unless said): ``k`` (step index in the run), ``yaw`` (target, deg), ``seen`` (the yaw was held
    before in the run), ``onset`` (image), ``system`` (levels), ``halfway`` (image, at the client),
    ``model`` (the model's own half-way for the step, offline), ``less`` (halfway − model),
    ``lv_half`` (the display tick whose levels were first half-way to the settled levels),
    ``lv_src`` (the camera frame those levels came from; < 0: taken before the step, the head
    turn re-projected), ``lv_back`` (the last tick after that whose levels were more than half-way
    off again: the display went back), ``lv_first`` (share of the levels' change the first changed tick made),
    ``cam`` (the first camera frame looking the new way: its capture stamp), ``cam_gap`` (its
    interval from the camera frame before it), ``scene`` (scene perception of it out),
    ``shown`` (the first display tick computed from it), ``lv_cam`` (share of the levels' change at
    that tick), ``own``
    (the first display tick of it with its own scene result, not one carried from an earlier frame),
    ``lv_scene`` (the depth frame whose scene result the half-way tick's levels used), ``img_src``
    (the camera frame of the client's half-way frame)."""
    with log.lock:
        heads, poses, scenes, frames = list(log.heads), list(log.poses), list(log.scenes), list(log.frames)
    by_stamp = {round(f[0], 6): f for f in frames}
    sent_yaw = dict(zip(step_times, step_yaws))
    order = {t: k for k, t in enumerate(sorted(step_times))}
    held, seen_before = {0}, {}
    for t in sorted(step_times):
        seen_before[t] = round(sent_yaw[t]) in held
        held.add(round(sent_yaw[t]))
    rows = []
    for i, r in enumerate(results):
        t0 = r.sent
        row = {"k": order.get(t0, -1), "yaw": float(sent_yaw.get(t0, math.nan)), "seen": seen_before.get(t0, False),
               "onset": _ms(None if r.onset_s is None else t0 + r.onset_s, t0),
               "system": system_onset[i] if system_onset else None,
               "halfway": _ms(None if r.halfway_s is None else t0 + r.halfway_s, t0),
               "model": model_halfway[i] if model_halfway else None}
        row["less"] = (None if row["halfway"] is None or row["model"] is None else row["halfway"] - row["model"])
        # the levels: before, settled (0.8–1.2 s after the step), and the first tick half-way
        pre = [f for f in frames if f[0] < t0]
        end = min([t for t in step_times if t > t0] + [t0 + 1.2])
        post = [f for f in frames if end - 0.25 < f[0] < end]
        row.update(lv_half=None, lv_src=None, lv_first=None, lv_back=None, lv_scene=None)
        share = None                                    # share of the levels' change a tick made
        if pre and post and pre[-1][2].shape == post[-1][2].shape:
            base, final = pre[-1][2], post[-1][2]
            change = _d(base, final)
            if change > 0:
                def share(f, base=base, final=final, change=change):
                    return 1.0 - _d(f[2], final) / change if f[2].shape == base.shape else None
            after = [f for f in frames if f[0] >= t0 and f[2].shape == base.shape]
            first = _first(after, lambda f: _d(f[2], base) > 0)
            if change > 0 and first is not None:
                row["lv_first"] = 1.0 - _d(first[2], final) / change
            half = _first(after, lambda f: _d(f[2], final) <= HALF * change) if change > 0 else None
            if half is not None:
                row["lv_half"], row["lv_src"] = _ms(half[0], t0), _ms(half[1], t0)
                row["lv_scene"] = _ms(_scene_stamp(half), t0) if _scene_stamp(half) > 0 else None
                off = [f for f in after if half[0] < f[0] < end and _d(f[2], final) > HALF * change]
                row["lv_back"] = _ms(off[-1][0], t0) if off else None
        # the camera path: the first frame looking the new way
        row.update(cam=None, cam_gap=None, scene=None, shown=None, lv_cam=None, own=None)
        head = _first(heads, lambda h: h[0] >= t0 - 0.005 and abs(h[1] - sent_yaw.get(t0, math.nan)) < 1.0)
        before = [p for p in poses if p[0] < (head[0] if head else t0)]
        if before:
            heading0 = before[-1][1]
            capture = _first(poses, lambda p: p[0] >= before[-1][0] + 1e-6
                             and abs((p[1] - heading0 + 180) % 360 - 180) > amplitude / 2)
            if capture is not None:
                prev = [p for p in poses if p[0] < capture[0]]
                row["cam"] = _ms(capture[0], t0)
                row["cam_gap"] = _ms(capture[0], prev[-1][0]) if prev else None
                sc = _first(scenes, lambda s: abs(s[0] - capture[0]) < 1e-6)
                row["scene"] = _ms(sc[1], t0) if sc else None
                shown = _first(frames, lambda f: f[1] >= capture[0] - 1e-6)
                row["shown"] = _ms(shown[0], t0) if shown else None
                if shown is not None and share is not None:
                    row["lv_cam"] = share(shown)
                own = _first(frames, lambda f: f[1] >= capture[0] - 1e-6 and abs(_scene_stamp(f) - f[1]) < 1e-6)
                row["own"] = _ms(own[0], t0) if own else None
        img = by_stamp.get(round(r.halfway_stamp, 6)) if r.halfway_stamp is not None else None
        row["img_src"] = _ms(img[1], t0) if img else None
        rows.append(row)
    return rows


def node_simulator(config_overrides: list[str], graph_path: Path):
    """The spv node's :class:`~raspv_spv.simulator.PhospheneSimulator` of the graph at
    ``graph_path`` with ``config_overrides`` (its temporal model, map and renderer)."""
    from raspv_bringup.graph import load_graph
    from raspv_spv.config import config_from_node_params
    from raspv_spv.simulator import PhospheneSimulator
    from raspv_spv.spv_params import PARAMS

    graph = load_graph(graph_path, config_overrides)
    entry = next(n for n in graph.nodes if n.kind == "spv")
    params = {p.name: p.default for p in PARAMS}
    params.update(entry.params)
    return PhospheneSimulator(config_from_node_params(params))


def display_halfway(log, results, config_overrides: list[str], graph_path: Path) -> list:
    """Half-way to the new view as the display drew it [ms from each step's send time], one entry
    per result (None: never): the levels the display published (``/spv/frame``) replayed at their
    tick stamps through the node's temporal model and renderer offline, with the client's criteria
    — the client's half-way less this is the delivery to the client; this less the model's own
    half-way is what the display added (levels late, a tick's period)."""
    from raspv_bench.motion_latency import analyse_steps, reduce_frame

    sim = node_simulator(config_overrides, graph_path)
    with log.lock:
        frames = [f for f in log.frames if f[2].shape == (sim.count,)]
    if not frames:
        return [None] * len(results)
    times, images = [], []
    for f in frames:
        images.append(reduce_frame(sim.render(sim.brightness(f[2], at_s=f[0]))))
        times.append(f[0])
    times = np.array(times)
    drawn, _ = analyse_steps(times, times, np.stack(images), np.array([r.sent for r in results]))
    by_sent = {round(d.sent, 6): d for d in drawn}
    out = []
    for r in results:
        d = by_sent.get(round(r.sent, 6))
        out.append(None if d is None or d.halfway_s is None else 1e3 * d.halfway_s)
    return out


def temporal_build_up(log: ProbeLog, results, config_overrides: list[str], graph_path: Path,
                      sample_ms: float = 2.0) -> tuple[list, list, list]:
    """Onset, 50 % and half-way-to-the-new-view latency [ms] of the temporal model alone, one
    entry per measured step (None where a step has no settled levels): the step's settled levels
    before → after, switched at once and displayed every ``sample_ms`` through the node's own
    temporal model offline (the recursive model's pulse clock at a different phase for each
    step; the look-up table at its frame rate), with the same criteria as at the client."""
    from raspv_bench.motion_latency import analyse_steps, reduce_frame

    sim = node_simulator(config_overrides, graph_path)
    recursive = sim.config.temporal_update == "recursive"
    dt = sample_ms / 1e3 if recursive else 1.0 / sim.config.frame_rate
    with log.lock:
        frames = list(log.frames)
    onset, half, halfway = [None] * len(results), [None] * len(results), [None] * len(results)
    for i, r in enumerate(results):
        pre = [f for f in frames if f[0] < r.sent]
        post = [f for f in frames if r.sent + 0.8 < f[0] < r.sent + 1.2]
        if not pre or not post or pre[-1][2].shape != (sim.count,) or post[-1][2].shape != (sim.count,):
            continue
        sim.reset()
        # the step at every phase of the recursive model's pulse clock (pulses at k/pulse_rate)
        phase = (0.618034 * i) % 1.0 / sim.config.pulse_rate if recursive else 0.0
        images, times = [], []
        settle, steps = 0.6 + phase, int(1.2 / dt)
        for k in range(steps):
            t = k * dt
            levels = pre[-1][2] if t < settle else post[-1][2]
            b = sim.brightness(levels, at_s=t) if recursive else sim.brightness(levels)
            images.append(reduce_frame(sim.render(b)))
            times.append(t)
        step = (math.ceil(settle / dt) * dt if recursive else int(round(settle / dt)) * dt) - 1e-6
        res, _ = analyse_steps(np.array(times), np.array(times), np.stack(images), np.array([step]))
        if res:
            onset[i] = None if res[0].onset_s is None else 1e3 * res[0].onset_s
            half[i] = None if res[0].half_s is None else 1e3 * res[0].half_s
            halfway[i] = None if res[0].halfway_s is None else 1e3 * res[0].halfway_s
    return onset, half, halfway


COLUMNS = (("k", "step", "{:>4d}"), ("seen", "seen", "{!s:>5}"), ("onset", "onset", "{:6.1f}"),
           ("system", "sys", "{:6.1f}"), ("halfway", "half", "{:6.1f}"), ("model", "model", "{:6.1f}"),
           ("less", "less", "{:6.1f}"), ("less_rise", "lessrise", "{:8.1f}"),
           ("drawn", "drawn", "{:6.1f}"), ("delivery", "deliv", "{:6.1f}"), ("lv_first", "lv1st", "{:5.2f}"), ("lv_half", "lvhalf", "{:6.1f}"),
           ("lv_src", "lvsrc", "{:7.1f}"), ("lv_back", "lvback", "{:6.1f}"), ("cam", "cam", "{:6.1f}"), ("cam_gap", "camgap", "{:6.1f}"),
           ("scene", "scene", "{:6.1f}"), ("shown", "shown", "{:6.1f}"), ("lv_cam", "lvcam", "{:5.2f}"),
           ("own", "own", "{:6.1f}"), ("lv_scene", "lvscn", "{:7.1f}"), ("img_src", "imgsrc", "{:7.1f}"))


def format_rows(rows: list[dict]) -> list[str]:
    """The rows as a fixed-width table (a header line, then one line per step; '-' where unknown)."""
    widths = [max(len(head), len(fmt.format(0 if key != "seen" else False))) for key, head, fmt in COLUMNS]
    lines = [" ".join(head.rjust(w) for (_, head, _), w in zip(COLUMNS, widths))]
    for row in rows:
        cells = []
        for (key, _, fmt), w in zip(COLUMNS, widths):
            v = row.get(key)
            cells.append(("-" if v is None else fmt.format(v)).rjust(w))
        lines.append(" ".join(cells))
    return lines


def _fmt(v) -> str:
    return "-" if v is None else f"{v:.0f}"


def slowest_summary(rows: list[dict], key: str = "less", n: int = 3) -> str:
    """What the ``n`` slowest steps by ``key`` waited for, in one line."""
    ranked = sorted((r for r in rows if r.get(key) is not None), key=lambda r: -r[key])[:n]
    parts = []
    for r in ranked:
        src = r.get("lv_src")
        waited = ("levels from a camera frame taken after the step" if src is not None and src >= 0
                  else "levels re-projected" if src is not None else "levels never half-way")
        parts.append(f"step {r['k']} {r[key]:.0f} ms ({waited}; levels half-way at {_fmt(r.get('lv_half'))} ms, "
                     f"the first camera frame looking the new way taken at {_fmt(r.get('cam'))} ms, "
                     f"{_fmt(r.get('cam_gap'))} ms after the one before)")
    return "; ".join(parts)
