"""Which equations of motion the benchmark's compiled peers copy (a closed choice).

A system says it (``peer_equations`` of :class:`~gyro_rotor.core.centrifuge.Centrifuge`
and :class:`~gyro_rotor.core.system.generated.GeneratedSystem`); ``numerics.bench.PEERS``
builds the peers' right-hand side by it, so that core names no module of numerics.
"""

import enum


class PeerEquations(enum.StrEnum):
    """The equations a compiled peer's right-hand side is written from."""

    #: the centrifuge's full model (:func:`~gyro_rotor.core.model.full_rhs` without D),
    #: written again by hand in numba for CyRK and numbalsoda
    CENTRIFUGE_FULL = 'centrifuge_full'
    #: a system file's generated equations (numba on sympy's lambdify) for CyRK
    GENERATED = 'generated'
