"""The files a ROS 2 install uses beside the nodes: URDF, launch files, RViz and Foxglove.

``ros2 launch``, robot_state_publisher and RViz cannot run here (not installable from the
PyPI wheels), so these tests check what can be checked without them (the URDFs: test_urdf.py):
the launch files, imported against stub ``launch``/``launch_ros`` modules, start executables
that exist, with files that setup.py installs, and robot_state_publisher with the URDF of
the scene's system; RViz and Foxglove configs name topics the nodes publish.
"""

import ast
from glob import glob
import json
from pathlib import Path
import runpy
import sys
import types
import xml.etree.ElementTree as ET

from gyro_rotor.bag import wire
import pytest
import yaml

REPO = Path(__file__).resolve().parents[1]


# -- the launch files, against stub launch modules --------------------------------------
class _Entity:
    """A recorded launch action or substitution: its class name, args and kwargs."""

    def __init__(self, *args, **kwargs):
        self.args, self.kwargs = args, kwargs

    def items(self):          # launch_arguments={...}.items() is passed through
        return self.kwargs.items()


def _stub_modules(share: Path) -> dict:
    names = {
        'launch': ['LaunchDescription', 'Condition'],
        'launch.actions': ['DeclareLaunchArgument', 'IncludeLaunchDescription', 'LogInfo',
                           'GroupAction', 'OpaqueFunction'],
        'launch.conditions': ['IfCondition', 'UnlessCondition'],
        'launch.substitutions': ['LaunchConfiguration', 'PathJoinSubstitution', 'Command'],
        'launch.launch_description_sources': ['PythonLaunchDescriptionSource'],
        'launch_ros.actions': ['Node'],
        'launch_ros.parameter_descriptions': ['ParameterValue'],
        'launch_ros.substitutions': ['FindPackageShare'],
    }
    mods = {}
    for mod, classes in names.items():
        m = types.ModuleType(mod)
        for c in classes:
            setattr(m, c, type(c, (_Entity,), {}))
        mods[mod] = m
    mods['launch_ros'] = types.ModuleType('launch_ros')
    aip = types.ModuleType('ament_index_python')
    pk = types.ModuleType('ament_index_python.packages')
    pk.get_package_share_directory = lambda pkg: str(share) if pkg == 'gyro_rotor' else \
        pytest.fail(f'share directory of {pkg} asked for')
    mods['ament_index_python'], mods['ament_index_python.packages'] = aip, pk
    return mods


def _installed_share(tmp_path: Path) -> Path:
    """share/gyro_rotor as setup.py's data_files install it (copied from the source tree)."""
    tree = ast.parse((REPO / 'setup.py').read_text())
    data = next(kw.value for node in ast.walk(tree) if isinstance(node, ast.Call)
                for kw in node.keywords if kw.arg == 'data_files')
    share = tmp_path / 'share' / 'gyro_rotor'
    for entry in data.elts:
        dest, files = entry.elts
        dest_txt = ast.unparse(dest)
        if 'package_name' not in dest_txt:
            continue
        sub = [e.value for e in dest.args[2:]] if isinstance(dest, ast.Call) else []
        pattern = ast.unparse(files)
        paths = (glob(str(REPO / files.args[0].value)) if isinstance(files, ast.Call)
                 else [str(REPO / p) for p in ast.literal_eval(pattern)])
        target = share.joinpath(*sub)
        target.mkdir(parents=True, exist_ok=True)
        for p in paths:
            (target / Path(p).name).write_bytes(Path(p).read_bytes())
    return share


def _console_scripts() -> set:
    tree = ast.parse((REPO / 'setup.py').read_text())
    ep = next(kw.value for node in ast.walk(tree) if isinstance(node, ast.Call)
              for kw in node.keywords if kw.arg == 'entry_points')
    scripts = ast.literal_eval(ep)['console_scripts']
    return {s.split('=')[0].strip() for s in scripts}


def _walk(entity):
    yield entity
    values = list(entity.args) + list(entity.kwargs.values()) if isinstance(entity, _Entity) \
        else list(entity) if isinstance(entity, (list, tuple)) \
        else list(entity.values()) if isinstance(entity, dict) else []
    for v in values:
        if isinstance(v, (_Entity, list, tuple, dict)):
            yield from _walk(v)


