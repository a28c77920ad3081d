"""The documentation cannot rot (issue 28).

The site builds with MkDocs in strict mode (a broken page, link or nav entry fails), the
README stays a README (at most about 200 lines), and every bash and Python block of the
tutorials runs: in an empty folder, in order, with the project's ``.venv`` first on the
PATH. A ```text block right after a block quotes lines of its output: each must appear in
what the block printed. The ROS tutorial runs with ``ros2`` from a rostools build
(``node_helpers.rostools_env``: the one bootstrap made from ../shared/rostools) and is skipped
with that reason where there is none.
"""

import contextlib
import io
import os
import pathlib
import re
import subprocess
import sys

import node_helpers
import pytest

REPO = pathlib.Path(__file__).resolve().parent.parent
TUTORIALS = sorted((REPO / 'docs' / 'tutorials').glob('*.md'))
BLOCK = re.compile(r'```(bash|python|text)\n(.*?)```', re.S)


def blocks(path: pathlib.Path) -> list:
    """Return [(language, code, quoted output lines or [])] of a page, in order."""
    found = BLOCK.findall(path.read_text(encoding='utf-8'))
    out = []
    for lang, code in found:
        if lang == 'text':
            if out:
                out[-1][2].extend(line for line in code.splitlines() if line.strip())
            continue
        out.append((lang, code, []))
    return out


def test_site_builds_strict(tmp_path):
    pytest.importorskip('mkdocs', reason='mkdocs is in requirements-test.txt')
    res = subprocess.run([sys.executable, '-m', 'mkdocs', 'build', '--strict', '--site-dir',
                          str(tmp_path / 'site')], cwd=REPO, capture_output=True, text=True,
                         env=dict(os.environ, NO_MKDOCS_2_WARNING='1'),
                         timeout=300)
    assert res.returncode == 0, res.stdout + res.stderr
    assert (tmp_path / 'site' / 'reference' / 'cli' / 'index.html').exists()
    cli = (tmp_path / 'site' / 'reference' / 'cli' / 'index.html').read_text()
    for command in ('locus', 'demo', 'analyze', 'campbell'):
        assert f'gyro-rotor {command}' in cli


def test_readme_fits_on_a_few_screens():
    lines = (REPO / 'README.md').read_text(encoding='utf-8').splitlines()
    assert len(lines) <= 200, len(lines)
    text = '\n'.join(lines)
    for needed in ('./run_demo.sh', './run_tests.sh', 'source .venv/bin/activate'):
        assert needed in text


@pytest.mark.parametrize('page', TUTORIALS, ids=[p.stem for p in TUTORIALS])
def test_tutorial_blocks_run_and_print_what_the_page_quotes(page, tmp_path, monkeypatch):
    steps = blocks(page)
    assert steps, f'{page.name} has no code block'
    bash = any(lang == 'bash' for lang, _, _ in steps)
    # the ROS tutorial runs with ros2 from a rostools build (skipped where there is none)
    # and in a shell with job control, as the user's terminal: without it (bash -c) a
    # background job ignores SIGINT, and `kill -INT %1` would not stop the launch
    ros = (f'set -m; set +u; source {node_helpers.rostools_env()}; set -u\n'
           if page.stem == 'ros' else '')
    env = dict(os.environ, PATH=f'{pathlib.Path(sys.executable).parent}:{os.environ["PATH"]}',
               MPLBACKEND='Agg', ROS_AUTOMATIC_DISCOVERY_RANGE='LOCALHOST')
    monkeypatch.chdir(tmp_path)
    for lang, code, quoted in steps:
        if lang == 'bash':
            res = subprocess.run(['bash', '-euo', 'pipefail', '-c', ros + code], env=env,
                                 capture_output=True, text=True, timeout=600)
            assert res.returncode == 0, f'{code}\n{res.stdout}\n{res.stderr}'
            printed = res.stdout
        else:
            buf = io.StringIO()
            with contextlib.redirect_stdout(buf):
                exec(compile(code, str(page), 'exec'), {'__name__': '__tutorial__'})
            printed = buf.getvalue()
        missing = [line for line in quoted if line not in printed]
        assert not missing, f'{page.name}: {code}\nprinted:\n{printed}\nmissing: {missing}'
    assert bash or page.stem == 'python-api'
