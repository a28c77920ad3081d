"""gyro_rotor: the elastically restrained centrifuge of K. Magnus (1980) on a synchronous drive.

The pure-Python core (no rclpy import): :mod:`gyro_rotor.params`, :mod:`gyro_rotor.model`,
:mod:`gyro_rotor.rotations`, :mod:`gyro_rotor.steady`, :mod:`gyro_rotor.scene` and
:mod:`gyro_rotor.simulate`. The ROS 2 nodes (:mod:`gyro_rotor.sim_node`,
:mod:`gyro_rotor.analysis_node`) are thin adapters over it.

References
----------
K. Magnus, "Die Stabilitaet von Schwingungen in Rotorsystemen mit Synchronantrieb",
Karl-Marguerre-Gedaechtnis-Kolloquium, TH Darmstadt, 1980.
"""

__version__ = '0.1.0'
