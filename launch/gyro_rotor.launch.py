"""Launch both nodes: rotor_analysis recording, and rotor_sim on a scene (plus TF, RViz).

    ros2 launch gyro_rotor gyro_rotor.launch.py scene:=nutation output:=/tmp/run1 rviz:=true

Arguments: ``scene`` (for rotor_sim; rotor_analysis follows the scene that rotor_sim
announces), ``output`` (the bag directory; empty: a fresh ``bags_out/rotor_<time>``),
``rviz``.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument, IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration


def generate_launch_description():
    """Return the description: analysis.launch.py, then sim.launch.py on ``scene``."""
    launch_dir = os.path.join(get_package_share_directory('gyro_rotor'), 'launch')
    scene = LaunchConfiguration('scene')
    return LaunchDescription([
        DeclareLaunchArgument('scene', default_value='precession'),
        DeclareLaunchArgument('output', default_value=''),
        DeclareLaunchArgument('rviz', default_value='false'),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(launch_dir, 'analysis.launch.py')),
            launch_arguments={'output': LaunchConfiguration('output'),
                              'scene': scene}.items()),     # subscribed from the start
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(launch_dir, 'sim.launch.py')),
            launch_arguments={'scene': scene, 'rviz': LaunchConfiguration('rviz'),
                              # the recorder: rotor_sim holds t = 0 until it subscribes
                              'wait_for_subscribers': '1',
                              'wait_for_node': 'rotor_analysis'}.items()),
    ])
