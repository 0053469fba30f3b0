"""Running a session: the protocol's graph, and for each planned trial — set the condition's
parameters, put the avatar at the start, show the instructions and wait for the subject's
start, run until the goal, the time limit or an abort, then record (no rclpy here: the graph is
reached through :class:`raspv_experiments.runner_node.GraphClient`).

Humans walk in real time; scripted subjects run in **lockstep** (the simulator steps each time
the subject answered the last frame, in simulation time, as fast as the machine allows) and
**headless** (the spv node publishes each frame at once, no display loop, no headset bridge).

Scripted sessions in lockstep **repeat exactly**: the simulator holds between trials and on the
frame a trial ends (``lockstep_hold``), a planner answers every frame after its path is out
(``lockstep``), each condition runs in a graph started with its parameters (no background
rebuild racing the first frames: the graph restarts when the world or the condition changes),
and the subject starts each trial with a fresh policy seeded by its number and the trial. The
same protocol and subject give the same trial records.
"""
from __future__ import annotations

import copy
import math
import os
import signal
import subprocess
import sys
import threading
import time
from dataclasses import asdict, dataclass, field
from pathlib import Path
from typing import Any, Callable

from raspv_bringup.graph import Graph, NodeEntry
from raspv_bringup.supervisor import Supervisor, stop_with_parent
from raspv_common.shown_share import ShownFrame, shown_share
from raspv_experiments.design import PlannedTrial, plan_session, scripted_subject_id, subject_number, trial_seed
from raspv_experiments.gaze_metrics import trial_gaze_metrics
from raspv_experiments.goal_knowledge import told_goal
from raspv_experiments.metrics import trajectory_record, trial_metrics
from raspv_experiments.protocol import Protocol, Task, uses_gaze
from raspv_experiments.runner_node import GraphClient
from raspv_experiments.session import SessionError, SessionFolder, now_iso
from raspv_experiments.session_control import ClockWatch, ExperimenterControl, TrialMonitor, ViewState
from raspv_experiments.world_geometry import world_geometry

STALL_S = 60.0            # wall seconds the runner watched the simulation clock stand: the graph is stuck
START_TIMEOUT_S = 180.0   # wall seconds for a graph to come up
BAG_START_S = 60.0        # wall seconds for a trial's bag recorder to subscribe


@dataclass
class RunOptions:
    out: Path
    subject: str                      # e.g. S07, or scripted-follow_path-3
    policy: str | None = None         # scripted subject's policy (None: a person)
    number: int | None = None         # subject number (default: the digits of the id)
    resume: bool = False
    lockstep: bool | None = None      # default: on for scripted subjects
    headless: bool | None = None      # default: on for scripted subjects
    bag: bool | None = None           # default: the protocol's record.bag
    keys: bool = True                 # read the experimenter's keys from the terminal
    subject_params: dict[str, Any] = field(default_factory=dict)
    other_representation: bool = False  # a learned patient may see another representation than it was trained on
    stop: threading.Event = field(default_factory=threading.Event)   # set to stop between two polls

    @property
    def scripted(self) -> bool:
        return self.policy is not None

    @property
    def exact(self) -> bool:
        """Scripted in lockstep: the session repeats exactly (see the module docstring)."""
        return self.scripted and (self.lockstep is None or self.lockstep)


