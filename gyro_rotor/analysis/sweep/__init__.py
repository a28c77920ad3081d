"""Sweeps: many trajectories of one scene over a grid of parameters and initial conditions.

A sweep answers the drive engineer's questions that the paper (Magnus 1980) leaves open:
from which initial slips a synchronous drive pulls the rotor into synchronism and in which
well (the pull-in map of the sine law), and which drive damping K_D gives the best
nonlinear behaviour for a given stiffness K_S (the design map; the paper's closing remark
and ``gyro-rotor tune`` answer it linearly).

=============  ==================================================================
module         concept
=============  ==================================================================
``grid``       ``--grid KEY=START:STOP:COUNT[:log]`` axes, their product, checks
``metrics``    per-trajectory metrics (final well, pole slips, settling, ...)
``task``       the sweep specification and one block of points = one ensemble run,
               for the centrifuge and for any system file's scene alike
``store``      incremental Parquet output, the manifest, ``--resume``
``runner``     serial in-process or on Dask (local process cluster or by address)
``maps``       heatmap PNGs of a metric over two grid axes
``bench``      the sweep benchmark (throughput, scaling, task overhead)
=============  ==================================================================

Pure Python (numpy, numba via the ensemble, pyarrow, dask); no rclpy.
"""
