"""ament_python packaging of bb2_mission (`colcon build`, ROS 2 Jazzy): ``bb2_mission/`` here links to the top-level
source; name, version, description, maintainer and license come from package.xml (``../../ament_setup.py``)."""
import runpy
from pathlib import Path

setup_package = runpy.run_path(str(Path(__file__).resolve().parents[2] / 'ament_setup.py'))['setup_package']
setup_package(__file__)
