# Copyright 2026 polarization_compass developers
#
# Licensed under the Apache License, Version 2.0 (the "License");
# you may not use this file except in compliance with the License.
# You may obtain a copy of the License at
#
#     http://www.apache.org/licenses/LICENSE-2.0
#
# Unless required by applicable law or agreed to in writing, software
# distributed under the License is distributed on an "AS IS" BASIS,
# WITHOUT WARRANTIES OR CONDITIONS OF ANY KIND, either express or implied.
# See the License for the specific language governing permissions and
# limitations under the License.

"""
ament_python build description for polarization_compass.

`colcon build` installs the node executables into lib/polarization_compass (see setup.cfg) so that
`ros2 run polarization_compass <node>` finds them; launch files, parameter files and scenes go into
share/polarization_compass.
"""

from glob import glob

from setuptools import find_packages, setup

PACKAGE = 'polarization_compass'

setup(
    name=PACKAGE,
    version='0.1.0',
    packages=find_packages(include=[PACKAGE, PACKAGE + '.*']),
    package_data={PACKAGE: ['data/*.yaml', 'data/*.npz']},
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + PACKAGE]),
        ('share/' + PACKAGE, ['package.xml']),
        ('share/' + PACKAGE + '/launch', glob('launch/*.launch.py')),
        ('share/' + PACKAGE + '/config', glob('config/*.yaml') + glob('config/*.xml')),
        ('share/' + PACKAGE + '/config/scenes', glob('config/scenes/*.yaml')),
        ('share/' + PACKAGE + '/config/arrays', glob('config/arrays/*.yaml')),
    ],
    install_requires=['setuptools'],
    # Error-map sweeps on Dask distributed with maps as xarray/Zarr (docs/error-maps.md); never
    # needed by the nodes.
    extras_require={
        'sweep': ['dask==2026.8.0', 'distributed==2026.8.0', 'xarray==2026.9.0', 'zarr==3.1.6']
    },
    zip_safe=False,
    maintainer='polarization_compass developers',
    maintainer_email='polarization-compass@example.invalid',
    description='Heading from skylight polarization, with tilt error maps and correction (ROS 2).',
    license='Apache-2.0',
    tests_require=['pytest'],
    entry_points={
        'console_scripts': [
            'polarization-compass = polarization_compass.cli:entry',
            'sky_simulator = polarization_compass.nodes.sky_simulator:main',
            'heading_estimator = polarization_compass.nodes.heading_estimator:main',
            'array_heading_estimator = polarization_compass.nodes.array_heading_estimator:main',
            'tilt_corrector = polarization_compass.nodes.tilt_corrector:main',
            'error_evaluator = polarization_compass.nodes.error_evaluator:main',
            'player_flow = polarization_compass.nodes.player_flow:main',
        ],
    },
)
