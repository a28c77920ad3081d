"""The benchmark's scene sets and repeats (:mod:`~gyro_rotor.numerics.bench`), without its imports.

``gyro-rotor bench --help`` names them; this module lets it do so without loading the
integrators, the scenes and the peers that the benchmark itself needs.
"""

__all__ = ['DEFAULT_SCENES', 'QUICK_SCENES', 'REPEATS', 'SYSTEM_SCENES']

DEFAULT_SCENES = ('precession', 'nutation', 'upright', 'stiff_drive@K_D=100', 'stiff_drive',
                  'stiff_drive@K_D=1e6', 'fast_spin', 'conservative', 'conservative@t_end=100',
                  'pole_slip')
#: the short sweep (``--quick``, under a minute): one scene per kind of method
QUICK_SCENES = ('precession', 'stiff_drive', 'conservative')
#: the system files' scenes of the table ``general``
SYSTEM_SCENES = ('centrifuge_euler', 'twin_gimbal', 'elastic_frame')
#: every run of a full sweep is timed this many times, the best kept (``--repeats``'s default).
#: Identical runs (auto's and the method it picked at the same rtol: same steps, same
#: evaluations) differed by up to 7 % at error 1e-9 and 17 % at 1e-6 in the run at 512ca0d,
#: the best of 3: more than auto's column, held to 1.2 times the fastest own method, can bear
REPEATS = 5
