"""Topic names of the RASPV graph (see docs/DEVELOPING.md for types and frames)."""

# RGB-D source (sim, camera, replay): all publish exactly these.
COLOR = "/camera/color/image_raw"           # sensor_msgs/Image rgb8
DEPTH = "/camera/depth/image_raw"           # sensor_msgs/Image 32FC1 metres, registered to colour
CAMERA_INFO = "/camera/color/camera_info"   # sensor_msgs/CameraInfo
CAMERA_POSE = "/camera/pose"                # geometry_msgs/PoseStamped, world <- camera optical
DEPTH_INFO = "/camera/depth/camera_info"    # sensor_msgs/CameraInfo of the registered depth (camera node)
IMU = "/camera/imu"                         # sensor_msgs/Imu in the colour optical frame (camera node, when the device has one)

# Simulator only.
ODOM = "/odom"                              # nav_msgs/Odometry, base in world
SIM_LABELS = "/sim/labels"                  # sensor_msgs/Image mono8, ground-truth class ids
SIM_COLLISIONS = "/sim/collisions"          # raspv_msgs/CollisionEvent
SIM_CLASSES = "/sim/classes"                # std_msgs/String JSON {id: class name}, latched

# Commands to the avatar / camera head.
CMD_VEL = "/cmd_vel"                        # geometry_msgs/Twist, base frame
HEAD_ORIENTATION = "/head/orientation"      # geometry_msgs/QuaternionStamped, head relative to base

# Perception.
SCENE_STRUCTURE = "/scene/structure"        # raspv_msgs/SceneStructure
SCENE_LABELS = "/scene/labels"              # sensor_msgs/Image mono8 per-pixel scene class
STAIRS = "/stairs"                          # raspv_msgs/StairDetection
SEGMENTATION_LABELS = "/segmentation/labels"  # sensor_msgs/Image mono8 class ids

# Navigation.
NAV_PATH = "/nav/path"                      # nav_msgs/Path, world frame

# Phosphene output.
SPV_IMAGE = "/spv/image"                    # sensor_msgs/Image mono8 (or rgb8 green channel)
SPV_FRAME = "/spv/frame"                    # raspv_msgs/PhospheneFrame
SPV_MAP = "/spv/map"                        # raspv_msgs/PhospheneMap, transient-local

CLOCK = "/clock"                            # rosgraph_msgs/Clock (bag replay)
