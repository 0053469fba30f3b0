"""The virtual world: world files, the BlindBot avatar, people, RGB-D camera, teleoperation and
experiment logs on PyBullet (cores here never import rclpy; `sim_node`/`teleop_node` are the nodes)."""
