"""colcon (ament_python) build of this package: everything is in setup.cfg, written by
``python -m raspv_bringup.colcon_workspace`` (see docs/DEVELOPING.md)."""
from setuptools import setup

setup()
