"""A virtual patient walking a task in one process, from the cores (no rclpy, no graph): the
simulator core renders, the phosphene simulator core turns the frame into brightness with the
spv node's parameters, the policy answers — the loop a lockstep session closes through ROS,
for developing policies and testing them in seconds. With the ``path`` overlay the planner
node's core (:class:`raspv_nav.assistant.NavigationAssistant`: the building's structure, obstacles
from each depth frame, a replan every ``replan_s``) draws the path, as in the graph. Modes that need the scene node's output (scene
perception) are not run here: those run in sessions and sweeps.

    result = quick_trial("experiments/worlds/hallway.yaml", (1.0, 1.5, 0.0), (8.6, 1.5, 0.8), 40.0,
                         spv={"device": "argus_ii", "mode": "depth", "temporal": False, "max_depth": 3.0})
"""
from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Any, Callable

import numpy as np

from raspv_experiments.policies import PhospheneLayout, PolicyConfig, make_policy


@dataclass
class QuickResult:
    success: bool
    time_s: float
    collisions: int
    path: list[tuple[float, float]] = field(default_factory=list)
    phosphenes: int = 0                   # phosphenes of the map shown (the layout's count, not the requested one)


def quick_trial(world: str, start: tuple[float, float, float], goal: tuple[float, float, float], time_limit: float,
                spv: dict[str, Any], policy: str | Callable[..., Any] = "navigate", config: PolicyConfig | None = None,
                rate: float = 10.0, size: tuple[int, int] = (160, 120), replan_s: float = 0.5,
                planner: dict[str, Any] | None = None, policy_kw: dict[str, Any] | None = None,
                on_frame: Callable[[Any], None] | None = None, other_representation: bool = False,
                goal_knowledge=None, sim_params: dict[str, Any] | None = None) -> QuickResult:
    """Walk from ``start`` (x, y [m], yaw [rad]) to the region ``goal`` (x, y, radius [m]) within
    ``time_limit`` s of sim time, seeing the phosphenes of the spv node parameters ``spv``.
    ``policy`` is a policy name or a callable (layout, config, goal=…) → Policy; ``policy_kw`` go to its constructor (e.g. ``model`` of ``learned``); ``on_frame``
    gets the simulation before each decision (demonstrations: the expert's ground truth). A
    ``learned`` patient shown another representation than it was trained on is refused
    (:class:`~raspv_experiments.learned_policy.LearnedModelError`, one line naming both) unless
    ``other_representation``. ``goal_knowledge`` (a protocol's
    :class:`~raspv_experiments.goal_knowledge.GoalKnowledge`; None: exact) is what the patient is
    told of the goal, its error drawn from ``config.seed`` as the graph's runner draws it.
    ``sim_params`` (the sim node's parameters of the protocol's graph): with ``depth_noise`` the
    depth is degraded like a real sensor's (noise, quantisation, holes), as the sim node does."""
    from raspv_bringup.registry import schema_for
    from raspv_sim.avatar import head_quaternion
    from raspv_sim.simulator import SimConfig, Simulation
    from raspv_sim.world_spec import GoalSpec
    from raspv_spv.frame_inputs import FrameInputs
    from raspv_spv.spv_node_rebuild import build_simulator

    params = {**schema_for("spv").defaults(), **spv}
    sim_p = {**schema_for("sim").defaults(), **(sim_params or {})}
    if policy == "learned" and not other_representation:
        from raspv_experiments.learned_policy import LearnedModelError, representation_mismatch

        mismatch = representation_mismatch((policy_kw or {}).get("model", ""), spv)
        if mismatch:
            raise LearnedModelError(mismatch)
    spv_sim = build_simulator(params)
    m = spv_sim.map
    layout = PhospheneLayout(m.centres[:, 0].astype(float), m.centres[:, 1].astype(float), spv_sim.config.width,
                             spv_sim.config.height, float(m.focal_px))
    config = config or PolicyConfig()
    x0, y0, yaw = start
    dx, dy = goal[0] - x0, goal[1] - y0
    told = (math.cos(yaw) * dx + math.sin(yaw) * dy, -math.sin(yaw) * dx + math.cos(yaw) * dy)
    if goal_knowledge is not None:
        from raspv_experiments.goal_knowledge import told_goal

        told = told_goal(told, goal_knowledge, config.seed)
    build = policy if callable(policy) else (lambda *a, **kw: make_policy(policy, *a, **kw))
    agent = build(layout, config, goal=told, **(policy_kw or {}))
    agent.show(params["mode"], params["overlays"])
    assistant = None
    if "path" in params["overlays"]:       # the planner node's core, as the planner node runs it
        from raspv_nav.assistant import NavigationAssistant, assistant_config
        from raspv_experiments.world_geometry import world_geometry
        from raspv_nav.planner_params import PARAMS as PLANNER_PARAMS
        from raspv_sim.occupancy_export import world_occupancy

        with Simulation(world, SimConfig(width=16, height=12, renderer="tiny")) as building:
            structure = world_occupancy(building.world, 0.05, structure_only=True)
        target = world_geometry(world).reachable_point(np.asarray(goal[:2], float), goal[2])
        p = {q.name: q.default for q in PLANNER_PARAMS} | {"robot_radius": 0.2, **(planner or {})}
        assistant = NavigationAssistant(structure, goal[:2] if target is None else target, assistant_config(p))
    extras: dict[str, Any] = {}
    planned = -float("inf")
    from raspv_sim.depth_sensor import sensor_config_from_params

    sim_config = SimConfig(width=size[0], height=size[1], renderer="tiny",
                           depth_sensor=sensor_config_from_params(sim_p), seed=int(sim_p["seed"]))
    with Simulation(world, sim_config) as sim:
        sim.start_trial(x0, y0, yaw, (GoalSpec("goal", goal[:2], goal[2]),))
        sim.set_head(head_quaternion(0.0, math.radians(config.head_pitch_deg), 0.0))
        t0, command, path = sim.t, (0.0, 0.0), []
        while sim.t - t0 < time_limit - 1e-6:
            report = sim.step(1.0 / rate, *command)
            path.append((sim.avatar.x, sim.avatar.y))
            if "goal" in report.goals_reached:
                return QuickResult(True, sim.t - t0, sim.monitor.count, path, len(m.centres))
            if report.collisions:
                agent.touch()
            frame = sim.render(labels=False)
            if assistant is not None:
                assistant.set_subject(sim.t, sim.avatar.x, sim.avatar.y, sim.avatar.yaw)
                assistant.add_depth(frame.depth, frame.intrinsics, frame.world_from_camera, sim.t)
                if sim.t - planned >= replan_s - 1e-6:
                    planned = sim.t
                    status = assistant.replan()
                    extras = {"nav_path": status.path} if status.path is not None else {}
            inputs = FrameInputs(color=frame.rgb, depth=frame.depth, camera=frame.intrinsics, stamp=sim.t,
                                 camera_pose=frame.world_from_camera, extras=dict(extras))
            b = spv_sim.brightness(spv_sim.levels(inputs), max(1, round(params["rate"] / rate)))
            if on_frame is not None:
                on_frame(sim)
            c = agent.act(b, sim.t)
            command = (c.linear, c.angular)
        return QuickResult(False, sim.t - t0, sim.monitor.count, path, len(m.centres))
