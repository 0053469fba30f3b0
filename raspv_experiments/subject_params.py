"""Parameters of the `subject` node (a scripted subject; imports nothing heavy)."""
from raspv_common.params import Param

POLICY_NAMES = ("follow_path", "wander_avoid")

PARAMS = [
    Param("policy", "follow_path", "what the virtual patient does (raspv_experiments/policies.py)", choices=POLICY_NAMES),
    Param("seed", 1, "seed of the motor noise (one virtual subject)", minimum=0, maximum=2**31 - 1),
    Param("max_linear", 0.6, "walking speed", minimum=0.05, maximum=3.0, unit="m/s"),
    Param("max_angular", 1.0, "turning speed", minimum=0.05, maximum=6.0, unit="rad/s"),
    Param("head_pitch_deg", 40.0, "head pitch held while walking (positive looks down)", minimum=-30.0, maximum=70.0,
          unit="deg"),
    Param("eye_height", 1.6, "eye height the subject assumes when judging distances", minimum=0.5, maximum=2.2,
          unit="m"),
    Param("lookahead", 1.0, "follow_path: distance ahead on the trail it steers to", minimum=0.3, maximum=8.0, unit="m"),
    Param("bright_ratio", 0.85, "follow_path: the trail is what is at least this fraction of the brightest phosphene",
          minimum=0.3, maximum=1.0),
    Param("noise", 0.05, "motor noise added to the turning speed (std. dev.)", minimum=0.0, maximum=2.0, unit="rad/s"),
    Param("auto_start", True, "press 'start' as soon as instructions are shown"),
]