def parse_subject(text: str) -> tuple[str, str | None, int]:
    """``S07`` → (S07, None, 7); ``scripted:follow_path[:3]`` → (scripted-follow_path-3, follow_path, 3);
    ``scripted`` alone is the default virtual patient, ``scripted:navigate:1``."""
    from raspv_experiments.subject_params import DEFAULT_POLICY, POLICY_NAMES

    if text == "scripted":
        text = f"scripted:{DEFAULT_POLICY}"
    if text.startswith("scripted:"):
        parts = text.split(":")
        policy = parts[1] if len(parts) > 1 else ""
        if policy not in POLICY_NAMES:
            raise ValueError(f"--subject {text}: unknown policy {policy!r}; use scripted:POLICY[:N] with POLICY one of "
                             f"{', '.join(POLICY_NAMES)}")
        try:
            number = int(parts[2]) if len(parts) > 2 else 1
        except ValueError:
            raise ValueError(f"--subject {text}: N must be a number (the virtual subject), e.g. scripted:{policy}:3") from None
        if number < 1 or len(parts) > 3:
            raise ValueError(f"--subject {text}: expected scripted:POLICY[:N] with N >= 1")
        return scripted_subject_id(policy, number), policy, number
    if not text or any(c in text for c in "/\\ :"):
        raise ValueError(f"--subject {text!r}: use an id without spaces, slashes or colons, e.g. S07")
    return text, None, subject_number(text)


def session_graph(protocol: Protocol, world: str, options: RunOptions, seed: int,
                  condition: str | None = None) -> Graph:
    """The protocol's graph for one world, adapted to the subject: the task's world in the
    simulator (and the planner), no run log (trials log themselves), and for scripted subjects
    lockstep stepping, sim time everywhere, a headless spv node, no headset bridge, and the
    subject node with its ability (:mod:`raspv_experiments.subject_ability`). With
    ``condition`` (scripted, lockstep) the condition's parameters are the nodes' own and the
    simulator holds between trials, the planner answering every frame and the scene node taking
    each frame with the camera pose of its stamp."""
    from raspv_experiments.subject_ability import subject_ability

    g = copy.deepcopy(protocol.graph)
    lockstep = options.scripted if options.lockstep is None else options.lockstep
    headless = options.scripted if options.headless is None else options.headless
    exact = lockstep and options.scripted and any(n.kind == "spv" for n in g.nodes)
    baked = protocol.trial_params(condition) if condition is not None else {}
    planners = [n.name for n in g.nodes if n.kind == "planner"]
    nodes: list[NodeEntry] = []
    for n in g.nodes:
        if headless and n.kind == "bridge":
            continue
        n.params.update(baked.get(n.name, {}))
        if n.kind == "sim":
            n.params.update(world=world, log_dir="", log_rate=protocol.record.trajectory_rate)
            if lockstep:
                n.params["step_mode"] = "lockstep"
            if exact:
                n.params["lockstep_hold"] = True
                if planners:
                    n.params["lockstep_participants"] = planners
        elif lockstep:
            n.params["use_sim_time"] = True
        if n.kind == "planner":
            if not n.params.get("map"):
                n.params["world"] = world
            if exact:
                n.params["lockstep"] = True
        if n.kind == "scene" and exact:
            n.params["lockstep"] = True         # each depth frame with the camera pose of its stamp
        if n.kind == "spv" and headless:
            n.params["headless"] = True
        nodes.append(n)
    if not any(n.kind == "sim" for n in nodes):
        raise SessionError(f"{protocol.path}: graph: experiments need a 'sim' node (trials reset the virtual world)")
    if options.scripted:
        if not any(n.kind == "spv" for n in nodes):
            raise SessionError(f"{protocol.path}: graph: a scripted subject needs an 'spv' node (it sees /spv/frame)")
        # its eyes move (scripted gaze) when the spv node uses the gaze in any condition
        eyes = {"gaze": "model"} if uses_gaze(protocol) else {}
        params = {**subject_ability(seed), "policy": options.policy, "seed": seed, **eyes, **options.subject_params}
        if lockstep:
            params["use_sim_time"] = True
        nodes.append(NodeEntry("subject", "subject", False, params))
    g.nodes = nodes
    return g


