"""Scene perception from one depth frame (no ROS): floor and gravity frame, Manhattan axes,
classified planes, obstacle clusters, free floor and a per-pixel class image.

    perception = ScenePerception(SceneConfig())
    result = perception.process(depth_m, intrinsics, world_from_camera=None)
    result.structure.floor_found, result.structure.camera_height, result.labels  # (H, W) uint8

The object keeps the floor track between frames (feed frames in order; ``reset()`` between
sequences). Geometry in the camera optical frame C unless stated; see ``scene_structure``.
"""
from __future__ import annotations

import math
import time
from dataclasses import dataclass

import cv2
import numpy as np

from raspv_common.intrinsics import CameraIntrinsics
from raspv_perception import scene_labels as L
from raspv_perception.floor import CAMERA_UP, FloorCandidate, FloorTracker, angle_deg, camera_angles, floor_frame
from raspv_perception.free_floor import free_floor
from raspv_perception.manhattan import HorizontalBasis, manhattan_axes
from raspv_perception.obstacles import euclidean_clusters, organised_links
from raspv_perception.plane_extraction import (CloudSamples, PlaneSegment, dominant_up, grow_planes, slanted_planes,
                                               upward_layers, vertical_planes, _pieces)
from raspv_perception.plane_fitting import hull_on_plane
from raspv_perception.point_cloud import as_depth_metres, organised_cloud, organised_normals
from raspv_perception.scene_config import SceneConfig
from raspv_perception.scene_structure import GravitySource, ObstacleCluster, Plane, PlaneType, SceneStructure

_PLANE_LABEL = {PlaneType.FLOOR: L.FLOOR, PlaneType.WALL: L.WALL, PlaneType.HORIZONTAL: L.HORIZONTAL,
                PlaneType.OTHER: L.OTHER}


@dataclass
class SceneResult:
    """``structure``: what was found; ``labels`` (H, W) uint8 class per depth pixel
    (``scene_labels``)."""

    structure: SceneStructure
    labels: np.ndarray


class _StageClock:
    def __init__(self, t0: float) -> None:
        self.last = t0
        self.laps: dict[str, float] = {}

    def lap(self, name: str) -> None:
        now = time.perf_counter()
        self.laps[name] = (now - self.last) * 1e3
        self.last = now


