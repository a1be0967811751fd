"""ament_python package description for paramotion.

One executable per node is registered as a console script; ``setup.cfg`` puts them under
``lib/paramotion`` so that ``ros2 run paramotion <node>`` finds them after ``colcon build``.
"""
from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'paramotion'

NODES = [
    # Shared / smoke graph (paramotion/)
    'smoke_sim = paramotion.smoke.sim_node:main',
    'smoke_range_sensor = paramotion.smoke.range_sensor_node:main',
    'smoke_controller = paramotion.smoke.controller_node:main',
    'bag_recorder = paramotion.bag.recorder_node:main',
    'bag_player = paramotion.bag.player_node:main',
    # coverage_pkg (issue 3)
    'coverage_sim = coverage_pkg.sim_node:main',
    'coverage_sonar = coverage_pkg.sonar_node:main',
    'coverage_planner = coverage_pkg.planner_node:main',
    'coverage_monitor = coverage_pkg.monitor_node:main',
    # climber_pkg (issue 4)
    'climber_sim = climber_pkg.sim_node:main',
    'climber_ultrasonic = climber_pkg.ultrasonic_node:main',
    'climber_planner = climber_pkg.planner_node:main',
    # cable_robot_pkg FAST (issue 5)
    'fast_sim = cable_robot_pkg.fast.sim_node:main',
    'fast_tracker = cable_robot_pkg.fast.optical_tracker_node:main',
    'fast_trajectory = cable_robot_pkg.fast.feed_trajectory_node:main',
    'fast_cable_controller = cable_robot_pkg.fast.cable_pid_node:main',
    'fast_isolation_controller = cable_robot_pkg.fast.isolation_node:main',
    'fast_control_container = cable_robot_pkg.fast.control_container_node:main',
    # cable_robot_pkg workspace (issue 6)
    'workspace_monitor = cable_robot_pkg.cdrpm.workspace_monitor_node:main',
    # voronoi_pkg: Gough-Stewart simplified Voronoi planner (issue 7)
    'voronoi_planner = voronoi_pkg.planner_node:main',
]

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(exclude=['test', 'test.*']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        # ros2 launch paramotion <graph>.launch.xml; the launch files find their default
        # inputs as $(dirname)/../<pkg>/..., the same relative path as in the source tree.
        ('share/' + PACKAGE + '/launch', sorted(glob('launch/*.launch.xml'))),
        ('share/' + PACKAGE + '/coverage_pkg/worlds', sorted(glob('coverage_pkg/worlds/*.json'))),
        ('share/' + PACKAGE + '/climber_pkg/trunks', sorted(glob('climber_pkg/trunks/*.json'))),
    ],
    package_data={'': ['*.yaml', '*.json']},
    include_package_data=True,
    install_requires=['setuptools'],
    # Sweeps run their cases on Dask; everything else works without it (--serial).
    extras_require={'sweeps': ['dask>=2026.8.0', 'distributed>=2026.8.0']},
    zip_safe=True,
    maintainer='paramotion developers',
    maintainer_email='dev@paramotion.invalid',
    description='Parallel robots and sensor-based planning papers as a ROS 2 node graph.',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': NODES + [
            'paramotion = paramotion.cli:main',
        ],
    },
)
