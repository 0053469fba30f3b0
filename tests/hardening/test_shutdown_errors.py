"""Handlers that take an error for shutdown catch only what rclpy raises then, and only while
the context is shut down or the handle destroyed (raspv_common/shutdown_errors.py): a real rcl
failure while the node runs surfaces instead of silently ending a liveliness lookup (which
would leave its input "unknown" and drive a wrong stale verdict). Real rclpy on this session's
private domain."""
from __future__ import annotations

import pytest
import rclpy
from rclpy.context import Context
from rclpy.exceptions import InvalidTopicNameException
from std_msgs.msg import String

from raspv_common.liveliness import ProducerWatch
from raspv_common.shutdown_errors import SHUTDOWN_ERRORS, during_shutdown


@pytest.fixture
def node(ros_domain):
    context = Context()
    rclpy.init(context=context)
    n = rclpy.create_node("shutdown_errors_test", context=context)
    yield n
    n.destroy_node()
    rclpy.try_shutdown(context=context)


def raised(call) -> BaseException:
    with pytest.raises(Exception) as info:
        call()
    return info.value


def test_what_shutdown_raises_is_told_apart(node):
    pub = node.create_publisher(String, "/shutdown_errors_test", 1)
    assert not isinstance(raised(lambda: node.get_publishers_info_by_topic("/a//b")), SHUTDOWN_ERRORS)
    rclpy.shutdown(context=node.context)
    after_shutdown = raised(lambda: pub.publish(String()))
    assert isinstance(after_shutdown, SHUTDOWN_ERRORS) and during_shutdown(after_shutdown, node.context)
    node.destroy_node()
    destroyed = raised(lambda: node.get_publishers_info_by_topic("/x"))
    assert isinstance(destroyed, SHUTDOWN_ERRORS) and during_shutdown(destroyed, node.context)


def test_a_lookup_that_fails_while_the_node_runs_is_not_taken_for_shutdown(node):
    watch = ProducerWatch(node)
    with pytest.raises(InvalidTopicNameException):
        watch.watch({"camera": "/camera//depth"})        # was swallowed: the input stayed "unknown"
    watch.watch({"camera": "/camera/depth/image_raw"})
    rclpy.shutdown(context=node.context)
    watch.refresh()                                      # at shutdown: quietly nothing
    node.destroy_node()
    watch.refresh()
