"""Launch rotor_sim on a scene, with its system's robot description (and RViz).

    ros2 launch gyro_rotor sim.launch.py scene:=precession rviz:=true

Arguments (``ros2 launch gyro_rotor sim.launch.py --show-args``):

* ``scene``: rotor_sim's ``scene`` parameter: a shipped centrifuge scene
  (``share/gyro_rotor/config/<scene>.yaml``), a shipped system file's scene of any rotor system
  (``share/gyro_rotor/config/systems/scenes/<scene>.yaml``, such as ``twin_gimbal``) or
  the path of a scene file; rotor_sim reads the file and declares every key of it as a
  parameter;
* ``robot_description``: start robot_state_publisher (TF from ``joint_states``) with the
  URDF of the scene's system: ``share/gyro_rotor/urdf/NAME.urdf`` for a shipped system
  (``centrifuge``, ``centrifuge_euler``, ``twin_gimbal``, ``elastic_frame``), ``mine.urdf``
  beside a system file ``mine.yaml`` of your own. A system without one gets a log line
  instead, whatever this says;
* ``rviz``: start RViz2 with ``share/gyro_rotor/rviz/gyro_rotor.rviz``;
* ``use_sim_time``: robot_state_publisher and RViz follow rotor_sim's ``/clock`` (default
  true). Not passed to rotor_sim: it is the clock source and refuses use_sim_time true;
* ``namespace``: the ROS namespace of every node here and of their relative topics
  (``/clock`` and ``/diagnostics`` stay global);
* ``wait_for_subscribers``, ``wait_for_node``: hold simulation time at 0 until
  ``joint_states`` and ``energy`` each have this many subscribers, and that node among
  them (gyro_rotor.launch.py sets 1 and rotor_analysis, so that the recorder gets every
  sample from t = 0 even when Foxglove or rqt subscribes first).
"""

import os

from ament_index_python.packages import get_package_share_directory
from gyro_rotor.tools.launch import launch_arguments, robot_description
from launch import LaunchDescription
from launch.actions import LogInfo, OpaqueFunction
from launch.conditions import IfCondition
from launch.substitutions import LaunchConfiguration
from launch_ros.actions import Node
from launch_ros.parameter_descriptions import ParameterValue


def _robot_state_publisher(context, share, namespace, use_sim_time):
    """Return robot_state_publisher with the URDF of the scene's system (or why not)."""
    urdf, why = robot_description(context.launch_configurations, share)
    if urdf is None:
        return [LogInfo(msg=why)] if why else []
    return [Node(package='robot_state_publisher', executable='robot_state_publisher',
                 name='robot_state_publisher', namespace=namespace, output='screen',
                 parameters=[{'robot_description': urdf, 'use_sim_time': use_sim_time}])]


def generate_launch_description():
    """Return the description: rotor_sim, robot_state_publisher, RViz2 (optional)."""
    share = get_package_share_directory('gyro_rotor')
    scene = LaunchConfiguration('scene')
    namespace = LaunchConfiguration('namespace')
    use_sim_time = ParameterValue(LaunchConfiguration('use_sim_time'), value_type=bool)
    return LaunchDescription([
        *launch_arguments('scene', 'robot_description', 'rviz', 'use_sim_time', 'namespace',
                          'wait_for_subscribers', 'wait_for_node'),
        Node(package='gyro_rotor', executable='rotor_sim', name='rotor_sim',
             namespace=namespace, output='screen',
             parameters=[{'scene': scene, 'publish_clock': True,
                          'wait_for_subscribers': ParameterValue(
                              LaunchConfiguration('wait_for_subscribers'), value_type=int),
                          'wait_for_node': LaunchConfiguration('wait_for_node')}]),
        OpaqueFunction(function=_robot_state_publisher,
                       args=[share, namespace, use_sim_time]),
        Node(package='rviz2', executable='rviz2', name='rviz2', namespace=namespace,
             output='screen', condition=IfCondition(LaunchConfiguration('rviz')),
             arguments=['-d', os.path.join(share, 'rviz', 'gyro_rotor.rviz')],
             parameters=[{'use_sim_time': use_sim_time}]),
    ])
