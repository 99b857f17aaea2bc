"""ament_python packaging of bb2_bringup (ROS 2 Jazzy): launch files, the params file and the missions, installed
into share/bb2_bringup so that `ros2 launch bb2_bringup bb2_graph.launch.py` finds them (FindPackageShare).

No Python module: ``config`` and ``missions`` here are symlinks to the repository's top-level folders.  The
name, version, description, maintainer and license come from package.xml (``bb2_ros_ws/ament_setup.py``).
"""
import runpy
from pathlib import Path

setup_package = runpy.run_path(str(Path(__file__).resolve().parents[2] / 'ament_setup.py'))['setup_package']
setup_package(__file__, python=False, share={
    'launch': ['launch/*.launch.py'],
    'config': ['config/bb2_graph.yaml', 'config/foxglove_layout.json'],
    'missions': ['missions/*.yaml'],
    'missions/fleets': ['missions/fleets/*.yaml'],
})
