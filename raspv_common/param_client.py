"""Get, set and list another node's parameters through the standard rcl_interfaces services.

``ParamClient`` works from any node. Its ``*_async`` methods never block (use them inside
callbacks of a spinning node, e.g. the headset bridge); the blocking methods spin the given
node until the answer arrives (use them in command-line tools).
"""
from __future__ import annotations

from typing import Any, Callable

import rclpy
import yaml
from rcl_interfaces.msg import Parameter as ParameterMsg
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import DescribeParameters, GetParameters, ListParameters, SetParameters
from rclpy.node import Node


class ParamError(Exception):
    """The target node is unreachable or refused the request; ``str()`` says why."""


def value_from_msg(v: ParameterValue) -> Any:
    t = v.type
    return {
        ParameterType.PARAMETER_NOT_SET: None,
        ParameterType.PARAMETER_BOOL: v.bool_value,
        ParameterType.PARAMETER_INTEGER: v.integer_value,
        ParameterType.PARAMETER_DOUBLE: v.double_value,
        ParameterType.PARAMETER_STRING: v.string_value,
        ParameterType.PARAMETER_BYTE_ARRAY: list(v.byte_array_value),
        ParameterType.PARAMETER_BOOL_ARRAY: list(v.bool_array_value),
        ParameterType.PARAMETER_INTEGER_ARRAY: list(v.integer_array_value),
        ParameterType.PARAMETER_DOUBLE_ARRAY: list(v.double_array_value),
        ParameterType.PARAMETER_STRING_ARRAY: list(v.string_array_value),
    }[t]


def value_to_msg(value: Any, like: int | None = None) -> ParameterValue:
    """Python value → ParameterValue; ``like`` (a ParameterType of the current value) makes
    ints become doubles for double parameters and keeps strings as strings."""
    v = ParameterValue()
    if like == ParameterType.PARAMETER_DOUBLE and isinstance(value, int) and not isinstance(value, bool):
        value = float(value)
    if like == ParameterType.PARAMETER_DOUBLE_ARRAY and isinstance(value, list):
        value = [float(x) if isinstance(x, int) and not isinstance(x, bool) else x for x in value]
    if isinstance(value, bool):
        v.type, v.bool_value = ParameterType.PARAMETER_BOOL, value
    elif isinstance(value, int):
        v.type, v.integer_value = ParameterType.PARAMETER_INTEGER, value
    elif isinstance(value, float):
        v.type, v.double_value = ParameterType.PARAMETER_DOUBLE, value
    elif isinstance(value, str):
        v.type, v.string_value = ParameterType.PARAMETER_STRING, value
    elif isinstance(value, list):
        kinds = {type(x) for x in value}
        if kinds <= {bool} and value:
            v.type, v.bool_array_value = ParameterType.PARAMETER_BOOL_ARRAY, value
        elif kinds <= {int} and value:
            v.type, v.integer_array_value = ParameterType.PARAMETER_INTEGER_ARRAY, value
        elif kinds <= {float, int} and value:
            v.type, v.double_array_value = ParameterType.PARAMETER_DOUBLE_ARRAY, [float(x) for x in value]
        elif kinds <= {str}:
            v.type, v.string_array_value = ParameterType.PARAMETER_STRING_ARRAY, value
        else:
            raise ParamError(f"cannot send a list mixing {', '.join(sorted(k.__name__ for k in kinds))}")
    else:
        raise ParamError(f"cannot send a value of type {type(value).__name__}")
    return v


def parse_cli_value(text: str, like: int | None) -> Any:
    """A command-line value → Python: kept as text for string parameters, YAML otherwise."""
    if like == ParameterType.PARAMETER_STRING:
        return text
    try:
        return yaml.safe_load(text)
    except yaml.YAMLError:
        return text


