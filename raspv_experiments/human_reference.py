"""The published human numbers of the obstacle-course study and the same measure computed for a
virtual patients' count sweep, point by point (no rclpy).

de Ruyter van Steveninck et al. 2022, JoV 22(2):1 ("Real-world indoor mobility with simulated
prosthetic vision", Results, "Phosphene resolution"): 20 sighted subjects, Canny-edge SPV at 10×10
… 50×50 phosphenes. Performance is given as the share **restored**: 0 % is the mean at 10×10 in
the complex (textured) course, 100 % the mean with normal (camera) vision — trial duration
16.74 s (SD 4.44) and 0 collisions there. The text reports it at two resolutions of the simple
course (plain boxes, as `experiments/worlds/obstacle_course.yaml`) and one of the complex one;
the other points are in its Fig. 2.5 as standardised scores and are not used here.

For virtual patient s at count N the same measure is ``(M_10 − M_N) / (M_10 − M_normal)`` on the
means over subjects, with ``M_normal`` of normal vision: 0 collisions (as the people), and for
time the shortest path of the course for the 0.25 m body walked at the subject's own speed
(a lower bound of what seeing everything would give: no slowing near boxes, no turning).
Anchored on the simple course's 10×10 (the people's anchor is the complex one's, so their simple
10×10 is itself above 0 %).
"""
from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from raspv_experiments.quick_sweep import measure_of

CITATION = "de Ruyter van Steveninck et al. 2022, JoV 22(2):1, Results: Phosphene resolution"
HUMAN_SUBJECTS = 20
HUMAN_NORMAL_VISION_TIME_S = 16.74            # mean (SD 4.438) with camera vision, 0 collisions
# (phosphenes, course) -> % restored, as the paper's text states it
HUMAN_RESTORED = {
    "time_s": {(324, "simple"): 46.2, (676, "simple"): 59.2, (676, "complex"): 52.2},
    "collisions": {(324, "simple"): 81.5, (676, "simple"): 90.2, (676, "complex"): 74.1},
}


@dataclass
class Restored:
    measure: str
    level: str
    percent: float                      # % restored, mean over subjects
    ci: tuple[float, float]             # percentile bootstrap 95 % over subjects
    human_simple: float | None          # the people's % at this count, simple course (None: not in the text)


def _per_subject(records, measure: str, level: str, factor: str, time_limits: dict[str, float]) -> dict[int, float]:
    vals: dict[int, list[float]] = {}
    for r in records:
        if r.factors.get(factor) == level:
            vals.setdefault(r.subject, []).append(measure_of(r, measure, time_limits))
    return {s: float(np.mean(v)) for s, v in vals.items()}


def restored(records, factor: str, levels: list[str], time_limits: dict[str, float],
             normal_time_s: dict[int, float], seed: int = 1, resamples: int = 9999) -> list[Restored]:
    """% restored at each level against the first (``levels[0]``: 0 %) and normal vision (100 %),
    for time (normal: ``normal_time_s`` per subject) and collisions (normal: 0); ratio of means
    over the subjects that ran every level, with a percentile bootstrap over subjects."""
    rng = np.random.default_rng(seed)
    out = []
    for measure in ("time_s", "collisions"):
        per = [_per_subject(records, measure, lv, factor, time_limits) for lv in levels]
        subjects = sorted(set.intersection(*(set(p) for p in per)))
        if len(subjects) < 2:
            raise ValueError(f"{measure}: fewer than 2 subjects ran every level")
        m = np.array([[p[s] for s in subjects] for p in per])                # (L, S)
        normal = np.array([normal_time_s[s] if measure == "time_s" else 0.0 for s in subjects])
        pick = rng.integers(0, len(subjects), (resamples, len(subjects)))

        def share(rows, base, ref):
            gap = base.mean(-1) - ref.mean(-1)
            with np.errstate(divide="ignore", invalid="ignore"):
                return 100.0 * (base.mean(-1) - rows.mean(-1)) / gap

        for i, level in enumerate(levels):
            point = float(share(m[i], m[0], normal))
            boot = share(m[i][pick], m[0][pick], normal[pick])
            boot = boot[np.isfinite(boot)]
            ci = (float(np.percentile(boot, 2.5)), float(np.percentile(boot, 97.5))) if len(boot) else (np.nan, np.nan)
            human = HUMAN_RESTORED[measure].get((int(level), "simple"))
            out.append(Restored(measure, level, point, ci, human))
    return out


def restored_table(rows: list[Restored]) -> str:
    """Markdown: per count, the virtual patients' % restored [CI] beside the people's."""
    lines = ["| phosphenes | time: virtual % [95 % CI] | time: people % | collisions: virtual % [95 % CI] | "
             "collisions: people % |", "|---|---|---|---|---|"]
    by = {(r.measure, r.level): r for r in rows}
    for level in dict.fromkeys(r.level for r in rows):
        cells = []
        for measure in ("time_s", "collisions"):
            r = by[(measure, level)]
            cells.append(f"{r.percent:.0f} [{r.ci[0]:.0f}, {r.ci[1]:.0f}]")
            cells.append("—" if r.human_simple is None else f"{r.human_simple:.1f}")
        lines.append(f"| {level} | " + " | ".join(cells) + " |")
    return "\n".join(lines)
