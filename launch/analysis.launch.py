"""Launch rotor_analysis: live checks of the verdict and an MCAP recording.

    ros2 launch gyro_rotor analysis.launch.py output:=/tmp/rotor_bag

Arguments (``ros2 launch gyro_rotor analysis.launch.py --show-args``): ``output``,
``scene``, ``window_s``, ``use_sim_time`` (default true: ROS time is the simulation time of
rotor_sim's ``/clock``, the base of every stamp the node writes; false: the system clock)
and ``namespace`` (of the node and its relative topics: it then listens to the rotor_sim
of that namespace; ``/clock`` and ``/diagnostics`` stay global).
"""

from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    """Return the description: rotor_analysis recording to ``output``."""
    return LaunchDescription([
        DeclareLaunchArgument('output', default_value='',
                              description='rosbag2 (MCAP) directory to record to, which must '
                                          "not exist yet ('': a fresh "
                                          'bags_out/rotor_<time>)'),
        DeclareLaunchArgument('scene', default_value='',
                              description="scene to predict against ('': the one rotor_sim "
                                          'announces on ~/scene, followed through live '
                                          'changes)'),
        DeclareLaunchArgument('window_s', default_value='8.0',
                              description='analysis window [s]'),
        DeclareLaunchArgument('use_sim_time', default_value='true',
                              description="follow rotor_sim's /clock (simulation time); "
                                          'false: the system clock'),
        DeclareLaunchArgument('namespace', default_value='',
                              description='ROS namespace of the node and its topics'),
        Node(package='gyro_rotor', executable='rotor_analysis', name='rotor_analysis',
             namespace=LaunchConfiguration('namespace'), output='screen',
             parameters=[{'output': LaunchConfiguration('output'),
                          'scene': LaunchConfiguration('scene'),
                          'window_s': ParameterValue(LaunchConfiguration('window_s'),
                                                     value_type=float),
                          'use_sim_time': ParameterValue(LaunchConfiguration('use_sim_time'),
                                                         value_type=bool)}]),
    ])
