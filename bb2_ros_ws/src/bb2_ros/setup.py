"""ament_python packaging of the bb2_ros Python package for `colcon build` (ROS 2 Jazzy).

The code is not copied here: ``bb2_ros/`` in this directory is a symlink to the top-level source
(``../../../bb2_ros``), which both colcon modes handle (see bb2_ros_ws/README.md).  Executables
are installed under ``lib/bb2_ros`` (setup.cfg) so that ``ros2 run bb2_ros <executable>`` finds them.
"""
from setuptools import find_packages, setup

package_name = 'bb2_ros'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(include=[package_name, package_name + '.*']),
    package_data={package_name: ['data/*.json', 'data/*.yaml', 'data/**/*.json', 'data/**/*.yaml',
                                 'data/**/*.npz']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='BB2 Sim developers',
    maintainer_email='bb2-sim@todo.todo',
    description='BB2 ROS 2 node shells: simulator (fixed-rate ROM, /clock, lockstep or real time), planner, path_following, l1_autopilot, mixer.',
    license='TODO',
    entry_points={
        'console_scripts': [
            'simulator = bb2_ros.simulator:main',
            'planner = bb2_ros.planner:main',
            'path_following = bb2_ros.path_following:main',
            'l1_autopilot = bb2_ros.l1_autopilot:main',
            'mixer = bb2_ros.mixer:main',
            'container = bb2_ros.container:main',
        ],
    },
)