@pytest.fixture
def launch_env(tmp_path, monkeypatch):
    share = _installed_share(tmp_path)
    for name, mod in _stub_modules(share).items():
        monkeypatch.setitem(sys.modules, name, mod)
    return share


LAUNCH_FILES = sorted(p.name for p in (REPO / 'launch').glob('*.launch.py'))


def test_the_launch_files_are_installed(launch_env):
    assert set(LAUNCH_FILES) >= {'sim.launch.py', 'analysis.launch.py', 'gyro_rotor.launch.py'}
    assert sorted(p.name for p in (launch_env / 'launch').iterdir()) == LAUNCH_FILES
    assert (launch_env / 'urdf' / 'centrifuge.urdf').is_file()
    assert (launch_env / 'rviz' / 'gyro_rotor.rviz').is_file()
    assert (launch_env / 'config' / 'precession.yaml').is_file()


@pytest.mark.parametrize('name', LAUNCH_FILES)
def test_launch_file_starts_existing_executables_with_installed_files(name, launch_env):
    ld = runpy.run_path(str(launch_env / 'launch' / name))['generate_launch_description']()
    assert type(ld).__name__ == 'LaunchDescription'
    entities = list(_walk(ld))
    nodes = [e for e in entities if type(e).__name__ == 'Node']
    includes = [e for e in entities if type(e).__name__ == 'PythonLaunchDescriptionSource']
    args = {e.args[0] for e in entities if type(e).__name__ == 'DeclareLaunchArgument'}
    used = {e.args[0] for e in entities if type(e).__name__ == 'LaunchConfiguration'}
    assert used <= args, f'{name}: undeclared launch arguments {used - args}'
    assert nodes or includes
    scripts = _console_scripts()
    for n in nodes:
        if n.kwargs['package'] == 'gyro_rotor':
            assert n.kwargs['executable'] in scripts
        else:
            assert n.kwargs['package'] in ('robot_state_publisher', 'rviz2')
    for inc in includes:
        assert Path(inc.args[0]).is_file()
        assert Path(inc.args[0]).parent == launch_env / 'launch'
    for e in entities:           # every literal path into the share directory exists
        if isinstance(e, str) and e.startswith(str(launch_env)):
            assert Path(e).exists(), e
    for e in entities:
        if type(e).__name__ == 'PathJoinSubstitution':
            parts = e.args[0]
            assert parts[0] == str(launch_env) and parts[1] == 'config'


def _is_config(value, name: str, typ=None) -> bool:
    """Whether ``value`` is LaunchConfiguration(name) (in a ParameterValue of ``typ``)."""
    if typ is not None:
        if type(value).__name__ != 'ParameterValue' or value.kwargs.get('value_type') is not typ:
            return False
        value = value.args[0]
    return type(value).__name__ == 'LaunchConfiguration' and value.args[0] == name


class _Context:
    """The launch context an OpaqueFunction reads: the launch configurations."""

    def __init__(self, **cfg):
        self.launch_configurations = cfg


def _robot_state_publisher(ld, **cfg) -> list:
    """Return the actions of sim.launch.py's OpaqueFunction for these configurations."""
    op = next(e for e in _walk(ld) if type(e).__name__ == 'OpaqueFunction')
    return op.kwargs['function'](_Context(**cfg), *op.kwargs.get('args', ()))


