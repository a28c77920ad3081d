"""Launch rotor_analysis: live checks of the verdict and an MCAP recording.

    ros2 launch gyro_rotor analysis.launch.py output:=/tmp/rotor_bag

Arguments (``ros2 launch gyro_rotor analysis.launch.py --show-args``): ``output``,
``scene``, ``window_s``, ``use_sim_time`` (default true: ROS time is the simulation time of
rotor_sim's ``/clock``, the base of every stamp the node writes; false: the system clock)
and ``namespace`` (of the node and its relative topics: it then listens to the rotor_sim
of that namespace; ``/clock`` and ``/diagnostics`` stay global).
"""

from gyro_rotor.tools.launch import launch_arguments
from launch import LaunchDescription
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    """Return the description: rotor_analysis recording to ``output``."""
    return LaunchDescription([
        *launch_arguments('output', 'scene', 'window_s', 'use_sim_time', 'namespace',
                          scene=('', "scene to predict against ('': the one rotor_sim announces "
                                     'on ~/scene, followed through live changes)')),
        Node(package='gyro_rotor', executable='rotor_analysis', name='rotor_analysis',
             namespace=LaunchConfiguration('namespace'), output='screen',
             parameters=[{'output': LaunchConfiguration('output'),
                          'scene': LaunchConfiguration('scene'),
                          'window_s': ParameterValue(LaunchConfiguration('window_s'),
                                                     value_type=float),
                          'use_sim_time': ParameterValue(LaunchConfiguration('use_sim_time'),
                                                         value_type=bool)}]),
    ])