def learned_mismatch(protocol: Protocol, options: RunOptions) -> str | None:
    """The first condition whose phosphenes a ``learned`` subject was not trained on, as one
    line naming both representations (None: every condition is its training representation)."""
    if options.policy != "learned":
        return None
    from raspv_experiments.learned_policy import representation_mismatch

    for c in protocol.conditions:
        for n in (n for n in protocol.graph.nodes if n.kind == "spv"):
            spv = {**n.params, **protocol.trial_params(c.name).get(n.name, {})}
            mismatch = representation_mismatch(options.subject_params.get("model", ""), spv)
            if mismatch:
                return f"{protocol.path}: condition {c.name}: {mismatch}"
    return None


def _world_groups(protocol: Protocol, trials: list[PlannedTrial],
                  by_condition: bool = False) -> list[tuple[str, str | None, list[PlannedTrial]]]:
    """Consecutive trials in the same world (and condition, ``by_condition``): the graph restarts
    between groups. (world, condition or None, trials) each."""
    groups: list[tuple[str, str | None, list[PlannedTrial]]] = []
    for t in trials:
        key = (protocol.task(t.task).world, t.condition if by_condition else None)
        if groups and groups[-1][:2] == key:
            groups[-1][2].append(t)
        else:
            groups.append((*key, [t]))
    return groups


