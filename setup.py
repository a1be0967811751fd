"""ament_python package description for paramotion.

One executable per node is registered as a console script; ``setup.cfg`` puts them under
``lib/paramotion`` so that ``ros2 run paramotion <node>`` finds them after ``colcon build``.
"""
import runpy
from glob import glob
from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = 'paramotion'

# The node executables: paramotion/start.py's table (read without importing the package), each
# entry paramotion.start:<name>, which imports the node's module and runs its main().
NODES = runpy.run_path(str(Path(__file__).resolve().parent / 'paramotion' / 'start.py'))['NODES']

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
        'console_scripts': [f'{name} = paramotion.start:{name}' for name in NODES] + [
            'paramotion = paramotion.cli:main',
        ],
    },
)
