"""The parameters a scene's system gives ``rotor_sim``: pure data, no ROS.

Each system (:class:`~gyro_rotor.core.centrifuge.Centrifuge`,
:class:`~gyro_rotor.core.system.generated.GeneratedSystem`) says which parameters its
scene has (``parameter_specs``); :mod:`gyro_rotor.ros.sim_params` declares them in one
loop and builds the scene from the values given at start
(:meth:`~gyro_rotor.core.scene.Scene.with_changes`).
"""

from __future__ import annotations

import dataclasses
from typing import Any

__all__ = ['ParamSpec']


@dataclasses.dataclass(frozen=True)
class ParamSpec:
    """One parameter of a scene: its key, the scene's value, documentation and kind.

    ``read_only``: read at start only (else live); ``typ``: its Python type (float, int,
    bool, str or list); ``kick``: a key of the kick of ``~/perturb``
    (``perturbation.KEY``); ``fixed``: a value other than the scene's is refused (the
    scene's system).
    """

    key: str
    default: Any
    doc: str
    read_only: bool = False
    typ: type = float
    kick: bool = False
    fixed: bool = False
