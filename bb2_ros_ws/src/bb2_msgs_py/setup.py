"""ament_python packaging of the bb2_msgs_py Python package for `colcon build` (ROS 2 Jazzy).

The code is not copied here: ``bb2_msgs_py/`` in this directory is a symlink to the top-level source
(``../../../bb2_msgs_py``), which both colcon modes handle (see bb2_ros_ws/README.md).  Executables
are installed under ``lib/bb2_msgs_py`` (setup.cfg) so that ``ros2 run bb2_msgs_py <executable>`` finds them.
"""
from setuptools import find_packages, setup

package_name = 'bb2_msgs_py'

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
    description='BB2 message contract: topic names, standard message types, QoS, frames and numpy to and from message conversions.',
    license='TODO',
    entry_points={
        'console_scripts': [
        ],
    },
)
