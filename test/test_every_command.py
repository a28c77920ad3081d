"""The same commands on every shipped scene, with the same output formats (issue 25).

One theorem, one path: the centrifuge is the built-in system ``centrifuge``, a system
file's scene is a system like it, and every command takes either. For every shipped scene:
``simulate`` (one CSV format: ``name [unit]``, rates ``NAME_dot``), ``eig`` and ``locus``
(the JSON keys every system has; the claims (a)-(d) hold on every shipped system),
``tune``, ``campbell``, ``steady``, ``sweep``, and ``demo`` with ``analyze`` on its bag.
"""

import json

from gyro_rotor.cli.main import main
from gyro_rotor.core.scene import list_scenes, load_scene
import pytest

SCENES = tuple(list_scenes())
#: the scenes whose sweep runs on a dask LocalCluster: the centrifuge's and a system file's
DASK_SCENES = ('precession', 'twin_gimbal')


def test_both_kinds_of_system_are_shipped():
    """The matrix below covers the built-in centrifuge and system files."""
    kinds = {load_scene(n).builtin for n in SCENES}
    assert kinds == {True, False}
    assert len(list_scenes(builtin=False)) >= 3


@pytest.mark.parametrize('name', SCENES)
def test_every_command_on_every_scene(name, tmp_path, capsys):
    scene = load_scene(name)

    csv = tmp_path / 'run.csv'
    assert main(['simulate', name, '--t-end', '0.2', '--rate', '50', '--out', str(csv)]) == 0
    out = capsys.readouterr().out
    for word in ('final state:', 'E*:', 'max |residual|', 'RHS evaluations', 'wrote'):
        assert word in out, (word, out)
    header = csv.read_text().splitlines()[0].split(',')
    names = [h.split(' [')[0] for h in header]
    assert all(h.endswith(']') and ' [' in h for h in header), header
    assert names[0] == 't' and {'E_star', 'dE_dt', 'residual'} <= set(names)
    assert all(n.removesuffix('_dot') in names for n in names if n.endswith('_dot')), names
    assert len(csv.read_text().splitlines()) == 1 + 11

    eig = tmp_path / 'eig.json'
    assert main(['eig', name, '--json', str(eig)]) == 0
    doc = json.loads(eig.read_text())
    assert doc['scene'] == scene.name and doc['system'] == scene.system_name
    assert {'K_D', 'modes', 'spectral_abscissa'} <= set(doc)
    assert doc['modes'] and all({'name', 're', 'im', 'reached'} <= set(m) for m in doc['modes'])
    scale = max(1.0, max(abs(complex(m['re'], m['im'])) for m in doc['modes']))
    assert doc['spectral_abscissa'] <= 1e-12 * scale     # 0 up to round-off (conservative)

    loc = tmp_path / 'locus.json'
    assert main(['locus', name, '--json', str(loc), '--points', '20']) == 0
    doc = json.loads(loc.read_text())
    assert doc['scene'] == scene.name and doc['system'] == scene.system_name
    assert {k: c['holds'] for k, c in doc['claims'].items()} == dict.fromkeys('abcd', True)
    assert len(doc['meeting_points']) == len(doc['meetings'])
    capsys.readouterr()

    assert main(['tune', name]) == 0
    assert 'best' in capsys.readouterr().out

    camp = tmp_path / 'campbell.json'
    assert main(['campbell', name, '--points', '5', '--json', str(camp)]) == 0
    doc = json.loads(camp.read_text())
    assert {'Omega0', 'frequencies_hz', 'decay_rates', 'critical_speeds'} <= set(doc)
    assert len(doc['Omega0']) == 5

    assert main(['steady', name]) == 0
    assert capsys.readouterr().out.startswith(f'scene {scene.name}')

    sweep = tmp_path / 'sweep'
    # a dask LocalCluster (worker processes unpickle the scene: the built-in centrifuge's, a
    # system file's) on one scene of each kind; --serial elsewhere (the same blocks, without
    # a cluster's start: 15-20 s a scene at load 5; test_sweep holds the two equal)
    serial = [] if name in DASK_SCENES else ['--serial']
    assert main(['sweep', name, '--grid', 'K_D=0.05:0.1:2', '--t-end', '0.5', '--out',
                 str(sweep), '--yes', '--quiet'] + serial) == 0
    assert any(sweep.iterdir())
    capsys.readouterr()

    run = tmp_path / 'demo'
    status = main(['demo', name, '--duration', '1', '--rtf', '0', '--quiet', '--out', str(run)])
    text = capsys.readouterr().out
    result = [x for x in text.splitlines() if x.startswith('RESULT: ')]
    assert len(result) == 1 and status == (0 if 'RESULT: CONFIRMED' in result[0] else 1)
    status = main(['analyze', str(run / 'bag')])
    text = capsys.readouterr().out
    result = [x for x in text.splitlines() if x.startswith('RESULT: ')]
    assert len(result) == 1 and f"scene '{scene.name}'" in text
