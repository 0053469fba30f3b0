"""Settings of the SLAM system (no ROS), with the literature defaults they come from.

Units: metres, degrees, pixels of the full-size image, frames (of the camera's stream).
"""
from __future__ import annotations

from dataclasses import dataclass, fields

from raspv_common.intrinsics import OPENCV_DISTORTION_COUNTS


@dataclass(frozen=True)
class SlamConfig:
    # -- features (ORB-SLAM2's settings for a 640×480 RGB-D camera: 1000 ORB features, scale
    #    factor 1.2, 8 levels, FAST threshold 20)
    features: int = 1000
    scale_factor: float = 1.2
    levels: int = 8
    fast_threshold: int = 20
    min_depth: float = 0.3              # depth readings used for 3-D points [m] (Kinect v1: ~0.4-4.5 m)
    max_depth: float = 4.0              # farther structured-light depth is too noisy (σ ≈ 2.9 mm·z², Khoshelham 2012) [m]
    distortion: tuple[float, ...] = ()  # plumb-bob k1 k2 p1 p2 [k3] of the colour camera; () = rectified images
    rolling_shutter_readout: float = 0.0   # [s] first to last row of the colour camera's rolling shutter (0: global
                                        # shutter); frames are corrected to mid-row time by the predicted rotation rate
    # -- matching and PnP
    match_ratio: float = 0.8            # Lowe's ratio test on Hamming distances
    max_hamming: int = 64               # of 256 bits: ORB-SLAM's TH_LOW 50 / TH_HIGH 100
    reprojection_px: float = 3.0        # PnP RANSAC inlier threshold [px] (χ²₂ 95 % = 2.45 σ, σ ≈ 1.2 px)
    min_inliers: int = 20               # a PnP pose with fewer inliers is not trusted
    # -- dense refinement (raspv_perception's RGB-D registration, half-size images)
    dense_scale: float = 0.5
    dense_iterations: tuple[int, ...] = (6, 4, 1)   # coarse to fine; PnP gives a near start (Open3D: 10, 5, 3). One
                                        # finest iteration, not two: -8 % tracking CPU, poses 0.07 cm apart (median)
    dense_coarsest_px: int = 40         # a start not from PnP (the motion model's, a whole frame's turn off when a
                                        # turn starts or stops between frames) is registered on a pyramid going down
                                        # to the level >= this wide (4 levels at 320 px; coarser levels take the
                                        # first iterations count): a fixed angular reach for any camera's size
    min_agreement: float = 0.3          # share of 3-D points that must agree with the other frame's depth
    # -- tracking
    lost_after: int = 10                # consecutive failed frames before the state is LOST (1/3 s at 30 Hz)
    max_frame_translation: float = 0.3  # a frame-to-frame motion larger than this is a failure [m]
    max_frame_rotation_deg: float = 30.0
    new_map_after: float = 1.0          # lost this long [s of frame stamps] with relocalisation failing: a new
                                        # sub-map starts (merged when a place of the old one is seen); 0 = never
    # -- keyframes: a new one when the view left the reference (overlap, distance or angle)
    keyframe_overlap: float = 0.7       # share of the reference keyframe's 3-D points still in view
    keyframe_translation: float = 0.25  # [m]
    keyframe_rotation_deg: float = 15.0
    keyframe_candidates: int = 5        # the sharpest of the last frames becomes the keyframe (blur, rolling shutter)
    reuse_radius: float = 0.3           # an existing keyframe this close (and within reuse angle) is reused [m]
    reuse_angle_deg: float = 20.0
    covisible_keyframes: int = 6        # extra edges from a new keyframe to the keyframes sharing most of its view
    covisible_overlap: float = 0.3      # share of a keyframe's points in the other's view for an edge attempt
    # -- place recognition and loop closure
    vocabulary_words: int = 1000        # words of the per-map bag of binary words (k-majority)
    vocabulary_first: int = 8           # keyframes before the first vocabulary is trained (then at 2×, 4×, …)
    loop_candidates: int = 3            # best-scoring keyframes verified per query
    loop_min_inliers: int = 30          # PnP inliers a loop or relocalisation needs (ORB-SLAM: 50 before its refinement)
    loop_exclude_recent: int = 10       # the last keyframes are neighbours, not loops
    relocalise_min_inliers: int = 50    # PnP inliers a relocalisation needs (ORB-SLAM2's 50): with 30 the office
                                        # kidnap walk was placed 6.7 m off by 33 inliers (a right one had 286)
    # -- pose graph (GTSAM): edge noise of a dense RGB-D registration between keyframes
    edge_sigma_translation: float = 0.01   # [m]
    edge_sigma_rotation_deg: float = 0.5
    local_window_keyframes: int = 30    # the loop closer's per-keyframe optimisation moves the sub-map's last N
                                        # keyframes (their neighbours held); the whole sub-map at a loop (ORB-SLAM)
    whole_graph_sigmas: float = 1.0     # a new edge out of that window disagreeing with the map by more than this
                                        # many σ (translation or rotation) is a loop: the whole sub-map is optimised
    # -- resources
    threads: int = 1                    # OpenCV and Open3D threads (process-wide); 1 = one core
    background: bool = True             # loop closing in a background thread (False: inline, for tests)

    def __post_init__(self) -> None:
        positive = ("features", "scale_factor", "levels", "keyframe_candidates", "min_inliers", "dense_scale", "lost_after",
                    "dense_coarsest_px",
                    "max_frame_translation", "max_frame_rotation_deg", "keyframe_translation",
                    "keyframe_rotation_deg", "vocabulary_words", "loop_candidates", "loop_min_inliers",
                    "relocalise_min_inliers",
                    "edge_sigma_translation", "edge_sigma_rotation_deg", "reprojection_px", "threads",
                    "local_window_keyframes", "whole_graph_sigmas")
        for name in positive:
            if not getattr(self, name) > 0:
                raise ValueError(f"{name} must be positive, got {getattr(self, name)}")
        if not 0 <= self.rolling_shutter_readout < 0.1:
            raise ValueError(f"rolling_shutter_readout must be in [0, 0.1) s, got {self.rolling_shutter_readout}")
        if not self.new_map_after >= 0:
            raise ValueError(f"new_map_after must be >= 0 s (0: never start a new map), got {self.new_map_after}")
        if not 0 <= self.min_depth < self.max_depth:
            raise ValueError(f"need 0 <= min_depth < max_depth, got {self.min_depth}, {self.max_depth}")
        if not 0 < self.match_ratio <= 1:
            raise ValueError(f"match_ratio must be in (0, 1], got {self.match_ratio}")
        if not 0.05 <= self.dense_scale <= 1:
            raise ValueError(f"dense_scale must be in [0.05, 1], got {self.dense_scale}")
        for name in ("min_agreement", "keyframe_overlap", "covisible_overlap"):
            if not 0 <= getattr(self, name) <= 1:
                raise ValueError(f"{name} must be in [0, 1], got {getattr(self, name)}")
        if self.distortion and len(self.distortion) not in OPENCV_DISTORTION_COUNTS:
            raise ValueError(f"distortion needs 4, 5 or 8 plumb-bob coefficients (or none), got {len(self.distortion)}")
        if self.scale_factor <= 1:
            raise ValueError(f"scale_factor must be > 1, got {self.scale_factor}")

    def as_dict(self) -> dict:
        return {f.name: (list(v) if isinstance(v := getattr(self, f.name), tuple) else v) for f in fields(self)}

    @classmethod
    def from_dict(cls, values: dict) -> "SlamConfig":
        """A config from saved values; unknown keys (from another version) are ignored."""
        known = {f.name for f in fields(cls)}
        kw = {k: tuple(v) if isinstance(v, list) else v for k, v in values.items() if k in known}
        return cls(**kw)
