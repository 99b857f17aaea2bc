"""ament_python packaging of the bb2_control Python package for `colcon build` (ROS 2 Jazzy).

The code is not copied here: ``bb2_control/`` in this directory is a symlink to the top-level source
(``../../../bb2_control``; see bb2_ros_ws/README.md).  The name, version, description, maintainer and license
come from package.xml, the rest is ``bb2_ros_ws/ament_setup.py``.
"""
import runpy
from pathlib import Path

setup_package = runpy.run_path(str(Path(__file__).resolve().parents[2] / 'ament_setup.py'))['setup_package']
setup_package(__file__)