def test_sim_launch_publishes_the_urdf_and_clock(launch_env):
    path = launch_env / 'launch' / 'sim.launch.py'
    ld = runpy.run_path(str(path))['generate_launch_description']()
    nodes = {n.kwargs['executable']: n for n in _walk(ld) if type(n).__name__ == 'Node'}
    [rsp_node] = _robot_state_publisher(ld, scene='precession')
    rsp = rsp_node.kwargs['parameters'][0]
    assert rsp['robot_description'] == (REPO / 'urdf' / 'centrifuge.urdf').read_text()
    assert _is_config(rsp['use_sim_time'], 'use_sim_time', bool)
    sim_params = nodes['rotor_sim'].kwargs['parameters'][0]
    assert sim_params['publish_clock'] is True
    # rotor_sim reads the scene file itself: a centrifuge scene or any rotor system's
    assert sim_params['scene'].args[0] == 'scene'
    assert sim_params['wait_for_subscribers'].args[0].args[0] == 'wait_for_subscribers'
    # the simulator is the clock source: use_sim_time is never passed to it
    assert all('use_sim_time' not in p for p in nodes['rotor_sim'].kwargs['parameters']
               if isinstance(p, dict))
    rviz = nodes['rviz2'].kwargs['parameters'][0]
    assert _is_config(rviz['use_sim_time'], 'use_sim_time', bool)
    for n in list(nodes.values()) + [rsp_node]:
        assert _is_config(n.kwargs['namespace'], 'namespace')


@pytest.mark.parametrize('scene, system', [
    ('precession', 'centrifuge'), ('nutation', 'centrifuge'), ('twin_gimbal', 'twin_gimbal'),
    ('elastic_frame', 'elastic_frame'), ('centrifuge_euler', 'centrifuge_euler')])
def test_robot_state_publisher_gets_the_urdf_of_the_scenes_system(launch_env, scene, system):
    ld = runpy.run_path(str(launch_env / 'launch' / 'sim.launch.py'))[
        'generate_launch_description']()
    for on in ('true', 'True', '1'):
        [node] = _robot_state_publisher(ld, scene=scene, robot_description=on)
        assert node.kwargs['executable'] == 'robot_state_publisher'
        assert node.kwargs['parameters'][0]['robot_description'] == \
            (REPO / 'urdf' / f'{system}.urdf').read_text()
    assert _robot_state_publisher(ld, scene=scene, robot_description='false') == []


def test_a_system_without_urdf_gets_a_log_line(launch_env, tmp_path):
    """A system file of one's own without NAME.urdf beside it: no TF, one line says why."""
    ld = runpy.run_path(str(launch_env / 'launch' / 'sim.launch.py'))[
        'generate_launch_description']()
    (tmp_path / 'mine.yaml').write_text(
        (REPO / 'config' / 'systems' / 'twin_gimbal.yaml').read_text())
    scene = tmp_path / 'scene.yaml'
    scene.write_text('/**:\n  ros__parameters:\n    system: mine.yaml\n')
    [log] = _robot_state_publisher(ld, scene=str(scene))
    assert type(log).__name__ == 'LogInfo' and 'no URDF' in log.kwargs['msg']
    (tmp_path / 'mine.urdf').write_text('<robot name="mine"/>')
    [node] = _robot_state_publisher(ld, scene=str(scene))
    assert node.kwargs['parameters'][0]['robot_description'] == '<robot name="mine"/>'


def test_scene_urdf_follows_rotor_sims_lookup(launch_env, tmp_path):
    from gyro_rotor.tools.launch import scene_urdf
    share = str(launch_env)
    assert scene_urdf('precession', share) == str(launch_env / 'urdf' / 'centrifuge.urdf')
    assert scene_urdf('twin_gimbal', share) == str(launch_env / 'urdf' / 'twin_gimbal.urdf')
    assert scene_urdf('no_such_scene', share) is None        # rotor_sim reports it
    general = tmp_path / 'mine.yaml'
    general.write_text('/**:\n  ros__parameters:\n    system: no_such_system\n')
    assert scene_urdf(str(general), share) is None
    (tmp_path / 'c.yaml').write_text(
        (REPO / 'config' / 'nutation.yaml').read_text())
    assert scene_urdf(str(tmp_path / 'c.yaml'), share) == \
        str(launch_env / 'urdf' / 'centrifuge.urdf')


