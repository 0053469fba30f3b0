"""The obstacle-course count sweep inside the study's range (10×10–50×50), against the people of
de Ruyter van Steveninck et al. 2022: the power the sweep has to see the people's effect, the
trend inside the range, and the share of performance restored at each count beside theirs.
Prints the Markdown tables of docs/experiments.md ("Inside the study's range").

    .venv/bin/python tools/count_sweep_vs_people.py [experiments/results/obstacle_course_sweep.quick.csv]
"""
from __future__ import annotations

import sys
from pathlib import Path

import numpy as np

REPO = Path(__file__).resolve().parents[1]
SHIPPED = REPO / "experiments" / "results" / "obstacle_course_sweep.quick.csv"
FACTOR = "spv.num_phosphenes"
IN_RANGE = ["100", "324", "676", "2500"]          # the sweep's counts inside 10×10–50×50
LIMITS = {"course": 90.0}


def analyse(path: Path = SHIPPED) -> dict:
    """Everything the docs state, computed from the sweep's rows."""
    from raspv_experiments.human_reference import HUMAN_RESTORED, restored
    from raspv_experiments.power import effect_size_dz, paired_t_power, subjects_for_power
    from raspv_experiments.quick_sweep import read_quick_csv
    from raspv_experiments.subject_ability import subject_ability
    from raspv_experiments.trend import ordered_trends, subject_matrix
    from raspv_experiments.world_geometry import world_geometry

    records = [r for r in read_quick_csv([path]) if r.factors.get(FACTOR) in IN_RANGE]
    subjects, time_m = subject_matrix(records, LIMITS, FACTOR, IN_RANGE, "time_s")
    _, length = world_geometry(str(REPO / "experiments" / "worlds" / "obstacle_course.yaml")).shortest_path(
        (1.0, 1.5), (24.0, 1.5), 1.6)
    normal = {s: length / subject_ability(s)["max_linear"] for s in subjects}
    gap = time_m[:, 0].mean() - np.mean(list(normal.values()))
    sd = float(np.std(time_m[:, 0] - time_m[:, IN_RANGE.index("676")], ddof=1))
    power = {}
    for count, share in ((324, HUMAN_RESTORED["time_s"][(324, "simple")]),
                         (676, HUMAN_RESTORED["time_s"][(676, "simple")])):
        effect = share / 100 * gap                     # the people's gain from 10×10, in this sweep's seconds
        dz = effect / sd
        power[count] = {"share": share, "effect_s": effect, "dz": dz, "power": paired_t_power(dz, len(subjects)),
                        "n80": subjects_for_power(dz, 0.8), "n90": subjects_for_power(dz, 0.9)}
    observed_dz = effect_size_dz(time_m[:, 0] - time_m[:, IN_RANGE.index("676")])
    return {"subjects": len(subjects), "shortest_m": length, "normal_time_s": float(np.mean(list(normal.values()))),
            "time_10x10_s": float(time_m[:, 0].mean()), "gap_s": float(gap), "sd_diff_s": sd, "power": power,
            "observed_dz": observed_dz, "trends": ordered_trends(records, LIMITS, FACTOR, IN_RANGE),
            "restored": restored(records, FACTOR, IN_RANGE, LIMITS, normal)}


def main(argv: list[str]) -> int:
    from raspv_experiments.human_reference import restored_table
    from raspv_experiments.trend import trend_table

    a = analyse(Path(argv[0]) if argv else SHIPPED)
    print(f"{a['subjects']} subjects; 10×10 mean time {a['time_10x10_s']:.1f} s; normal vision (shortest path "
          f"{a['shortest_m']:.2f} m at each subject's speed) {a['normal_time_s']:.1f} s; gap {a['gap_s']:.1f} s; "
          f"SD of the 10×10 − 26×26 differences {a['sd_diff_s']:.1f} s; observed d_z {a['observed_dz']:.2f}")
    for count, p in a["power"].items():
        print(f"people's gain 10×10 → {count}: {p['share']} % of the gap = {p['effect_s']:.1f} s, d_z {p['dz']:.2f}: "
              f"power {p['power']:.2f} with n = {a['subjects']} (paired t, alpha 0.05 two-sided); "
              f"n for 80 % {p['n80']}, for 90 % {p['n90']}")
    print()
    print(trend_table(a["trends"], FACTOR))
    print()
    print(restored_table(a["restored"]))
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))