class SessionRunner:
    """Runs (or resumes) one subject's session; ``view`` shows progress (a TerminalView)."""

    def __init__(self, protocol: Protocol, options: RunOptions, view, say: Callable[[str], None] | None = None) -> None:
        self.protocol = protocol
        self.options = options
        self.view = view
        self.say = say or view.say
        self.control = ExperimenterControl()
        self.state = ViewState()
        self.subject = options.subject
        self.number = options.number if options.number is not None else subject_number(self.subject)
        self.folder = SessionFolder.for_subject(options.out, protocol, self.subject)
        self.plan = plan_session(protocol, self.subject)
        self.client: GraphClient | None = None
        self.supervisor: Supervisor | None = None
        self._sup_thread: threading.Thread | None = None
        self._graph_log = None

    # -- session ----------------------------------------------------------------------------
    def prepare(self) -> list[PlannedTrial]:
        """Create the session folder, or check it for --resume; returns the trials still to run."""
        f = self.folder
        if f.exists():
            if not self.options.resume:
                done = len(f.done())
                raise SessionError(f"{f.root} already holds this subject's session ({done} of {len(self.plan)} trials "
                                   "done): add --resume to continue it, or use another --out or subject id")
            f.check_resumable(self.protocol, self.subject)
            done = f.done()
            todo = [t for t in self.plan if t.index not in done]
            f.event("resumed", next_trial=todo[0].index if todo else None, done=len(done))
            self.say(f"resuming {f.root}: {len(done)} of {len(self.plan)} trials done"
                     + (f", next: trial {todo[0].index} ({todo[0].label})" if todo else ""))
            return todo
        if self.options.resume:
            raise SessionError(f"--resume: there is no session to resume in {f.root} (no session.json); "
                               "run without --resume to start it")
        f.create(self.protocol, self.subject, self.plan,
                 {"subject_kind": "scripted" if self.options.scripted else "person", "policy": self.options.policy,
                  "subject_params": self.options.subject_params, "argv": sys.argv,
                  **({"other_representation": True} if self.options.other_representation else {})})
        f.event("started", trials=len(self.plan))
        return list(self.plan)

    def run(self) -> int:
        mismatch = learned_mismatch(self.protocol, self.options)
        if mismatch and not self.options.other_representation:
            raise SessionError(mismatch)
        todo = self.prepare()
        self.state.total = len(self.plan)
        self.state.done = self.state.done_before = len(self.plan) - len(todo)
        self.state.started = time.monotonic()
        if not todo:
            self.say(f"session complete: {self.folder.trials_path}")
            return 0
        current: PlannedTrial | None = None
        try:
            for world, condition, trials in _world_groups(self.protocol, todo, self.options.exact):
                self._start_graph(world, condition)
                try:
                    for trial in trials:
                        current = trial
                        if self._run_planned(trial) == "quit":
                            self.folder.event("quit", at_trial=trial.index)
                            self.say(f"stopped at trial {trial.index}; continue with --resume")
                            self.show(phase="stopped")
                            return 3
                finally:
                    self._stop_graph()
        except KeyboardInterrupt:          # SIGINT/SIGTERM: recorded as a quit, resumable
            self.folder.event("quit", at_trial=current.index if current else None, by="signal")
            self.show(phase="stopped", message="interrupted; continue with --resume")
            raise
        self.show(phase="finished")
        self.folder.event("finished")
        self.say(f"session complete: {len(self.plan)} trials in {self.folder.trials_path}")
        return 0

    def show(self, **changes: Any) -> None:
        for k, v in changes.items():
            setattr(self.state, k, v)
        self.state.message = self.control.message
        self.view.show(self.state)

    # -- graph ------------------------------------------------------------------------------
    def _start_graph(self, world: str, condition: str | None = None) -> None:
        graph = session_graph(self.protocol, world, self.options, self.number, condition)
        self.folder.root.mkdir(parents=True, exist_ok=True)
        self._graph_log = open(self.folder.root / "graph.log", "a", buffering=1)
        self._graph_log.write(f"--- {now_iso()}: graph for world {world}"
                              + (f", condition {condition}" if condition else "") + "\n")
        self.supervisor = Supervisor(graph, out=self._graph_log)
        self.supervisor.start()             # main thread: the nodes die with this process
        self._sup_thread = threading.Thread(target=self.supervisor.run, args=(lambda: not self.options.stop.is_set(),),
                                            daemon=True, name="graph-supervisor")
        self._sup_thread.start()
        self.show(phase="starting", message="")
        if self.client is None:
            self.client = GraphClient()
        controlled = [n for n in self.protocol.controlled if any(e.name == n for e in graph.nodes)]
        self.client.wait_ready(controlled, START_TIMEOUT_S, alive=self._sup_thread.is_alive)
        if self.options.exact:            # every frame of the first trial must reach every node
            from raspv_common import topics

            planners = sum(1 for n in graph.nodes if n.kind == "planner")
            self.client.wait_connected({topics.SPV_FRAME: (1, 2 + planners), topics.SPV_MAP: (1, 2),
                                        topics.SIM_LOCKSTEP: (1 + planners, 1), topics.HEAD_ORIENTATION: (1, 1),
                                        topics.EXPERIMENT_INSTRUCTIONS: (1, 1)},
                                       START_TIMEOUT_S, alive=self._sup_thread.is_alive)

    def _stop_graph(self) -> None:
        if self.supervisor is not None:
            self.supervisor.request_stop()
            if self._sup_thread is not None:
                self._sup_thread.join(timeout=30.0)
            self.supervisor = None
        if self.client is not None:
            self.client.close()
            self.client = None
        if self._graph_log is not None:
            self._graph_log.close()
            self._graph_log = None

    def _check_graph(self) -> None:
        if self._sup_thread is not None and not self._sup_thread.is_alive() and not self.options.stop.is_set():
            raise SessionError(f"a node of the graph ended; see {self.folder.root / 'graph.log'}")
        if self.options.stop.is_set():
            raise KeyboardInterrupt

    # -- one trial --------------------------------------------------------------------------
    def _run_planned(self, trial: PlannedTrial) -> str:
        """Run ``trial`` until it is completed or skipped (repeating when asked); "quit" to stop."""
        while True:
            status = self._run_attempt(trial)
            if status in ("completed", "skipped"):
                self.state.done += 1
                return status
            if status == "quit":
                return "quit"

    def _apply_condition(self, trial: PlannedTrial, task: Task) -> dict[str, dict[str, Any]]:
        """Set the condition's parameters (scripted in lockstep: the graph started with them) and
        point the planners at the goal; returns every parameter of the trial."""
        params = self.protocol.trial_params(trial.condition)
        to_set = {} if self.options.exact else copy.deepcopy(params)
        planners = [n.name for n in self.protocol.graph.nodes if n.kind == "planner"]
        if planners:        # the planner guides to where the body can stand in the goal region
            import numpy as np

            g = np.array([task.goal.x, task.goal.y])
            target = world_geometry(task.world).reachable_point(g, task.goal.radius)
            target = g if target is None else target
            goal = {"goal": [float(target[0]), float(target[1])], "goal_name": ""}
            for name in planners:
                params.setdefault(name, {}).update(goal)
                to_set.setdefault(name, {}).update(goal)
        for node, values in to_set.items():
            self.client.set_params(node, values)
        return params

    def _wait_start(self, info: dict[str, Any]) -> bool:
        """Show instructions until the subject (headset or scripted) or the experimenter (Enter)
        starts; False if the experimenter quit meanwhile."""
        self.client.take_responses()
        self.client.show({**info, "waiting": True})
        self.control.take_start()
        while True:
            self._check_graph()
            if any(r.get("action") == "start" and str(r.get("id", info["id"])) == info["id"]
                   for r in self.client.take_responses()) or self.control.take_start():
                return True
            if self.control.request == "quit":
                return False
            self.show()
            time.sleep(0.02)

    def _run_attempt(self, trial: PlannedTrial) -> str:
        task = self.protocol.task(trial.task)
        self.show(index=trial.index, label=trial.label, phase="instructions", elapsed=0.0,
                  time_limit=task.time_limit, collisions=0, last_hit="")
        params = self._apply_condition(trial, task)
        goal = (f"task:{task.goal.label}", task.goal.x, task.goal.y, task.goal.radius)
        yaw = math.radians(task.start_yaw_deg)
        self.client.start_trial(task.start_x, task.start_y, yaw, goal)          # stand at the start meanwhile
        run_name, attempt = self.folder.attempt_dir(trial)
        key = f"{self.subject}-{trial.index}-{attempt}"
        if trial.break_before and attempt == 1:
            self.show(phase="break")
            if not self._wait_start({"id": key + "-break", "trial": trial.index, "title": "Break",
                                     "text": "Take a break. Start the next block when you are ready."}):
                return "quit"
        self.show(phase="instructions")
        title = f"Trial {trial.index} of {len(self.plan)}" + (" (practice)" if trial.practice else "")
        info = {"id": key, "trial": trial.index, "title": title,
                "text": task.instructions or f"Reach the goal ({task.goal.label})."}
        if self.options.scripted:      # what the subject is told, and the frames of this trial come after
            dx, dy = task.goal.x - task.start_x, task.goal.y - task.start_y
            told = told_goal((math.cos(yaw) * dx + math.sin(yaw) * dy, -math.sin(yaw) * dx + math.cos(yaw) * dy),
                             self.protocol.goal_knowledge, trial_seed(self.number, trial.index))
            if told is not None:       # goal_knowledge none: nothing said (the subject explores)
                info["goal_from_start"] = [float(told[0]), float(told[1])]     # exact, as quick_trial tells it
            info["after"] = self.client.state()[0] or 0.0
        if not self._wait_start(info):
            return "quit"
        self.client.take_frames()
        bag = None
        if self.options.exact:          # lockstep trials are over in seconds: the recorder listens first
            bag = self._start_bag(self.folder.root / "trials" / run_name)
        res = self.client.start_trial(task.start_x, task.start_y, yaw, goal,
                                      str(self.folder.root / "trials"), run_name, time_limit=task.time_limit)
        self.client.show({"id": key, "trial": trial.index, "title": title, "text": "", "waiting": False})
        run_dir, start_t = Path(res.run_dir), float(res.sim_time)
        if not self.options.exact:
            bag = self._start_bag(run_dir)
        monitor = TrialMonitor(task.goal.x, task.goal.y, task.goal.radius, task.time_limit, start_t, start_t,
                               task.start_x, task.start_y)
        request = self._monitor(monitor)
        if self.options.exact and request is None:      # the trial's last frame reaches the display record too
            self.client.wait_frame(min(monitor.t, start_t + task.time_limit))
        self._stop_bag(bag)
        self.client.end_trial(plot=False)
        frames = self.client.take_frames()
        end_t = min(monitor.t, start_t + task.time_limit)      # when it ended (the sim may have stepped on)
        if self.control.paused:
            self.control.paused = False
            self.client.set_params("sim", {"paused": False})
        status = {None: "completed", "repeat": "repeated", "skip": "skipped", "quit": "interrupted"}[request]
        record = self._record(trial, task, params, status, attempt, run_dir, start_t, end_t, monitor)
        record["display"] = self._display_record(trial, frames, start_t, end_t)
        self.folder.record(record)
        if status != "completed":
            self.folder.event(status, trial=trial.index, attempt=attempt)
        m = record.get("metrics", {})
        self.say(f"trial {trial.index} ({trial.label}): {status}"
                 + (f", {m.get('outcome')} in {m.get('completion_time_s', 0):.1f} s, {m.get('collisions', 0)} collisions"
                    if status == "completed" else ""))
        return "quit" if request == "quit" else status

    def _monitor(self, monitor: TrialMonitor) -> str | None:
        """Poll until the trial ends; returns the experimenter's request (repeat/skip/quit) or None."""
        paused = False
        watch = ClockWatch(STALL_S)
        while True:
            self._check_graph()
            t, pose, _ = self.client.state()
            if self.control.paused != paused:
                paused = self.control.paused
                self.client.set_params("sim", {"paused": paused})
                self.show(phase="paused" if paused else "running")
            if paused:
                watch.reset()
            elif watch.update(t, time.monotonic()):
                raise SessionError(f"the simulation clock did not advance for {STALL_S:.0f} s (the graph is stuck or "
                                   f"starved of CPU); see {self.folder.root / 'graph.log'}; the trial is not "
                                   "recorded: --resume runs it again")
            for c in self.client.take_collisions():
                monitor.collision(f"{c['class']}:{c['name']}")
            if any(r.get("action") == "abort" for r in self.client.take_responses()):
                monitor.abort()
            request = self.control.take_request()
            if request is not None:
                return request
            outcome = monitor.update(t, *(pose if pose else (None, None)))
            self.show(phase="paused" if paused else "running", elapsed=monitor.elapsed,
                      collisions=len(monitor.collisions), last_hit=monitor.collisions[-1] if monitor.collisions else "")
            if outcome is not None:
                return None
            time.sleep(0.01)

    def _record(self, trial: PlannedTrial, task: Task, params: dict, status: str, attempt: int, run_dir: Path,
                start_t: float, end_t: float, monitor: TrialMonitor) -> dict[str, Any]:
        record: dict[str, Any] = {
            "protocol": self.protocol.name, "subject": self.subject, "session": str(self.folder.root),
            **asdict(trial), "attempt": attempt, "status": status, "world": task.world,
            "start": [task.start_x, task.start_y, task.start_yaw_deg],
            "goal": {"x": task.goal.x, "y": task.goal.y, "radius": task.goal.radius, "label": task.goal.label},
            "time_limit_s": task.time_limit, "params": params, "run_dir": str(run_dir),
            "sim_start_s": round(start_t, 4), "sim_end_s": round(end_t, 4), "finished": now_iso(),
            "policy": self.options.policy}
        if self.options.scripted and self.protocol.goal_knowledge.told != "exact":
            record["goal_knowledge"] = self.protocol.goal_knowledge.told     # what the virtual patient was told
        if self.options.other_representation and self.options.policy == "learned":
            record["other_representation"] = True        # run outside its training representation, as told
        factors = self.protocol.condition(trial.condition).factors
        if factors:
            record["factors"] = dict(factors)
        if status == "completed":
            geometry = world_geometry(task.world)
            _, shortest = geometry.shortest_path((task.start_x, task.start_y), (task.goal.x, task.goal.y), task.goal.radius)
            metrics = trial_metrics(run_dir, start_t, end_t, monitor.outcome == "aborted", task.time_limit,
                                    f"task:{task.goal.label}", shortest, geometry)
            record["metrics"] = metrics.as_dict()
            record["trajectory"] = trajectory_record(run_dir, start_t, end_t)
            gaze = trial_gaze_metrics(run_dir, start_t, end_t)     # when the trial logged eye gaze
            if gaze is not None:
                record["gaze"] = gaze.as_dict()
        if self.options.bag if self.options.bag is not None else self.protocol.record.bag:
            record["bag"] = str(run_dir / "bag")
        return record

    def _display_record(self, trial: PlannedTrial, frames: list[ShownFrame], start_t: float,
                        end_t: float) -> dict[str, Any]:
        """What the subject was shown during the trial: the phosphenes of the map on display, and
        the share of frames in the condition's own mode and overlays (:mod:`raspv_common.shown_share`)."""
        if self.options.exact:                   # sim-time stamps: exactly the trial's frames
            frames = [f for f in frames if start_t + 1e-6 < f.t <= end_t + 1e-6]
        spv = next((n for n in self.protocol.graph.nodes if n.kind == "spv"), None)
        own_mode = own_overlays = None
        if spv is not None:
            from raspv_bringup.registry import schema_for

            defaults = schema_for("spv").defaults()
            chosen = self.protocol.condition(trial.condition).params.get(spv.name, {})
            own_mode = chosen.get("mode", spv.params.get("mode", defaults["mode"]))
            own_overlays = chosen.get("overlays", spv.params.get("overlays", defaults["overlays"]))
        share = shown_share(frames, own_mode, own_overlays, end_t=None)
        out: dict[str, Any] = {**self.client.display_map(), **share.as_dict()}
        return out

    # -- bags -------------------------------------------------------------------------------
    def _start_bag(self, run_dir: Path) -> subprocess.Popen | None:
        if not (self.options.bag if self.options.bag is not None else self.protocol.record.bag):
            return None
        cmd = [sys.executable, "-m", "raspv_bringup.cli", "bag", "record", "-o", str(run_dir / "bag"),
               *self.protocol.record.bag_topics]
        run_dir.mkdir(parents=True, exist_ok=True)
        log = open(run_dir / "bag.log", "w")
        topics = [t for t in self.protocol.record.bag_topics if self.client.node.count_publishers(t)]
        before = {t: self.client.node.count_subscribers(t) for t in topics}
        proc = subprocess.Popen(cmd, stdout=log, stderr=subprocess.STDOUT, stdin=subprocess.DEVNULL,
                                env=os.environ.copy(), start_new_session=True, preexec_fn=stop_with_parent)
        # (not the nodes' _die_with_parent: it leaves SIGINT blocked for node_entry to unblock, and the
        # recorder never does — _stop_bag's SIGINT stayed pending until its 20 s kill, bag unfinished)
        # every topic that has a publisher gets the recorder's subscription before the trial starts
        deadline = time.monotonic() + BAG_START_S
        while any(self.client.node.count_subscribers(t) <= n for t, n in before.items()):
            if proc.poll() is not None or time.monotonic() > deadline:
                self.say(f"the bag recorder did not subscribe within {BAG_START_S:.0f} s; see {run_dir / 'bag.log'}")
                break
            time.sleep(0.05)
        time.sleep(0.3)                 # its subscriptions matched on the publishers' side too
        return proc

    @staticmethod
    def _stop_bag(proc: subprocess.Popen | None) -> None:
        if proc is None:
            return
        proc.send_signal(signal.SIGINT)
        try:
            proc.wait(timeout=20)
        except subprocess.TimeoutExpired:
            proc.kill()
            proc.wait()

    def close(self) -> None:
        self._stop_graph()
