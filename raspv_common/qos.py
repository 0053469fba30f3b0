"""QoS profiles used across the graph.

Images are *reliable, keep-last 2*: with the shared-memory transport a reliable image costs
~3 ms between processes, and keep-last 2 means a slow subscriber sees the newest frame instead
of a backlog. Nodes that *process* images (scene perception, odometry, the phosphene
simulator) subscribe keep-last 1 (:data:`LATEST_QOS`): when they fall behind they skip to the
newest frame instead of working through an older one (a frame less of latency per frame of
backlog). Recorders keep the publishers' depth. Commands are reliable keep-last 1 (only the
newest command matters). Latched topics (the phosphene map, class tables) are transient-local
so late joiners get them.
"""
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy

SENSOR_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=2,
                        reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
LATEST_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                        reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
COMMAND_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
EVENT_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                       reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
LATCHED_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                         reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# IMU samples come at 100–400 Hz: keep a short backlog so a busy subscriber loses none.
IMU_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=50,
                     reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
# Eye-gaze samples (/gaze/direction) come at 60–1000 Hz, in bursts from a scripted subject (a
# frame's worth at once): a writer history of a few seconds lets a reliable reader that missed a
# burst (a full shared-memory port, repaired at the next heartbeat) still get every sample for
# the trial's log; the spv node reads them keep-last 2 (only the newest matters to the display).
GAZE_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1000,
                      reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
# tf as tf2_ros does it: /tf reliable keep-last 100 (a burst of transforms is not lost); /tf_static
# reliable, transient-local, keep-last 1: each node sends all its static transforms in one message,
# which late joiners (RViz, a recorder) still get.
TF_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.VOLATILE)
TF_STATIC_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=1,
                           reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
# what a tf listener subscribes /tf_static with: every publisher's latched message
TF_STATIC_LISTENER_QOS = QoSProfile(history=HistoryPolicy.KEEP_LAST, depth=100,
                                    reliability=ReliabilityPolicy.RELIABLE, durability=DurabilityPolicy.TRANSIENT_LOCAL)
