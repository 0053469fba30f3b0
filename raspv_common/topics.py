"""Topic names of the RASPV graph (see docs/DEVELOPING.md for types and frames)."""

# RGB-D source (sim, camera, replay): all publish exactly these.
COLOR = "/camera/color/image_raw"           # sensor_msgs/Image rgb8
DEPTH = "/camera/depth/image_raw"           # sensor_msgs/Image 32FC1 metres, registered to colour
CAMERA_INFO = "/camera/color/camera_info"   # sensor_msgs/CameraInfo
CAMERA_POSE = "/camera/pose"                # geometry_msgs/PoseStamped, map <- camera optical (frame_id map)
DEPTH_INFO = "/camera/depth/camera_info"    # sensor_msgs/CameraInfo of the registered depth (camera node)
IMU = "/camera/imu"                         # sensor_msgs/Imu in the colour optical frame (camera node, when the device has one)

# Simulator only.
ODOM = "/odom"                              # nav_msgs/Odometry, base_link in odom
SIM_LABELS = "/sim/labels"                  # sensor_msgs/Image mono8, ground-truth class ids
SIM_COLLISIONS = "/sim/collisions"          # raspv_msgs/CollisionEvent
SIM_CLASSES = "/sim/classes"                # std_msgs/String JSON {id: class name}, latched
SIM_LOCKSTEP = "/sim/lockstep"              # geometry_msgs/TwistStamped: command answering the frame of that stamp
SIM_START_TRIAL = "/sim/start_trial"        # raspv_msgs/srv/StartTrial
SIM_END_TRIAL = "/sim/end_trial"            # raspv_msgs/srv/EndTrial

# Commands to the avatar / camera head.
CMD_VEL = "/cmd_vel"                        # geometry_msgs/Twist, base frame
HEAD_ORIENTATION = "/head/orientation"      # geometry_msgs/QuaternionStamped, head relative to base
GAZE_DIRECTION = "/gaze/direction"          # geometry_msgs/Vector3Stamped, unit eye gaze in the head frame; (0,0,0) = invalid

# Perception.
SCENE_STRUCTURE = "/scene/structure"        # raspv_msgs/SceneStructure
SCENE_LABELS = "/scene/labels"              # sensor_msgs/Image mono8 per-pixel scene class
STAIRS = "/stairs"                          # raspv_msgs/StairDetection
SEGMENTATION_LABELS = "/segmentation/labels"  # sensor_msgs/Image mono8 (mono16 beyond 256 classes) class ids
SEGMENTATION_CLASSES = "/segmentation/classes"  # raspv_msgs/ClassNames, latched

# Navigation.
NAV_PATH = "/nav/path"                      # nav_msgs/Path, world frame
NAV_CMD_VEL_HINT = "/nav/cmd_vel_hint"      # geometry_msgs/Twist, DWA suggestion (base frame)
NAV_GUIDANCE = "/nav/guidance"              # raspv_msgs/NavGuidance, world frame
NAV_GLOBAL_COSTMAP = "/nav/global_costmap"  # nav_msgs/OccupancyGrid, inflated static layer, latched
NAV_COSTMAP = "/nav/costmap"                # nav_msgs/OccupancyGrid, inflated static + obstacle layers
NAV_OBSTACLE_LAYER = "/nav/obstacle_layer"  # nav_msgs/OccupancyGrid, live obstacles from depth

# Phosphene output.
SPV_IMAGE = "/spv/image"                    # sensor_msgs/Image mono8 (or rgb8 green channel)
SPV_FRAME = "/spv/frame"                    # raspv_msgs/PhospheneFrame
SPV_MAP = "/spv/map"                        # raspv_msgs/PhospheneMap, transient-local
SPV_SPRITES = "/spv/sprites"                # raspv_msgs/PhospheneSprites, transient-local: what the levels stream draws with
HMD_PRESENTATION = "/hmd/presentation"      # std_msgs/String JSON {"fps", "refresh_hz"}: what the wearer's page composited, ~1 Hz
SPV_STATUS = "/spv/status"                  # std_msgs/String JSON, latched: what the display shows and which inputs are stale

# Transforms (REP 105 tree map → odom → base_link → … → camera optical; raspv_common/frames.py).
TF = "/tf"                                  # tf2_msgs/TFMessage, moving transforms (poses, the head)
TF_STATIC = "/tf_static"                    # tf2_msgs/TFMessage, transient-local: mountings and fixed offsets

# Localisation (the slam node, raspv_slam).
SLAM_STATE = "/slam/state"                  # std_msgs/String JSON, transient-local: tracking state, keyframes, inliers
SLAM_MARKERS = "/slam/markers"              # visualization_msgs/MarkerArray (map frame): keyframes, landmarks, loop edges
SLAM_SAVE_MAP = "/slam/save_map"            # raspv_msgs/srv/SaveMap: save the map now

CLOCK = "/clock"                            # rosgraph_msgs/Clock (bag replay; sim: simulation time)

# Experiments (raspv_experiments).
EXPERIMENT_INSTRUCTIONS = "/experiment/instructions"  # std_msgs/String JSON, latched: what the subject is told
EXPERIMENT_RESPONSE = "/experiment/response"          # std_msgs/String JSON: the subject's start/abort

# Live views (raspv_viz): markers of what perception found and the depth as a point cloud.
VIZ_SCENE = "/viz/scene"                    # visualization_msgs/MarkerArray: planes with hulls, obstacles, free floor
VIZ_STAIRS = "/viz/stairs"                  # visualization_msgs/MarkerArray: treads and the stair wireframe
VIZ_PATH = "/viz/path"                      # visualization_msgs/MarkerArray: the planned path and its goal
VIZ_PHOSPHENES = "/viz/phosphenes"          # visualization_msgs/MarkerArray: the phosphenes placed in front of the camera
VIZ_CLOUD = "/viz/cloud"                    # sensor_msgs/PointCloud2: decimated depth (xyz + rgb)
