"""ament_python packaging of bb2_bringup (ROS 2 Jazzy): launch files, the params file and the missions, installed
into share/bb2_bringup so that `ros2 launch bb2_bringup bb2_graph.launch.py` finds them (FindPackageShare).

No Python module: ``config`` and ``missions`` here are symlinks to the repository's top-level folders.
"""
from glob import glob

from setuptools import setup

package_name = 'bb2_bringup'

setup(
    name=package_name,
    version='0.1.0',
    packages=[],
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        ('share/' + package_name + '/launch', sorted(glob('launch/*.launch.py'))),
        ('share/' + package_name + '/config', ['config/bb2_graph.yaml', 'config/foxglove_layout.json']),
        ('share/' + package_name + '/missions', sorted(glob('missions/*.yaml'))),
    ],
    install_requires=['setuptools'],
    zip_safe=False,
    maintainer='BB2 Sim developers',
    maintainer_email='bb2-sim@todo.todo',
    description='BB2 bringup: launch files of the BB2 graph (one boat, a fleet), its params file and missions.',
    license='TODO',
)