class ScenePerception:
    """The full pipeline with its floor track. ``config`` may be replaced between frames."""

    def __init__(self, config: SceneConfig | None = None) -> None:
        self.config = config or SceneConfig()
        self.tracker = FloorTracker(self.config)
        self.timings: dict[str, float] = {}   # last frame's stage durations [ms]

    def reset(self) -> None:
        """Forget the floor track (start of a new sequence)."""
        self.tracker.reset()

    def set_config(self, config: SceneConfig) -> None:
        self.config = config
        self.tracker.config = config

    # -----------------------------------------------------------------------------------------
    def process(self, depth: np.ndarray, intrinsics: CameraIntrinsics,
                world_from_camera: np.ndarray | None = None, gravity_up: np.ndarray | None = None) -> SceneResult:
        """Analyse one depth image ((H, W) float metres with NaN holes, or uint16 mm).
        ``world_from_camera``: optional 4×4 pose (world z up), used as a prior for gravity;
        ``gravity_up``: optional up direction in C measured by an IMU (see ``imu_gravity``),
        which lets a first floor be found at any camera height."""
        t0 = time.perf_counter()
        cfg = self.config
        pose = None if world_from_camera is None else np.asarray(world_from_camera, dtype=np.float64)
        if pose is not None and (pose.shape != (4, 4) or not np.isfinite(pose).all()):
            raise ValueError(f"camera pose must be a finite 4x4 matrix, got shape {pose.shape}")
        imu_up = None if gravity_up is None else np.asarray(gravity_up, dtype=np.float64).reshape(-1)
        if imu_up is not None:
            if imu_up.shape != (3,) or not np.isfinite(imu_up).all() or np.linalg.norm(imu_up) < 1e-6:
                raise ValueError(f"gravity_up must be a finite non-zero 3-vector, got {gravity_up!r}")
            imu_up = imu_up / np.linalg.norm(imu_up)
        depth = as_depth_metres(depth, intrinsics)
        cloud = organised_cloud(depth, intrinsics, cfg.stride, cfg.min_depth, cfg.max_depth)
        normals, has_normal = organised_normals(cloud, cfg.normal_step, cfg.max_inverse_depth_bend)
        S = CloudSamples.build(cloud.points, cloud.valid, normals, has_normal, cloud.footprint, cfg)
        structure = SceneStructure()
        clock = _StageClock(t0)
        clock.lap("cloud_normals")

        # 1. Gravity and floor ------------------------------------------------------------------
        expect = self.tracker.expectation(pose, imu_up)
        cone = expect.max_angle_deg if self.tracker.tracking else max(expect.max_angle_deg, cfg.support_max_angle_deg)
        g = dominant_up(S, expect.up, cone, cfg.min_plane_area)
        layers = upward_layers(S, g, cfg) if g is not None else []
        candidates = [FloorCandidate(p, a) for p, _, a in layers]
        chosen = self.tracker.choose(candidates, expect)
        floor_index = next((i for i, c in enumerate(candidates) if c is chosen), None)
        reference = None            # plane heights are measured from (floor, else support plane)
        if chosen is not None:
            up, source, reference = chosen.plane[:3], GravitySource.FLOOR, chosen.plane
        elif imu_up is not None:
            up, source = imu_up, GravitySource.IMU
        elif pose is not None:
            up, source = pose[:3, :3].T @ np.array([0.0, 0.0, 1.0]), GravitySource.POSE    # world z in C
        elif layers and angle_deg(layers[0][0][:3], CAMERA_UP) <= cfg.support_max_angle_deg:
            up, source = layers[0][0][:3], GravitySource.SUPPORT
        else:
            up, source = (g if g is not None else CAMERA_UP), GravitySource.NONE
        up = np.asarray(up, dtype=np.float64) / np.linalg.norm(up)
        if reference is None and layers and source in (GravitySource.POSE, GravitySource.SUPPORT, GravitySource.IMU):
            reference = layers[0][0]
        structure.up, structure.gravity_source = up, source
        self.tracker.update(None if chosen is None else chosen.plane, pose)
        if chosen is not None:
            structure.floor_found = True
            structure.floor_plane = np.asarray(chosen.plane, dtype=np.float64)
            structure.camera_to_floor = floor_frame(chosen.plane)
            structure.camera_height = float(chosen.plane[3])
            structure.camera_pitch_deg, structure.camera_roll_deg = camera_angles(chosen.plane)
        clock.lap("floor")

        # 2. Planes ----------------------------------------------------------------------------
        segments: list[tuple[PlaneSegment, bool]] = []      # (piece, is floor)
        free = S.valid.copy()
        for i, (plane, inl, _) in enumerate(layers):
            pieces, _ = _pieces(S, plane, inl, "up", cfg.min_plane_area)
            segments.extend((piece, i == floor_index) for piece in pieces)
            free[inl] = False
        basis = HorizontalBasis.from_up(up)
        with np.errstate(invalid="ignore"):
            vertical = S.has_normal & (np.abs(S.normals @ up.astype(np.float32))
                                       <= math.sin(math.radians(cfg.plane_normal_angle_deg)))
        vert_idx = np.flatnonzero(vertical)
        vert_az = basis.azimuth_deg(S.normals[vert_idx])
        axes = manhattan_axes(basis, vert_az, S.area[vert_idx], cfg.manhattan_min_area)
        if axes is not None:
            structure.manhattan_found, structure.manhattan_x, structure.manhattan_z = True, axes.x, axes.z
        still = free[vert_idx]
        clock.lap("manhattan")
        loose = np.flatnonzero(free & ~S.has_normal)
        for piece in vertical_planes(S, basis, vert_idx[still], vert_az[still], loose, cfg):
            segments.append((piece, False))
            free[piece.indices] = False
        clock.lap("walls")
        for piece in slanted_planes(S, np.flatnonzero(free & S.has_normal), cfg):
            segments.append((piece, False))
            free[piece.indices] = False

        for (piece, _), extra in zip(segments, grow_planes(S, [seg for seg, _ in segments], free)):
            piece.indices = np.concatenate([piece.indices, extra])
        labels = np.where(cloud.valid, L.OTHER, L.NONE).astype(np.uint8)
        flat = labels.reshape(-1)
        for piece, is_floor in segments:
            kind = self._classify(piece, is_floor, up, S, structure)
            flat[piece.indices] = _PLANE_LABEL[kind]
            structure.planes.append(self._describe(piece, kind, S, structure))
        clock.lap("slanted_hulls")

        # 3. Obstacles and free floor ------------------------------------------------------------
        if reference is not None:
            self._obstacles(structure, S, labels, reference, intrinsics, in_plane=~free)
        clock.lap("obstacles_free_floor")
        full = cloud.upsample(labels)
        with np.errstate(invalid="ignore"):
            full[~((depth >= cfg.min_depth) & (depth <= cfg.max_depth))] = L.NONE
        clock.lap("labels")
        self.timings = clock.laps
        structure.processing_ms = (time.perf_counter() - t0) * 1e3
        return SceneResult(structure, full)

    # -----------------------------------------------------------------------------------------
    def _classify(self, piece: PlaneSegment, is_floor: bool, up: np.ndarray, S: CloudSamples,
                  structure: SceneStructure) -> PlaneType:
        """Floor; horizontal (normal within ``horizontal_angle_deg`` of up); wall (vertical, at
        least ``min_wall_area`` or spanning the view from top to bottom, and reaching
        ``min_wall_top`` above the floor or the top of the view — furniture sides stay
        obstacles); other."""
        cfg = self.config
        if is_floor:
            return PlaneType.FLOOR
        tilt = angle_deg(piece.plane[:3], up)
        if tilt < cfg.horizontal_angle_deg:
            return PlaneType.HORIZONTAL
        if abs(tilt - 90.0) > cfg.vertical_angle_deg:
            return PlaneType.OTHER
        h, w = S.shape
        margin = cfg.normal_step + 1                       # rows without normals at the border
        top_row = int(piece.indices.min()) // w
        bottom_row = int(piece.indices.max()) // w
        reaches_top = top_row <= margin
        if piece.area < cfg.min_wall_area and not (reaches_top and bottom_row >= h - 1 - margin):
            return PlaneType.OTHER
        if not structure.floor_found or reaches_top:
            return PlaneType.WALL
        f = structure.floor_plane
        top = float((S.points[piece.indices] @ f[:3].astype(np.float32)).max() + f[3])
        return PlaneType.WALL if top >= cfg.min_wall_top else PlaneType.OTHER

    @staticmethod
    def _describe(piece: PlaneSegment, kind: PlaneType, S: CloudSamples, structure: SceneStructure) -> Plane:
        idx = piece.indices
        pts = S.points[idx]
        centroid = pts.mean(axis=0).astype(np.float64)
        # The hull of the image-space hull's samples: a plane seen by a pinhole camera maps
        # projectively to the image, which keeps convex hulls.
        ys, xs = np.divmod(idx.astype(np.int32), np.int32(S.shape[1]))
        img_hull = cv2.convexHull(np.stack([xs, ys], axis=1), returnPoints=False).reshape(-1)
        hull, area = hull_on_plane(pts[img_hull], piece.plane)
        height = (float(structure.floor_plane[:3] @ centroid + structure.floor_plane[3])
                  if structure.floor_found else math.nan)
        return Plane(kind, np.asarray(piece.plane, dtype=np.float64), centroid, area, height, len(idx), hull)

    def _obstacles(self, structure: SceneStructure, S: CloudSamples, labels: np.ndarray, reference: np.ndarray,
                   intrinsics: CameraIntrinsics, in_plane: np.ndarray) -> None:
        cfg = self.config
        flat = labels.reshape(-1)
        n = reference[:3].astype(np.float32)
        with np.errstate(invalid="ignore"):
            height = S.points @ n + np.float32(reference[3])
            # Everything above the reference plane's inlier band joins the clustering, so an
            # obstacle keeps its base; clusters whose top stays below min_obstacle_height are
            # sensor noise along the plane and are dropped. Samples without a normal that no
            # plane took (depth edges, where "flying pixels" bridge objects) are labelled
            # afterwards but do not link.
            above = (S.valid & (flat != L.FLOOR) & (flat != L.WALL)
                     & (height > S.tolerance) & (height < cfg.max_obstacle_height))
            cand = above & (S.has_normal | in_plane)
        idx = np.flatnonzero(cand)
        T = floor_frame(reference)
        R, t = T[:3, :3], T[:3, 3]
        obstacle_xz = np.zeros((0, 2))
        if len(idx):
            pts_c = S.points[idx]
            # Neighbouring samples lie (stride·z/f) / cos(incidence) apart on a surface: the
            # sample's surface area over its lateral spacing (long on grazing table tops).
            lateral = pts_c[:, 2] * np.float32(cfg.stride / intrinsics.fx)
            spacing = S.area[idx] / lateral
            links = organised_links(idx, pts_c, S.shape, cfg.cluster_tolerance, spacing, spacing_factor=1.5)
            ids, count = euclidean_clusters(pts_c, cfg.voxel_size, cfg.cluster_tolerance, cfg.min_cluster_voxels, links)
            if count:
                # Each cluster's top: the highest member above the inlier band (a sorted
                # segment-wise maximum; every cluster id 0..count-1 has members).
                clustered = ids >= 0
                cl_ids = ids[clustered]
                cl_idx = idx[clustered]
                cl_order = np.argsort(cl_ids, kind="stable")
                starts = np.searchsorted(cl_ids[cl_order], np.arange(count))
                top = np.maximum.reduceat((height[cl_idx] - S.tolerance[cl_idx])[cl_order], starts).astype(np.float64)
                tall = np.flatnonzero(top >= cfg.min_obstacle_height)
                remap = np.full(count + 1, -1, dtype=np.int64)
                remap[tall] = np.arange(len(tall))
                ids, count = remap[ids], len(tall)          # ids of -1 stay -1 (remap[-1] = -1)
            member = ids >= 0
            pts = S.points[idx[member]].astype(np.float64)
            cid = ids[member]
            in_f = (pts - t) @ R                                    # F coordinates (x, y down, z)
            obstacle_xz = in_f[:, [0, 2]]
            was_other = flat[idx[member]] == L.OTHER
            flat[idx[member][was_other]] = L.OBSTACLE
            edge = above & ~S.has_normal & (flat == L.OTHER)
            near = cv2.dilate((labels == L.OBSTACLE).astype(np.uint8), np.ones((3, 3), np.uint8)).reshape(-1) > 0
            flat[edge & near] = L.OBSTACLE
            hz = np.hypot(in_f[:, 0], in_f[:, 2])
            order = np.argsort(cid, kind="stable")
            bounds = np.searchsorted(cid[order], np.arange(count + 1))
            if count:
                # Per-cluster reductions over the sorted members' segments (the same sums, in the
                # same order, as the per-cluster mean/min/max).
                starts, sizes = bounds[:-1], np.diff(bounds)
                centroids = np.add.reduceat(pts[order], starts, axis=0) / sizes[:, None]
                box = in_f[order]
                lo = np.minimum.reduceat(box, starts, axis=0)
                hi = np.maximum.reduceat(box, starts, axis=0)
                nearest = np.minimum.reduceat(hz[order], starts)
                for k in range(count):
                    structure.obstacles.append(ObstacleCluster(
                        centroid=centroids[k], min_floor=lo[k], max_floor=hi[k], height=float(-lo[k, 1]),
                        distance=float(nearest[k]), num_points=int(sizes[k])))
        if not structure.floor_found:
            return
        floor_idx = np.flatnonzero(flat == L.FLOOR)
        floor_f = (S.points[floor_idx].astype(np.float64) - t) @ R
        grid = free_floor(floor_f[:, [0, 2]], obstacle_xz, cfg.floor_cell, cfg.obstacle_margin, cfg.max_depth)
        flat[floor_idx[grid.is_blocked(floor_f[:, [0, 2]])]] = L.FLOOR_BLOCKED
        structure.free_floor = grid.polygon
