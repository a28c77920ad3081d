"""Launch both nodes: rotor_analysis recording, and rotor_sim on a scene (plus TF, RViz).

    ros2 launch gyro_rotor gyro_rotor.launch.py scene:=nutation output:=/tmp/run1 rviz:=true

Arguments (``ros2 launch gyro_rotor gyro_rotor.launch.py --show-args``): ``scene`` (for
rotor_sim; rotor_analysis follows the scene that rotor_sim announces), ``output`` (the bag
directory), ``rviz``, ``robot_description`` (robot_state_publisher, for the systems that
have a URDF), ``use_sim_time`` (of every node but rotor_sim, the clock source) and
``namespace`` (of every node). Ctrl-C stops it cleanly: every node exits with status 0,
the bag finalized.
"""

import os

from ament_index_python.packages import get_package_share_directory
from gyro_rotor.tools.launch import launch_arguments
from launch import LaunchDescription
from launch.actions import IncludeLaunchDescription
from launch.launch_description_sources import PythonLaunchDescriptionSource
from launch.substitutions import LaunchConfiguration


def generate_launch_description():
    """Return the description: analysis.launch.py, then sim.launch.py on ``scene``."""
    launch_dir = os.path.join(get_package_share_directory('gyro_rotor'), 'launch')
    scene = LaunchConfiguration('scene')
    common = {'use_sim_time': LaunchConfiguration('use_sim_time'),
              'namespace': LaunchConfiguration('namespace')}
    return LaunchDescription([
        *launch_arguments('scene', 'output', 'rviz', 'robot_description', 'use_sim_time',
                          'namespace'),
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(launch_dir, 'analysis.launch.py')),
            launch_arguments={'output': LaunchConfiguration('output'),
                              'scene': scene, **common}.items()),  # subscribed from the start
        IncludeLaunchDescription(
            PythonLaunchDescriptionSource(os.path.join(launch_dir, 'sim.launch.py')),
            launch_arguments={'scene': scene, 'rviz': LaunchConfiguration('rviz'),
                              'robot_description': LaunchConfiguration('robot_description'),
                              **common,
                              # the recorder: rotor_sim holds t = 0 until it subscribes
                              'wait_for_subscribers': '1',
                              'wait_for_node': 'rotor_analysis'}.items()),
    ])
