"""ament_python packaging of the bb2_ros Python package for `colcon build` (ROS 2 Jazzy).

The code is not copied here: ``bb2_ros/`` in this directory is a symlink to the top-level source
(``../../../bb2_ros``; see bb2_ros_ws/README.md).  The name, version, description, maintainer and license
come from package.xml, the rest is ``bb2_ros_ws/ament_setup.py``; executables are installed under
``lib/bb2_ros`` (setup.cfg) so that ``ros2 run bb2_ros <executable>`` finds them.
"""
import runpy
from pathlib import Path

setup_package = runpy.run_path(str(Path(__file__).resolve().parents[2] / 'ament_setup.py'))['setup_package']
setup_package(__file__, console_scripts=[
    'simulator = bb2_ros.simulator:main',
    'planner = bb2_ros.planner:main',
    'path_following = bb2_ros.path_following:main',
    'l1_autopilot = bb2_ros.l1_autopilot:main',
    'mixer = bb2_ros.mixer:main',
    'container = bb2_ros.container:main',
])
