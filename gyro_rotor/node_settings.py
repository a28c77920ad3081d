"""Settings of the simulation node ``rotor_sim``: its names, keys and ranges, and its recorder.

A scene file is at once a ROS 2 parameter file for ``rotor_sim`` (:mod:`gyro_rotor.core.scene`),
so it may carry the node's settings beside the scene's keys; the scene reader accepts and
range-checks them, the live simulation (:mod:`gyro_rotor.numerics.live`) runs with them and
the node (:mod:`gyro_rotor.ros.sim_params`) declares them as parameters. They are written
here once, in a module that imports nothing of the package (as :mod:`gyro_rotor.errors`), so
that every layer reads them without the physics core knowing the node.
"""

from __future__ import annotations

from typing import Any

__all__ = ['NODE_NAMES', 'NODE_RANGES', 'NODE_KEYS', 'recorder_node_name']

#: the sections of a parameter file that the simulation node reads (its name, any node)
NODE_NAMES = ('rotor_sim', '/rotor_sim', '/**')

#: ranges of the simulation node's numeric keys, the same in a scene file, --set, a
#: --params-file and a live parameter (rotor_sim declares them with these ranges)
NODE_RANGES = {
    'publish_rate': (1.0, 10000.0), 'real_time_factor': (0.0, 1000.0), 'rtol': (0.0, 1.0),
    'atol': (0.0, 1.0), 'step_size': (0.0, 1.0), 'diagnostics_period': (0.05, 3600.0),
    'max_catch_up': (0.001, 10.0), 'max_residual': (0.0, 1e9), 't_end': (1e-6, 1e9),
    'visualization_rate': (0.0, 10000.0), 'realtime_priority': (0, 99),
}

#: keys of the simulation node that a scene file may carry as well (type, default, doc)
NODE_KEYS: dict[str, tuple[type, Any, str]] = {
    'publish_rate': (float, 250.0, 'publish rate of the state topics [Hz]'),
    'real_time_factor': (float, 1.0, 'simulated seconds per wall second; 0 = as fast as '
                                     'possible'),
    'publish_clock': (bool, True, 'publish /clock (rosgraph_msgs/Clock) with the '
                                  'simulation time (as Gazebo does; other nodes follow it '
                                  'with use_sim_time)'),
    'integrator': (str, 'auto', 'integration method (auto picks one per scene)'),
    'rtol': (float, 0.0, 'relative tolerance of adaptive methods (0 = the method default)'),
    'atol': (float, 0.0, 'absolute tolerance of adaptive methods (0 = the method default)'),
    'step_size': (float, 0.0, 'step of fixed-step methods [s] (0 = the method default)'),
    'frame_id': (str, 'world', 'frame of the published poses and markers'),
    'diagnostics_period': (float, 1.0, 'period of /diagnostics [s]'),
    'max_catch_up': (float, 0.25, 'most wall seconds of simulation one tick may catch up'),
    'stop_at_t_end': (bool, False, 'stop integrating (and idle) when t reaches t_end'),
    'max_residual': (float, 1.0, 'divergence guard: the node stops integrating when '
                                 '|energy-balance residual| exceeds this [J] and '
                                 '1e-6 x max(|E*|, |E_ref|)'),
    'wait_for_subscribers': (int, 0, 'hold simulation time at 0 until joint_states and '
                                     'energy each have this many subscribers (a recorder '
                                     'then gets every sample from t = 0; 0 = start at once)'),
    'wait_for_node': (str, '', "and until a subscriber of this node (its recorder's hidden "
                               'node _<name>_recorder counts as it) is among them: another '
                               'subscriber, such as Foxglove, cannot stand in for the '
                               "recorder ('' = any subscribers)"),
    'use_sim_time': (bool, False, 'ROS: must stay false for the simulator itself'),
}


def recorder_node_name(node: str) -> str:
    """Return the name of the hidden node that records the topics of node ``node``."""
    return f'_{node}_recorder'
