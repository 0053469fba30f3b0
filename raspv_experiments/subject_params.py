"""Parameters of the `subject` node (a scripted subject; imports nothing heavy). The ability
parameters' defaults are the population's median subject (:mod:`raspv_experiments.subject_ability`);
sessions pass each virtual subject's own."""
from raspv_bringup.file_kinds import register_file_kind
from raspv_common.params import Param

POLICY_NAMES = ("navigate", "follow_path", "wander_avoid", "learned")
register_file_kind("patient_model", "raspv_experiments.learned_policy:check_model",
                   "learned virtual patient (ONNX with raspv_patient metadata, from raspv learn patient)")
DEFAULT_POLICY = "navigate"

PARAMS = [
    Param("policy", DEFAULT_POLICY, "what the virtual patient does (raspv_experiments/policies.py, navigate_policy.py)",
          choices=POLICY_NAMES),
    Param("seed", 1, "seed of the motor and perceptual noise (one virtual subject)", minimum=0, maximum=2**31 - 1),
    Param("max_linear", 0.6, "walking speed", minimum=0.05, maximum=3.0, unit="m/s"),
    Param("max_angular", 1.0, "turning speed", minimum=0.05, maximum=6.0, unit="rad/s"),
    Param("head_pitch_deg", 40.0, "head pitch held while walking (positive looks down)", minimum=-30.0, maximum=70.0,
          unit="deg"),
    Param("eye_height", 1.6, "eye height the subject assumes when judging distances", minimum=0.5, maximum=2.2,
          unit="m"),
    Param("lookahead", 1.0, "distance ahead on a trail it steers to", minimum=0.3, maximum=8.0, unit="m"),
    Param("bright_ratio", 0.85, "follow_path: the trail is what is at least this fraction of the brightest phosphene",
          minimum=0.3, maximum=1.0),
    Param("noise", 0.05, "motor noise added to the turning speed (std. dev.)", minimum=0.0, maximum=2.0, unit="rad/s"),
    Param("reaction_time_s", 0.3, "reaction time: a command acts this long (sim time) after the frame it was decided "
          "on", minimum=0.0, maximum=3.0, unit="s"),
    Param("min_brightness", 0.15, "perceptual threshold: dimmer phosphenes are not seen", minimum=0.0, maximum=1.0),
    Param("contrast_threshold", 0.12, "navigate: brighter than its row's floor by this much stands out as an obstacle",
          minimum=0.01, maximum=1.0),
    Param("perception_noise", 0.03, "std. dev. of the noise added to every brightness read", minimum=0.0, maximum=1.0),
    Param("model", "", "learned: the policy's ONNX file ('': the shipped raspv_experiments/models/"
          "learned_patient.onnx)", file_kind="patient_model"),
    Param("auto_start", True, "press 'start' as soon as instructions are shown"),
    Param("gaze", "none", "eye gaze it publishes on /gaze/direction: none, model (fixations and saccades of "
          "raspv_experiments/scripted_gaze.py, seeded per trial) or trace (the file gaze_trace)",
          choices=("none", "model", "trace")),
    Param("gaze_trace", "", "gaze trace CSV (t,x,y,z,valid or t,yaw_deg,pitch_deg,valid) for gaze: trace",
          file_kind="gaze_trace"),
    Param("gaze_rate", 120.0, "sampling rate of the gaze model", minimum=10.0, maximum=1000.0, unit="Hz"),
]
