"""Parameters of the `teleop` node (keyboard in a terminal)."""
from raspv_common.params import Param

PARAMS = [
    Param("linear_speed", 0.5, "initial walking speed (q/z, w/x change it)", minimum=0.0, maximum=3.0, unit="m/s"),
    Param("angular_speed", 1.0, "initial turning speed (q/z, e/c change it)", minimum=0.0, maximum=6.0, unit="rad/s"),
    Param("key_timeout", 0.7, "keep moving this long after the last motion key (0: until another key)",
          minimum=0.0, maximum=10.0, unit="s"),
    Param("head_step_deg", 5.0, "head turn per arrow key", minimum=0.5, maximum=45.0, unit="deg"),
    Param("rate", 10.0, "how often /cmd_vel and /head/orientation are published", minimum=1.0, maximum=100.0,
          dynamic=False, unit="Hz"),
]
