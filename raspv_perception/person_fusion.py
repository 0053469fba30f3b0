"""Person masks made whole by depth (no ROS): the network's person probability fused with scene
perception's obstacle clusters.

The fusion works on the scene labels subsampled to about ``FUSION_WIDTH`` px wide (they come
in 4-pixel blocks at the scene node's default stride), then the mask is scaled back.

The selfie network was trained on near, frontal people at 256²; people 2–5 m away, seen from
behind or partly hidden get faint or partial masks, and the network also fires on some things
that are not people. Scene perception (``/scene/labels``) says which pixels are floor, walls,
horizontal planes and obstacle clusters. The fusion, at the scene labels' resolution:

1. **Clusters**: the pixels of things — scene perception's obstacle clusters and the measured
   pixels it could not put on a plane (``OTHER``: the curved, small pieces a body is made of) —
   are split into clusters at depth discontinuities (neighbours more than ``depth_jump`` × depth
   apart belong to different objects): scene perception's Euclidean clusters, per pixel.
2. **Whole instances**: a cluster whose mean person probability reaches ``cluster_support``
   becomes person entirely, with the cluster's outline (a faint or partial mask is enough).
3. **Dropped**: network pixels on the floor, walls or horizontal planes, and on clusters that
   did not reach the support, are not person (depth shows a surface or another object there).
   Network pieces where depth has no reading (holes, out of range) are kept only where they
   touch an accepted cluster (dark hair and clothes often return no depth), or everywhere with
   ``keep_without_depth`` — off by default: a border of missing depth on a real sensor is
   where a selfie network likes to fire.
4. **Small pieces**: connected pieces smaller than ``min_area`` of the image are dropped (a
   standing person smaller than that is more than ~7 m away for a 525 px focal length, beyond
   what the network finds).

Without scene labels only step 4 applies (colour-only input, e.g. photographs).
"""
from __future__ import annotations

from dataclasses import dataclass

import cv2
import numpy as np

from raspv_perception import scene_labels as L

FUSION_WIDTH = 320          # px: the fusion runs on the scene labels subsampled to about this width


@dataclass(frozen=True)
class FusionConfig:
    """``threshold``: network probability from which a pixel is person. ``cluster_support``: mean
    probability over an obstacle cluster from which the whole cluster is person. ``min_area``:
    smallest kept piece, fraction of the image. ``depth_jump``: relative depth step that
    separates two clusters."""

    threshold: float = 0.5
    cluster_support: float = 0.25
    min_area: float = 0.002
    depth_jump: float = 0.05
    keep_without_depth: bool = False

    def __post_init__(self) -> None:
        for name in ("threshold", "cluster_support"):
            if not 0.0 < getattr(self, name) <= 1.0:
                raise ValueError(f"{name} must be in (0, 1], got {getattr(self, name)}")
        if not 0.0 <= self.min_area < 1.0:
            raise ValueError(f"min_area must be in [0, 1), got {self.min_area}")
        if not self.depth_jump > 0.0:
            raise ValueError(f"depth_jump must be positive, got {self.depth_jump}")


@dataclass
class FusionResult:
    """``mask`` (H, W) bool at the probability's size; ``clusters``: obstacle clusters seen,
    ``accepted``: those made person; ``fused``: whether depth took part."""

    mask: np.ndarray
    clusters: int = 0
    accepted: int = 0
    fused: bool = False


def drop_small(mask: np.ndarray, min_pixels: int) -> np.ndarray:
    """``mask`` without its 8-connected pieces of fewer than ``min_pixels`` pixels."""
    if min_pixels <= 1 or not mask.any():
        return mask
    count, comp, stats, _ = cv2.connectedComponentsWithStats(mask.astype(np.uint8), connectivity=8)
    keep = stats[:, cv2.CC_STAT_AREA] >= min_pixels
    keep[0] = False
    return keep[comp]


