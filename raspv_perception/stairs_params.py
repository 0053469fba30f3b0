"""Parameters of the `stairs` node; they map onto ``StairConfig`` fields of the same name."""
from raspv_common.params import Param

PARAMS = [
    Param("h_min", 0.09, "lowest riser of a staircase", minimum=0.02, maximum=0.5, unit="m"),
    Param("h_max", 0.225, "highest riser of a staircase", minimum=0.03, maximum=0.6, unit="m"),
    Param("min_tread", 0.22, "shortest tread", minimum=0.05, maximum=1.0, unit="m"),
    Param("max_tread", 0.60, "longest tread", minimum=0.1, maximum=2.0, unit="m"),
    Param("min_steps", 2, "steps (levels above or below the floor) needed to report a staircase", minimum=2, maximum=20),
    Param("connect_distance", 0.5, "neighbouring steps have points this close on the floor plane", minimum=0.05,
          maximum=2.0, unit="m"),
    Param("min_step_area", 0.04, "smallest visible piece of tread", minimum=0.005, maximum=2.0, unit="m^2"),
    Param("stride", 2, "process every stride-th depth pixel", minimum=1, maximum=8, unit="px"),
    Param("max_depth", 6.0, "farther depth readings are ignored", minimum=0.5, maximum=20.0, unit="m"),
]

CONFIG_FIELDS = tuple(p.name for p in PARAMS)