def test_combined_launch_records_from_t0(launch_env):
    """gyro_rotor.launch.py: the analysis knows the scene and rotor_sim waits for it."""
    ld = runpy.run_path(str(launch_env / 'launch' / 'gyro_rotor.launch.py'))[
        'generate_launch_description']()
    inc = {Path(e.args[0].args[0]).name: dict(e.kwargs['launch_arguments'])
           for e in _walk(ld) if type(e).__name__ == 'IncludeLaunchDescription'}
    assert inc['sim.launch.py']['wait_for_subscribers'] == '1'
    assert inc['sim.launch.py']['wait_for_node'] == 'rotor_analysis'
    assert inc['analysis.launch.py']['scene'].args[0] == 'scene'


def test_analysis_launch_follows_simulation_time(launch_env):
    """rotor_analysis runs with use_sim_time (default true): ROS time is rotor_sim's /clock."""
    path = launch_env / 'launch' / 'analysis.launch.py'
    ld = runpy.run_path(str(path))['generate_launch_description']()
    nodes = {n.kwargs['executable']: n for n in _walk(ld) if type(n).__name__ == 'Node'}
    params = nodes['rotor_analysis'].kwargs['parameters'][0]
    assert _is_config(params['use_sim_time'], 'use_sim_time', bool)
    assert _is_config(nodes['rotor_analysis'].kwargs['namespace'], 'namespace')
    args = _declared(ld)
    assert args['use_sim_time'].kwargs['default_value'] == 'true'


def _declared(ld) -> dict:
    """Return the DeclareLaunchArgument entities of a (stub) launch description by name."""
    return {e.args[0]: e for e in _walk(ld) if type(e).__name__ == 'DeclareLaunchArgument'}


#: the arguments every launch file of the package takes (issue 27), besides its own
LAUNCH_ARGUMENTS = {
    'gyro_rotor.launch.py': {'use_sim_time', 'namespace', 'scene', 'output', 'rviz',
                             'robot_description'},
    'sim.launch.py': {'use_sim_time', 'namespace', 'scene', 'rviz', 'robot_description',
                      'wait_for_subscribers', 'wait_for_node'},
    'analysis.launch.py': {'use_sim_time', 'namespace', 'scene', 'output', 'window_s'},
}


def _launch_api_arguments(path: Path, share: Path, monkeypatch) -> dict | None:
    """``ros2 launch --show-args``'s list through the launch API: {name: (default, doc)}.

    None where the launch API is not importable (it is not on PyPI; rostools builds it).
    """
    try:        # (the checkout's launch/ folder imports as an empty namespace package)
        from launch.launch_description_sources import PythonLaunchDescriptionSource
        import ament_index_python.packages as aip
    except ImportError:
        return None
    monkeypatch.setattr(aip, 'get_package_share_directory',
                        lambda pkg: str(share) if pkg == 'gyro_rotor' else pytest.fail(pkg))
    ld = PythonLaunchDescriptionSource(str(path)).try_get_launch_description_without_context()
    return {a.name: (''.join(getattr(s, 'text', str(s)) for s in a.default_value or ()),
                     a.description) for a in ld.get_launch_arguments()}


@pytest.mark.parametrize('name', sorted(LAUNCH_ARGUMENTS))
def test_launch_arguments_have_descriptions(name, tmp_path, monkeypatch):
    """Every argument of ``ros2 launch ... --show-args`` says what it does.

    Through the launch API where it is importable (its own list, the included files'
    arguments merged as ``--show-args`` shows them); otherwise read from the launch file
    against stub modules, the included files' declarations collected the same way.
    """
    share = _installed_share(tmp_path)
    path = share / 'launch' / name
    api = _launch_api_arguments(path, share, monkeypatch)
    if api is None:
        with monkeypatch.context() as m:
            for mod_name, mod in _stub_modules(share).items():
                m.setitem(sys.modules, mod_name, mod)
            ld = runpy.run_path(str(path))['generate_launch_description']()
            args = {k: (e.kwargs.get('default_value'), e.kwargs.get('description', ''))
                    for k, e in _declared(ld).items()}
    else:
        args = api
    assert set(args) >= LAUNCH_ARGUMENTS[name], set(args)
    for arg, (default, doc) in args.items():
        assert doc and doc != 'no description given' and len(doc) > 10, (name, arg, doc)
    assert 'true' in str(args['use_sim_time'][0])


