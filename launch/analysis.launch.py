"""Launch rotor_analysis: live checks of the verdict and an MCAP recording.

    ros2 launch gyro_rotor analysis.launch.py output:=/tmp/rotor_bag

Arguments: ``output`` (the rosbag2 directory to record to, which must not exist yet;
empty: a fresh ``bags_out/rotor_<time>``), ``scene`` (the scene to predict against; empty:
the one rotor_sim announces on ``~/scene``, which it follows through live changes),
``window_s`` (the analysis window [s]). rotor_analysis runs with ``use_sim_time`` (ROS
time = the simulation time of rotor_sim's ``/clock``, the base of every stamp it writes).
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
                              description='rosbag2 (MCAP) directory to record to'),
        DeclareLaunchArgument('scene', default_value='',
                              description="scene to predict against ('': rotor_sim's)"),
        DeclareLaunchArgument('window_s', default_value='8.0',
                              description='analysis window [s]'),
        Node(package='gyro_rotor', executable='rotor_analysis', name='rotor_analysis',
             output='screen',
             parameters=[{'output': LaunchConfiguration('output'),
                          'scene': LaunchConfiguration('scene'),
                          'window_s': ParameterValue(LaunchConfiguration('window_s'),
                                                     value_type=float),
                          'use_sim_time': True}]),
    ])