class ParamClient:
    """Parameter services of the node ``target`` (e.g. ``"spv"`` or ``"/spv"``)."""

    def __init__(self, node: Node, target: str) -> None:
        self.node = node
        self.target = target if target.startswith("/") else "/" + target
        self._get = node.create_client(GetParameters, f"{self.target}/get_parameters")
        self._set = node.create_client(SetParameters, f"{self.target}/set_parameters")
        self._list = node.create_client(ListParameters, f"{self.target}/list_parameters")
        self._describe = node.create_client(DescribeParameters, f"{self.target}/describe_parameters")

    def destroy(self) -> None:
        for c in (self._get, self._set, self._list, self._describe):
            self.node.destroy_client(c)

    def is_ready(self) -> bool:
        """True once the target's get/set parameter services are discovered."""
        return self._get.service_is_ready() and self._set.service_is_ready()

    def ask_until_answered(self, ask: Callable[[Callable[[Any], None]], None], timeout_s: float,
                           retry_s: float = 5.0) -> tuple[bool, Any]:
        """Block until ``ask(done)`` — e.g. ``lambda done: client.set_async(values, done)`` —
        answers: (True, answer), or (False, why) after ``timeout_s``. Waits for the services
        first, then asks again every ``retry_s``: a fresh client's request can be served before
        the node's reply writer has matched its reader, and that answer is lost. Parameter
        requests are idempotent, so a second answer changes nothing (the first one is kept)."""
        import threading
        import time

        deadline = time.monotonic() + timeout_s
        while not self.is_ready():
            if time.monotonic() > deadline:
                return False, f"parameter services of {self.target} not available"
            time.sleep(0.05)
        done = threading.Event()
        answers: list[Any] = []
        while True:
            ask(lambda answer: (answers.append(answer), done.set()))
            if done.wait(min(retry_s, max(0.0, deadline - time.monotonic()))):
                return True, answers[0]
            if time.monotonic() >= deadline:
                return False, f"{self.target} did not answer a parameter request within {timeout_s:.0f} s"

    # -- non-blocking ---------------------------------------------------------------------
    def set_async(self, values: dict[str, Any], done: Callable[[list[tuple[str, bool, str]]], None] | None = None,
                  types: dict[str, int] | None = None) -> None:
        """Request ``values`` be set; ``done`` gets [(name, successful, reason)]."""
        if not self._set.service_is_ready():
            if done:
                done([(n, False, f"node {self.target} is not reachable") for n in values])
            return
        req = SetParameters.Request()
        req.parameters = [ParameterMsg(name=n, value=value_to_msg(v, (types or {}).get(n))) for n, v in values.items()]
        future = self._set.call_async(req)
        names = list(values)
        if done:
            future.add_done_callback(
                lambda f: done([(n, r.successful, r.reason) for n, r in zip(names, f.result().results)]))

    def list_async(self, done: Callable[[list[str] | None], None]) -> None:
        """``done`` gets the node's parameter names (sorted), or None when it is not reachable."""
        if not self._list.service_is_ready():
            done(None)
            return
        self._list.call_async(ListParameters.Request()).add_done_callback(
            lambda f: done(sorted(f.result().result.names) if f.result() is not None else None))

    def get_async(self, names: list[str], done: Callable[[dict[str, Any]], None]) -> None:
        """``done`` gets {name: value}, None for names the node does not have (or for every
        name when the node is not reachable)."""
        if not self._get.service_is_ready():
            done({n: None for n in names})
            return

        def answered(future) -> None:
            values = list(future.result().values) if future.result() is not None else []
            if len(values) == len(names):
                done({n: (None if v.type == ParameterType.PARAMETER_NOT_SET else value_from_msg(v))
                      for n, v in zip(names, values)})
            elif len(names) == 1:
                done({names[0]: None})
            else:  # one unknown name empties the whole answer: ask name by name
                merged: dict[str, Any] = {}

                def one(answer: dict[str, Any]) -> None:
                    merged.update(answer)
                    if len(merged) == len(names):
                        done(merged)
                for n in names:
                    self.get_async([n], one)
        self._get.call_async(GetParameters.Request(names=names)).add_done_callback(answered)

    # -- blocking (command-line tools) ------------------------------------------------------
    def _call(self, client, request, timeout_s: float):
        if not client.wait_for_service(timeout_sec=timeout_s):
            raise ParamError(f"node {self.target} is not running or not reachable (waited {timeout_s:.0f} s)")
        future = client.call_async(request)
        rclpy.spin_until_future_complete(self.node, future, timeout_sec=timeout_s)
        if not future.done() or future.result() is None:
            raise ParamError(f"node {self.target} did not answer within {timeout_s:.0f} s")
        return future.result()

    def list(self, timeout_s: float = 5.0) -> list[str]:
        return sorted(self._call(self._list, ListParameters.Request(), timeout_s).result.names)

    def get(self, names: list[str], timeout_s: float = 5.0) -> dict[str, tuple[int, Any]]:
        """name → (ParameterType, value); unknown names raise ParamError."""
        res = self._call(self._get, GetParameters.Request(names=names), timeout_s)
        values = list(res.values)
        if len(values) != len(names) or any(v.type == ParameterType.PARAMETER_NOT_SET for v in values):
            known = self.list(timeout_s)
            missing = [n for n in names if n not in known]
            raise ParamError(f"node {self.target} has no parameter {', '.join(repr(m) for m in missing)}; "
                             f"it has: {', '.join(known)}")
        return {n: (v.type, value_from_msg(v)) for n, v in zip(names, values)}

    def describe(self, names: list[str], timeout_s: float = 5.0) -> dict[str, Any]:
        res = self._call(self._describe, DescribeParameters.Request(names=names), timeout_s)
        return {n: d for n, d in zip(names, res.descriptors)}

    def set(self, name: str, value: Any, timeout_s: float = 5.0) -> tuple[bool, str]:
        """Set one parameter (type matched to the current value); (successful, reason)."""
        current_type, _ = self.get([name], timeout_s)[name]
        req = SetParameters.Request(parameters=[ParameterMsg(name=name, value=value_to_msg(value, current_type))])
        result = self._call(self._set, req, timeout_s).results[0]
        return result.successful, result.reason
