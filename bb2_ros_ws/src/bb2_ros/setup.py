"""ament_python packaging of bb2_ros (`colcon build`, ROS 2 Jazzy): ``bb2_ros/`` here links to the top-level
source; name, version, description, maintainer and license come from package.xml (``../../ament_setup.py``)."""
import runpy
from pathlib import Path

setup_package = runpy.run_path(str(Path(__file__).resolve().parents[2] / 'ament_setup.py'))['setup_package']
setup_package(__file__, console_scripts=[
    'simulator = bb2_ros.entry:simulator',
    'planner = bb2_ros.entry:planner',
    'path_following = bb2_ros.entry:path_following',
    'l1_autopilot = bb2_ros.entry:l1_autopilot',
    'mixer = bb2_ros.entry:mixer',
    'container = bb2_ros.entry:container',
])
