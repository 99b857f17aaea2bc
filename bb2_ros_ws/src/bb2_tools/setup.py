"""ament_python packaging of the bb2_tools Python package for `colcon build` (ROS 2 Jazzy).

The code is not copied here: ``bb2_tools/`` in this directory is a symlink to the top-level source
(``../../../bb2_tools``), which both colcon modes handle (see bb2_ros_ws/README.md).  Executables
are installed under ``lib/bb2_tools`` (setup.cfg) so that ``ros2 run bb2_tools <executable>`` finds them.
"""
from glob import glob

from setuptools import find_packages, setup

package_name = 'bb2_tools'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(include=[package_name, package_name + '.*']),
    package_data={package_name: ['data/*.json', 'data/*.yaml', 'data/**/*.json', 'data/**/*.yaml',
                                 'data/**/*.npz']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/missions', sorted(glob('missions/*.yaml'))),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='BB2 Sim developers',
    maintainer_email='bb2-sim@todo.todo',
    description='BB2 tools: rosbag2-compatible MCAP recorder, the bb2-launch launcher and its supervisor and monitor, analysis, replay, the bb2-sim CLI; installs the shipped missions.',
    license='TODO',
    entry_points={
        'console_scripts': [
            'recorder = bb2_tools.recorder:main',
            'foxglove_bridge = bb2_tools.foxglove_live:main',
        ],
    },
)
