"""gyro_rotor: rotor systems on synchronous drives after K. Magnus (1980), live and offline.

The package is a house of layers. Each layer is a subpackage; a module may import from its
own layer and from the layers listed before it, never from a layer after it:

=========  ======================================================================  =======
layer      what it holds                                                           rclpy
=========  ======================================================================  =======
errors     the exception types (:mod:`gyro_rotor.errors`), below every layer       no
settings   the simulation node's settings that a scene file may carry              no
           (:mod:`gyro_rotor.node_settings`), below every layer
core       the physics: parameters, rotations, the models, steady motions, scenes  no
numerics   integrators (compiled kernels), simulate, ensemble, real-time pacing,   no
           benchmarks
linear     linearization, stability, the paper's claims, root locus, system        no
           identification
bag        rosbag2 MCAP: message definitions, QoS text, writer, reader, recovery   no
analysis   the streaming checks, predictions, the verdict, offline analysis,       no
           reports and plots
ros        the nodes and everything that imports rclpy: messages, the recorder,    yes
           rotor_sim, rotor_analysis
tools      process launching, soak, monitor                                        yes
cli        the ``gyro-rotor`` command and its subcommands                          yes
=========  ======================================================================  =======

``test/test_layers.py`` enforces the rule: no module of a pure layer imports rclpy, and no
module imports from a later layer.

References
----------
K. Magnus, "Die Stabilitaet von Schwingungen in Rotorsystemen mit Synchronantrieb",
Karl-Marguerre-Gedaechtnis-Kolloquium, TH Darmstadt, 1980.
"""

__version__ = '0.1.0'

#: the layers, lowest first (see the module docstring)
LAYERS = ('core', 'numerics', 'linear', 'bag', 'analysis', 'ros', 'tools', 'cli')
#: the layers whose modules may import rclpy
ROS_LAYERS = ('ros', 'tools', 'cli')
