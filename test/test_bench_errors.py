"""The benchmark's error measure on every model a scene can run (numerics/bench.errors)."""

from gyro_rotor.core.model import make_model
from gyro_rotor.core.scene import load_scene
from gyro_rotor.numerics.bench import errors
from gyro_rotor.numerics.integrators import integrate
import numpy as np
import pytest


@pytest.mark.parametrize('name', ['full', 'upright_axis', 'locked_housing'])
def test_errors_measure_the_axis_and_z_of_every_centrifuge_model(name):
    """A run against itself: 0; z moved by 1e-7: z_err 1e-7, axis_err 0.

    The reduced models' states hold no quaternion: the locked housing's 3 states were
    unpacked as a quaternion's 4 (a traceback in ``bench --scenes locked_housing``) and the
    upright axis's chi, chidot, z, zdot were read as one.
    """
    model = make_model(name, load_scene('precession').system.params)
    y0 = model.state_from_euler(theta=0.1 if name == 'full' else 0.0, psidot=1.0)
    R = integrate(model, y0, (0.0, 0.5), np.linspace(0.0, 0.5, 11), method='dop853',
                  rtol=1e-10).y
    assert errors(model, R.copy(), R)['err'] == 0.0
    Y = R.copy()
    Y[:, model.iz] += 1e-7
    e = errors(model, Y, R)
    assert e['axis_err'] == 0.0 and e['z_err'] == pytest.approx(1e-7, rel=1e-6)


def _row(scene, method, err, nsteps, status=0):
    from gyro_rotor.numerics.bench import BenchRow
    return BenchRow(scene=scene, method=method, family='gyro_rotor', setting='rtol=1e-06',
                    err=err, axis_err=err, z_err=err, end_err=err, residual=0.0, qnorm=0.0,
                    wall_per_sim=1e-4, nfev=12 * nsteps, nsteps=nsteps, status=status,
                    load=1.0)


def test_steps_per_radian_is_the_geometric_mean_of_the_fewest_steps():
    """The cost table of auto from bench rows: the fewest steps reaching each error, per radian.

    Two settings per scene and method: the looser one reaches 1e-6 but not 1e-9; a failed
    run (status != 0) and another method's rows never count. The table is the geometric mean
    over the six scenes of nsteps / (rate x t_end), the floor the smallest error reached.
    """
    import math
    from gyro_rotor.core.scene import load_scene
    from gyro_rotor.numerics.bench import COST_SCENES, steps_per_radian
    from gyro_rotor.numerics.integrators import methods
    from gyro_rotor.numerics.integrators.base import rates_of
    rows, radians = [], {}
    for i, sc in enumerate(COST_SCENES):
        scene = load_scene(sc)
        radians[sc] = max(rates_of(scene.system.params)) * scene.t_end
        for m in methods.COST_METHODS:
            rows += [_row(sc, m, 5e-7, 100 + i), _row(sc, m, 3e-10, 400 + i),
                     _row(sc, m, 1e-12, 10, status=-3), _row(sc, 'rk4', 1e-12, 5)]
    fit = steps_per_radian(rows)
    want_6 = math.exp(sum(math.log((100 + i) / radians[sc])
                          for i, sc in enumerate(COST_SCENES)) / 6)
    want_9 = math.exp(sum(math.log((400 + i) / radians[sc])
                          for i, sc in enumerate(COST_SCENES)) / 6)
    errs = methods.COST_ERRORS
    for m in methods.COST_METHODS:
        table = fit['steps'][m]
        for e, v in zip(errs, table):
            if e >= 5e-7:
                assert math.isclose(v, want_6, rel_tol=1e-12)
            elif e >= 3e-10:
                assert math.isclose(v, want_9, rel_tol=1e-12)
            else:
                assert v is None
        assert fit['floor'][m] == 3e-10
    assert steps_per_radian([r for r in rows if r.scene != 'upright']) is None


def test_auto_cost_table_is_that_of_the_committed_benchmark():
    """The cost table in use is that of the committed benchmark run, to its digits.

    methods.STEPS_PER_RADIAN and ERROR_FLOOR against bench.steps_per_radian of the rows of
    bench/work_precision.csv. A table left from another sweep (the decade sweep's differed
    by up to 20 %) or a benchmark rerun without its table fails here. Reads the file only,
    no timing.
    """
    import csv
    import dataclasses
    from pathlib import Path
    from gyro_rotor.numerics.bench import BenchRow, steps_per_radian
    from gyro_rotor.numerics.integrators import methods
    kinds = {f.name: f.type for f in dataclasses.fields(BenchRow)}
    cast = {'int': lambda v: int(float(v)), 'float': float, 'str': str}
    path = Path(__file__).resolve().parents[1] / 'bench' / 'work_precision.csv'
    with open(path, newline='') as fh:
        rows = [BenchRow(**{k: cast[kinds[k]](v) for k, v in r.items() if k in kinds})
                for r in csv.DictReader(fh)]
    fit = steps_per_radian(rows)
    for m in methods.COST_METHODS:
        assert [float(f'{v:.3g}') for v in fit['steps'][m]] == list(
            methods.STEPS_PER_RADIAN[m]), m
        assert float(f"{fit['floor'][m]:.1e}") == methods.ERROR_FLOOR[m], m
