"""ament_python package gyro_rotor: Magnus (1980) gyrostat on a synchronous drive."""
from glob import glob
import os

from setuptools import find_packages, setup

package_name = 'gyro_rotor'

setup(
    name=package_name,
    version='0.1.0',
    packages=find_packages(exclude=['test']),
    data_files=[
        ('share/ament_index/resource_index/packages', ['resource/' + package_name]),
        ('share/' + package_name, ['package.xml']),
        (os.path.join('share', package_name, 'config'), glob('config/*.yaml')),
        (os.path.join('share', package_name, 'config', 'systems'),
         glob('config/systems/*.yaml')),
        (os.path.join('share', package_name, 'config', 'systems', 'scenes'),
         glob('config/systems/scenes/*.yaml')),
        (os.path.join('share', package_name, 'launch'), glob('launch/*.launch.py')),
        (os.path.join('share', package_name, 'urdf'), glob('urdf/*.urdf')),
        (os.path.join('share', package_name, 'rviz'), glob('rviz/*.rviz')),
        (os.path.join('share', package_name, 'foxglove'), glob('foxglove/*.json')),
    ],
    install_requires=['setuptools'],
    zip_safe=True,
    maintainer='gyro_rotor developers',
    maintainer_email='dev@gyro-rotor.local',
    description='Real-time simulation and stability analysis of a gyrostat on a '
                'synchronous drive (K. Magnus 1980) for ROS 2 Jazzy.',
    license='Apache-2.0',
    extras_require={'test': ['pytest']},
    entry_points={
        'console_scripts': [
            'gyro-rotor = gyro_rotor.cli.main:main',
            'rotor_sim = gyro_rotor.ros.sim_node:main',
            'rotor_analysis = gyro_rotor.ros.analysis_node:main',
        ],
    },
)
