"""ament_python packaging of the bb2_tools Python package for `colcon build` (ROS 2 Jazzy).

The code is not copied here: ``bb2_tools/`` in this directory is a symlink to the top-level source
(``../../../bb2_tools``; see bb2_ros_ws/README.md).  The name, version, description, maintainer and license
come from package.xml, the rest is ``bb2_ros_ws/ament_setup.py``; executables are installed under
``lib/bb2_tools`` (setup.cfg) so that ``ros2 run bb2_tools <executable>`` finds them.
"""
import runpy
from pathlib import Path

setup_package = runpy.run_path(str(Path(__file__).resolve().parents[2] / 'ament_setup.py'))['setup_package']
setup_package(__file__, console_scripts=[
    'recorder = bb2_tools.recorder:main',
    'foxglove_bridge = bb2_tools.foxglove_live:main',
], share={'missions': ['missions/*.yaml']})
