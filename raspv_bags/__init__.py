"""Bags: recording, reading (complete, unfinished or damaged), repair, playback, offline
phosphene rendering and RGB-D dataset import. Cores only (numpy/rosbags, no rclpy); the
`replay` node in :mod:`raspv_camera.replay_node` and `raspv bag|render` use them."""
