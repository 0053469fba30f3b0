"""What rclpy raises when a node is used while its context shuts down or after it was destroyed,
and the check that an error is that (nodes' thin wrappers; this module imports rclpy).

A handler that treats an error as shutdown catches :data:`SHUTDOWN_ERRORS` and re-raises unless
:func:`during_shutdown` says so: an rcl failure while the context is still ok (a wrong topic
name, a middleware error) then surfaces instead of silently driving, e.g., a dead/slow verdict.
Measured with rclpy (Jazzy): a call on a node or publisher of a shut-down context raises
``RCLError`` ("context is invalid"); on a destroyed node, publisher or subscription
``InvalidHandle`` ("destruction was requested"); ``spin`` of an executor whose context shuts
down ``ExternalShutdownException``.
"""
from __future__ import annotations

from rclpy._rclpy_pybind11 import InvalidHandle, RCLError
from rclpy.executors import ExternalShutdownException, ShutdownException

SHUTDOWN_ERRORS = (RCLError, InvalidHandle, ExternalShutdownException, ShutdownException)


def during_shutdown(exc: BaseException, context) -> bool:
    """Whether ``exc`` is what rclpy raises for a destroyed handle or a shut-down ``context``
    (an rclpy Context): an ``RCLError`` counts only once the context is no longer ok."""
    if isinstance(exc, (InvalidHandle, ExternalShutdownException, ShutdownException)):
        return True
    return isinstance(exc, RCLError) and not context.ok()
