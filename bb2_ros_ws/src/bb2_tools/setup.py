"""ament_python packaging of bb2_tools (`colcon build`, ROS 2 Jazzy): ``bb2_tools/`` here links to the top-level
source; name, version, description, maintainer and license come from package.xml (``../../ament_setup.py``)."""
import runpy
from pathlib import Path

setup_package = runpy.run_path(str(Path(__file__).resolve().parents[2] / 'ament_setup.py'))['setup_package']
setup_package(__file__, console_scripts=[
    'recorder = bb2_tools.entry:recorder',
    'foxglove_bridge = bb2_tools.entry:foxglove_bridge',
], share={'missions': ['missions/*.yaml']})
