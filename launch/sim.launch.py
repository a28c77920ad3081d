"""Launch rotor_sim on a scene, with the centrifuge's robot description (and RViz).

    ros2 launch gyro_rotor sim.launch.py scene:=precession rviz:=true

Arguments: ``scene`` (rotor_sim's ``scene`` parameter: a shipped centrifuge scene,
``share/gyro_rotor/config/<scene>.yaml``, a shipped general scene of any rotor system,
``share/gyro_rotor/config/systems/scenes/<scene>.yaml`` such as ``twin_gimbal``, or the path
of a scene file; rotor_sim reads the file and declares every key of it as a parameter),
``robot_description`` (true: robot_state_publisher turns ``joint_states`` into TF with
``share/gyro_rotor/urdf/centrifuge.urdf``; only meaningful for the centrifuge scenes: pass
false for a general system, whose joints are its coordinates and rotor lags z_ROTOR),
``rviz`` (start RViz2 with ``share/gyro_rotor/rviz/gyro_rotor.rviz``),
``wait_for_subscribers`` (hold simulation time at 0 until ``joint_states`` and ``energy``
each have this many subscribers; 0: start at once), ``wait_for_node`` (and until that
node subscribes to both; gyro_rotor.launch.py sets 1 and rotor_analysis, so that the
recorder gets every sample from t = 0 even when Foxglove or rqt subscribes first).
rotor_sim publishes ``/clock`` (simulation time); every other node here runs with
``use_sim_time`` so that its TF and displays follow the simulated time.
"""

import os

from ament_index_python.packages import get_package_share_directory
from launch import LaunchDescription
from launch.actions import DeclareLaunchArgument
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def generate_launch_description():
    """Return the description: rotor_sim, robot_state_publisher, RViz2 (optional)."""
    share = get_package_share_directory('gyro_rotor')
    with open(os.path.join(share, 'urdf', 'centrifuge.urdf')) as f:
        urdf = f.read()
    scene = LaunchConfiguration('scene')
    return LaunchDescription([
        DeclareLaunchArgument('scene', default_value='precession',
                              description='scene name (config/<scene>.yaml, '
                                          'config/systems/scenes/<scene>.yaml) or path'),
        DeclareLaunchArgument('robot_description', default_value='true',
                              description='publish TF of the centrifuge from joint_states'),
        DeclareLaunchArgument('rviz', default_value='false', description='start RViz2'),
        DeclareLaunchArgument('wait_for_subscribers', default_value='0',
                              description='hold t = 0 until this many subscribers'),
        DeclareLaunchArgument('wait_for_node', default_value='',
                              description='... and until this node subscribes'),
        Node(package='gyro_rotor', executable='rotor_sim', name='rotor_sim', output='screen',
             parameters=[{'scene': scene, 'publish_clock': True,
                          'wait_for_subscribers': ParameterValue(
                              LaunchConfiguration('wait_for_subscribers'), value_type=int),
                          'wait_for_node': LaunchConfiguration('wait_for_node')}]),
        Node(package='robot_state_publisher', executable='robot_state_publisher',
             name='robot_state_publisher', output='screen',
             condition=IfCondition(LaunchConfiguration('robot_description')),
             parameters=[{'robot_description': urdf, 'use_sim_time': True}]),
        Node(package='rviz2', executable='rviz2', name='rviz2', output='screen',
             condition=IfCondition(LaunchConfiguration('rviz')),
             arguments=['-d', os.path.join(share, 'rviz', 'gyro_rotor.rviz')],
             parameters=[{'use_sim_time': True}]),
    ])