# -- RViz and Foxglove ------------------------------------------------------------------
def _published_topics() -> set:
    """Topic names that the nodes create publishers for (read from their source)."""
    topics = set()
    for path in (REPO / 'gyro_rotor' / 'ros').glob('*.py'):
        for node in ast.walk(ast.parse(path.read_text())):
            if isinstance(node, ast.Call) and getattr(node.func, 'attr', '') == \
                    'create_publisher' and len(node.args) >= 2 and \
                    isinstance(node.args[1], ast.Constant):
                topics.add('/' + node.args[1].value.lstrip('/'))
    return topics


def test_rviz_config_shows_the_robot_and_the_axis():
    cfg = yaml.safe_load((REPO / 'rviz' / 'gyro_rotor.rviz').read_text())
    vm = cfg['Visualization Manager']
    assert vm['Global Options']['Fixed Frame'] == 'world'
    displays = {d['Class']: d for d in vm['Displays']}
    assert displays['rviz_default_plugins/RobotModel']['Description Topic']['Value'] == \
        '/robot_description'
    assert displays['rviz_default_plugins/Marker']['Topic']['Value'] in _published_topics()


def test_foxglove_layout_plots_published_topics():
    layout = json.loads((REPO / 'foxglove' / 'gyro_rotor_layout.json').read_text())
    panels = layout['configById']

    def leaves(node):
        return [node] if isinstance(node, str) else leaves(node['first']) + \
            leaves(node['second'])
    assert set(leaves(layout['layout'])) == set(panels)
    published = _published_topics()
    paths = [p['value'] for cfg in panels.values() for p in cfg.get('paths', [])]
    for field in ('E_star', 'residual', 'z'):        # the plots of E*, r and z
        index = wire.ENERGY_FIELDS.index(field)
        assert any(p.startswith(f'/energy.data[{index}]') for p in paths), field
    scene = [cfg for key, cfg in panels.items() if key.startswith('3D!')]
    assert len(scene) == 1 and scene[0]['followTf'] == 'world'       # the 3-D scene
    assert set(scene[0]['topics']) <= published | {'/robot_description', '/tf'}
    assert {'/axis_marker', '/robot_description'} <= set(scene[0]['topics'])
    for p in paths:
        assert p.split('.')[0] in published
    assert panels['RawMessages!verdict']['topicPath'] in published


# -- package.xml: every dependency resolvable by rosdep ------------------------------------
#: rosdep keys of package.xml that the rosdep index defines (ros/rosdistro, rosdep/python.yaml
#: and base.yaml at commit 662921b, 2026-08-22, read for this list) or that are ROS packages
INDEX_KEYS = {'python3-numpy', 'python3-scipy', 'python3-yaml', 'python3-sympy',
              'python3-numba', 'python3-matplotlib', 'python3-pytest', 'python3-hypothesis',
              'mcap-ros2-support'}
ROS_PACKAGES = {'rclpy', 'builtin_interfaces', 'rcl_interfaces', 'std_msgs', 'sensor_msgs',
                'geometry_msgs', 'diagnostic_msgs', 'visualization_msgs', 'rosgraph_msgs',
                'std_srvs', 'ament_index_python', 'launch', 'launch_ros',
                'robot_state_publisher', 'rviz2', 'ament_flake8', 'ament_pep257'}


def test_every_package_xml_key_is_in_the_index_or_our_rosdep_file():
    root = ET.parse(REPO / 'package.xml').getroot()
    keys = {e.text.strip() for e in root if e.tag.endswith('depend')}
    ours = set(yaml.safe_load((REPO / 'rosdep' / 'gyro_rotor.yaml').read_text()))
    assert not ours & INDEX_KEYS               # never shadow a key of the index
    unknown = keys - INDEX_KEYS - ROS_PACKAGES - ours
    assert not unknown, f'rosdep cannot resolve {sorted(unknown)}'
    assert ours <= keys                        # the file defines nothing unused
    for key, rule in yaml.safe_load((REPO / 'rosdep' / 'gyro_rotor.yaml').read_text()).items():
        assert set(rule) >= {'ubuntu', 'debian'}, key
