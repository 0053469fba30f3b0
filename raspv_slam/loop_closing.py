"""Loop closing in a background thread: covisibility and loop edges for each new keyframe, then
pose-graph optimisation (no ROS).

For each keyframe the tracker makes (:meth:`LoopCloser.submit`):
1. it is indexed in the place database (which learns its vocabulary as the map grows);
2. **covisibility**: the older keyframes sharing most of its view (their 3-D points projected
   into it with the current poses) are registered to it (PnP + dense refinement from the poses'
   relative guess); each success is an edge. Only older ones: a keyframe made after it links to
   it when its own turn comes, so each pair is linked once and the graph is the same however far
   the thread lags behind tracking (lagging, it linked a keyframe to its own child too, the
   odometry edge counted twice, and the pan's floor point ended 4.8 or 5.0 cm off by the lag);
3. **loop**: the place database's best candidates that are not recent and not already linked
   are verified with PnP RANSAC (at least ``loop_min_inliers`` inliers, no pose guess: the
   drift may be large) and dense refinement; each success is a loop edge (robust kernel);
4. **merge**: when the map has several sub-maps (a new one is started after tracking was lost
   in an unmapped place), the best candidates of the *other* sub-maps are verified the same way
   with the relocalisation's stricter ``relocalise_min_inliers``; a verified one merges the two
   sub-maps: the younger is re-expressed in the older's frame by the one rigid transform the
   edge gives (:meth:`SlamMap.merge_segments`) and the edge joins the pose graph;
5. the pose graph (GTSAM, graduated non-convexity) is optimised, edges it judges outliers are
   dropped and the map's poses replaced; tracking applies the correction at its next frame.
   **Locally** for most keyframes: the sub-map's last ``local_window_keyframes`` keyframes move,
   the keyframes they share edges with are held at their poses — a cost that does not grow with
   the map (ORB-SLAM's local window; the whole graph per keyframe fell minutes behind a walk
   through new places). **The whole sub-map** when a loop edge or a merge was added, or when a
   new edge reaching outside the window disagrees with the map by more than
   ``whole_graph_sigmas`` of its noise (a loop closed by covisibility): a correction that must
   spread along the loop. Either way the same graduated non-convexity judges every edge it
   holds, so a wrong loop edge is dropped as before.

The thread runs at the tracker's pace: it never holds the map's lock while it computes, so
tracking does not wait for it (``background=False`` in the config runs it inline, for tests).
"""
from __future__ import annotations

import queue
import threading
import time

import numpy as np

from raspv_slam.config import SlamConfig
from raspv_slam.frame import FramePreparer
from raspv_slam.frame_registration import FrameRegistrar
from raspv_slam.pose_graph import PoseGraphProcess, optimise
from raspv_slam.se3 import inverse, pose_distance
from raspv_slam.slam_map import Edge, SlamMap

STOP = -1


