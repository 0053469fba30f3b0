"""Shared pieces every package uses: camera model, ROS <-> numpy conversions, node base, parameters."""