def depth_clusters(candidates: np.ndarray, depth: np.ndarray | None, jump: float) -> tuple[int, np.ndarray]:
    """Connected components (4-neighbours) of ``candidates`` (H, W) bool, cut where neighbouring
    depths [m] differ by more than ``jump`` × the nearer one. Returns (count incl. 0, ids (H, W))."""
    cut = candidates.copy()
    if depth is not None:
        d = np.where(np.isfinite(depth), depth, 0.0).astype(np.float32)
        with np.errstate(invalid="ignore"):
            dx = np.abs(np.diff(d, axis=1)) > jump * np.minimum(d[:, 1:], d[:, :-1])
            dy = np.abs(np.diff(d, axis=0)) > jump * np.minimum(d[1:, :], d[:-1, :])
        edge = np.zeros(d.shape, bool)
        edge[:, 1:] |= dx
        edge[1:, :] |= dy          # the far side of each step: one pixel wide cuts
        cut &= ~edge
    count, ids = cv2.connectedComponents(cut.astype(np.uint8), connectivity=4)   # 4: one-pixel cuts hold
    return count, ids


def fuse_person(probability: np.ndarray, scene_labels: np.ndarray | None = None, depth: np.ndarray | None = None,
                config: FusionConfig = FusionConfig()) -> FusionResult:
    """Person mask from the network's ``probability`` (H, W) in [0, 1], made whole and cleaned with
    ``scene_labels`` (h, w) uint8 (:mod:`~raspv_perception.scene_labels`) and the ``depth`` (h, w) [m]
    they were computed from, when given (see the module docstring)."""
    prob = np.asarray(probability, np.float32)
    H, W = prob.shape
    if scene_labels is None:
        mask = drop_small(prob >= config.threshold, int(config.min_area * H * W))
        return FusionResult(mask)
    labels = np.asarray(scene_labels)
    if depth is not None and np.shape(depth) != labels.shape:
        raise ValueError(f"depth {np.shape(depth)} and scene labels {labels.shape} differ in size")
    step = max(1, labels.shape[1] // FUSION_WIDTH)      # scene labels come in blocks of 4 px anyway
    if step > 1:
        labels = labels[::step, ::step]
        depth = None if depth is None else np.asarray(depth)[::step, ::step]
    h, w = labels.shape
    p = prob if (h, w) == (H, W) else cv2.resize(prob, (w, h), interpolation=cv2.INTER_LINEAR)
    obstacle = (labels == L.OBSTACLE) | (labels == L.OTHER)
    count, ids = depth_clusters(obstacle, depth, config.depth_jump)
    person = np.zeros((h, w), bool)
    accepted = 0
    if count > 1:
        flat = ids.ravel()
        area = np.bincount(flat, minlength=count)
        support = np.bincount(flat, weights=p.ravel(), minlength=count) / np.maximum(area, 1)
        good = (support >= config.cluster_support) & (area >= max(1, int(config.min_area * h * w)))
        good[0] = False
        accepted = int(good.sum())
        if accepted:
            person = good[ids]
            # the one-pixel cuts at depth steps inside an accepted cluster belong to it
            grown = cv2.dilate(person.astype(np.uint8), np.ones((3, 3), np.uint8)) > 0
            person |= grown & obstacle & (ids == 0)
    loose = (p >= config.threshold) & (labels == L.NONE)
    if loose.any():
        n, pieces, stats, _ = cv2.connectedComponentsWithStats(loose.astype(np.uint8), connectivity=8)
        keep = np.zeros(n, bool)
        if accepted:
            near = cv2.dilate(person.astype(np.uint8), np.ones((5, 5), np.uint8)) > 0
            keep[np.unique(pieces[near & loose])] = True
        if config.keep_without_depth:
            keep |= stats[:, cv2.CC_STAT_AREA] >= int(config.min_area * h * w)
        keep[0] = False
        person |= keep[pieces]
    if (h, w) != (H, W):
        person = cv2.resize(person.astype(np.uint8), (W, H), interpolation=cv2.INTER_NEAREST) > 0
    return FusionResult(person, max(0, count - 1), accepted, True)