class LoopCloser:
    def __init__(self, slam_map: SlamMap, registrar: FrameRegistrar, preparer: FramePreparer,
                 config: SlamConfig) -> None:
        self.map = slam_map
        self.registrar = registrar
        self.preparer = preparer
        self.config = config
        self._queue: queue.Queue[tuple[int, float]] = queue.Queue()     # (keyframe, submitted [monotonic s])
        self._thread: threading.Thread | None = None
        self._solver = PoseGraphProcess() if config.background else None
        self.loop_edges = 0
        self.covisibility_edges = 0
        self.optimisations = 0
        self.whole_graph_optimisations = 0       # of the optimisations, those over the whole sub-map
        self.whole_graph_for_loops = 0           # of those, the ones for a loop edge or a merge (the rest: an
                                                 # edge out of the window disagreeing with the map)
        self.merges = 0
        self.rejected: list[Edge] = []          # judged outliers by the optimisation (removed from the map)
        self.busy_ms: list[float] = []          # time spent per keyframe [ms]
        self.latency_ms: list[float] = []       # submitted to processed, per keyframe [ms] (waiting included)
        self.error: BaseException | None = None

    def submit(self, kf_id: int) -> None:
        if not self.config.background:
            self.process(kf_id)
            return
        if self._thread is None:
            self._thread = threading.Thread(target=self._run, name="slam-loop-closing", daemon=True)
            self._thread.start()
        self._queue.put((kf_id, time.monotonic()))

    def _run(self) -> None:
        if self._solver is not None:
            try:
                self._solver.start()              # ready by the first optimisation, a few keyframes later
            except OSError:
                pass                              # the first optimisation tries again and reports it
        while True:
            kf_id, submitted = self._queue.get()
            try:
                if kf_id == STOP:
                    return
                if self.error is None:
                    self.process(kf_id)
                    self.latency_ms.append((time.monotonic() - submitted) * 1e3)
            except BaseException as exc:       # kept and re-raised in the tracking thread by check()
                self.error = exc
            finally:
                self._queue.task_done()

    @property
    def backlog(self) -> int:
        """Keyframes waiting (not yet being processed)."""
        return self._queue.qsize()

    @property
    def busy(self) -> bool:
        """Keyframes are waiting or being processed."""
        return self._queue.unfinished_tasks > 0

    def check(self) -> None:
        """Re-raise in the caller's thread an error the background thread met."""
        if self.error is not None:
            raise RuntimeError(f"SLAM loop closing failed: {self.error}") from self.error

    def wait_idle(self, timeout_s: float | None = None) -> bool:
        """Wait until every submitted keyframe is processed (at most ``timeout_s`` [s]; None: no
        limit). True when idle. On a long walk through new places the backlog can be minutes long."""
        if self._thread is not None:
            if timeout_s is None:
                self._queue.join()
            else:
                deadline = time.monotonic() + timeout_s
                while self.busy and time.monotonic() < deadline:
                    time.sleep(0.02)
        self.check()
        return not self.busy

    def stop(self) -> None:
        """Stop the thread after the keyframe in hand; keyframes still waiting are dropped from loop
        closing (they stay in the map, as tracking placed them), so stopping never waits for a backlog."""
        if self._thread is not None:
            while True:
                try:
                    self._queue.get_nowait()
                except queue.Empty:
                    break
                self._queue.task_done()
            self._queue.put((STOP, 0.0))
            self._thread.join()
            self._thread = None
        if self._solver is not None:
            self._solver.close()

    # -- one keyframe -------------------------------------------------------------------------
    def process(self, kf_id: int) -> None:
        t0 = time.perf_counter()
        c = self.config
        m = self.map
        kf = m.keyframes[kf_id]
        m.places.add(kf_id, kf.features.descriptors)
        pose = m.pose(kf_id)
        parent = m.parent.get(kf_id)
        segment = m.segment_of(kf_id)
        new_loop = False
        added = 0
        reaching = []                             # new covisibility edges, for the whole-graph test
        near = [k for k in m.covisible(pose, c.covisible_overlap, exclude={kf_id, parent}, segment=segment)
                if k < kf_id]                     # the ones made after it link to it themselves (at any lag)
        for other in near[:c.covisible_keyframes]:
            guess = inverse(m.pose(other)) @ pose
            edge = self._verify(kf_id, other, guess, c.min_inliers, "covisibility")
            if edge is not None:
                m.add_edge(edge)
                added += 1
                self.covisibility_edges += 1
                reaching.append(edge)
        segments = m.segments()
        own = set(segments.get(segment, ()))
        recent = {k for k in m.keyframes if k > kf_id - c.loop_exclude_recent}
        tried = set(near[:c.covisible_keyframes]) | recent | {kf_id} | (set(m.keyframes) - own)
        for other, _score in m.places.query(kf.features.descriptors, c.loop_candidates, exclude=tried):
            if m.connected(kf_id, other):
                continue
            edge = self._verify(kf_id, other, None, c.loop_min_inliers, "loop")
            if edge is not None:
                m.add_edge(edge)
                added += 1
                self.loop_edges += 1
                new_loop = True
        if len(segments) > 1 and self._merge(kf_id, segment, own):
            segment = m.segment_of(kf_id)
            added += 1
            new_loop = True
        if added:
            self.optimise_after(kf_id, new_loop, reaching)
        self.busy_ms.append((time.perf_counter() - t0) * 1e3)

    def optimise_after(self, kf_id: int, new_loop: bool, new_edges: list[Edge]) -> int:
        """Optimise the pose graph after keyframe ``kf_id`` got edges (``new_loop``: a loop edge or
        a merge among them; ``new_edges``: its new covisibility edges): the whole sub-map or its
        local window (module docstring). Returns the keyframes the optimisation could move."""
        c = self.config
        m = self.map
        members = set(m.segments().get(m.segment_of(kf_id), ())) - set(m.transient)
        window = set(sorted(k for k in members if k <= kf_id)[-c.local_window_keyframes:])
        with m.lock:
            edges = list(m.edges)
        if new_loop or any(self._disagrees(e) for e in new_edges if e.a not in window):
            poses = {k: p for k, p in m.poses().items() if k in members}
            held = {min(poses)}
            self.whole_graph_optimisations += 1
            self.whole_graph_for_loops += bool(new_loop)
        else:
            # keyframes made after this one (a lagging thread) follow their parents (apply_correction):
            # held, they became the gauge and the map's first keyframe moved (2.5 cm on the pan)
            edges = [e for e in edges if (e.a in window or e.b in window) and max(e.a, e.b) <= kf_id]
            held = (({e.a for e in edges} | {e.b for e in edges}) - window) & members or {min(window)}
            poses = {k: m.pose(k) for k in window | held}
        optimised, outliers = optimise(poses, edges, c, solver=self._solver, held=held)
        m.remove_edges(outliers)
        self.rejected.extend(outliers)
        new_loop = new_loop and any(e.kind == "loop" and e.b == kf_id for e in edges if e not in outliers)
        moved = max(pose_distance(poses[k], optimised[k])[0] for k in optimised)
        m.apply_correction(optimised, closed_loop=new_loop and moved > 1e-3)
        self.optimisations += 1
        return len(poses) - len(held)

    def _disagrees(self, edge: Edge) -> bool:
        """The map's poses disagree with a new edge by more than ``whole_graph_sigmas`` of its noise
        (translation or rotation): closing it must move more than the local window."""
        c = self.config
        dt, dr = pose_distance(self.map.pose(edge.a) @ edge.a_from_b, self.map.pose(edge.b))
        return dt > c.whole_graph_sigmas * c.edge_sigma_translation or dr > c.whole_graph_sigmas * c.edge_sigma_rotation_deg

    def _merge(self, kf_id: int, segment: int, own: set[int]) -> bool:
        """Look for the keyframe's place in the other sub-maps; when one is verified, merge the
        younger sub-map into the older (the older's frame stays). True when merged."""
        c = self.config
        m = self.map
        kf = m.keyframes[kf_id]
        best = None
        for other, _score in m.places.query(kf.features.descriptors, c.loop_candidates, exclude=own | set(m.transient)):
            edge, inliers = self._verified(kf_id, other, None, c.relocalise_min_inliers, "loop")
            if edge is not None and (best is None or inliers > best[1]):
                best = (edge, inliers)
        if best is None:
            return False
        edge = best[0]
        other_segment = m.segment_of(edge.a)
        # S_other ← S_this from the edge: (S_other ← A)(A ← K)(S_this ← K)⁻¹
        other_from_this = m.pose(edge.a) @ edge.a_from_b @ inverse(m.pose(kf_id))
        keep, drop = min(segment, other_segment), max(segment, other_segment)
        keep_from_drop = other_from_this if keep == other_segment else inverse(other_from_this)
        m.merge_segments(keep, drop, keep_from_drop)
        m.add_edge(edge)
        self.merges += 1
        self.loop_edges += 1
        return True

    def _verify(self, kf_id: int, other: int, guess: np.ndarray | None, min_inliers: int, kind: str) -> Edge | None:
        """An edge other ← kf when the two keyframes register (PnP + dense), else None."""
        return self._verified(kf_id, other, guess, min_inliers, kind)[0]

    def _verified(self, kf_id: int, other: int, guess: np.ndarray | None, min_inliers: int,
                  kind: str) -> tuple[Edge | None, int]:
        """(:meth:`_verify`'s edge, its PnP inliers)."""
        m = self.map
        frame = lambda k: m.frame(k, self.preparer.keyframe_frame)    # noqa: E731
        reg = self.registrar.register(frame(kf_id), frame(other), min_inliers=min_inliers,
                                      predicted_target_from_source=guess)
        if not reg.ok or reg.method == "pnp" or (kind == "loop" and reg.inliers < min_inliers):
            return None, 0
        return Edge(other, kf_id, reg.target_from_source, kind), reg.inliers
