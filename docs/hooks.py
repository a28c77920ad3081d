"""MkDocs hooks: the home page, the CLI reference and the benchmark pages, generated.

The home page comes from README.md, the CLI reference from the argparse parsers, the
benchmark pages from bench/. All are generated at every build, so the site cannot disagree
with the README, the code or the benchmark records (the generated files are not tracked:
.gitignore).
"""

import pathlib
import re
import shutil

ROOT = pathlib.Path(__file__).resolve().parent.parent


def cli_markdown() -> str:
    """Return the CLI reference: every subcommand's ``--help``, as the parser prints it."""
    import argparse

    from gyro_rotor.cli.main import build_parser
    parser = build_parser()
    parts = ['# Command line reference\n',
             'Generated from the argparse parsers at every build of this site '
             '(`gyro-rotor COMMAND --help` prints the same).\n',
             '```text\n' + parser.format_help() + '```\n']
    sub = next(a for a in parser._actions if isinstance(a, argparse._SubParsersAction))
    for name, p in sub.choices.items():
        parts.append(f'## `gyro-rotor {name}`\n\n```text\n{p.format_help()}```\n')
    return '\n'.join(parts)


def home_markdown() -> str:
    """Return README.md with its links made relative to docs/ (the site's home page)."""
    text = (ROOT / 'README.md').read_text(encoding='utf-8')
    text = re.sub(r'\]\(docs/', '](', text)
    return re.sub(r'\]\(bench/\)', '](bench/work_precision.md)', text)


def on_pre_build(config, **kwargs):
    """Write index.md, reference/cli.md and copy bench/ into the docs before they are read."""
    docs = pathlib.Path(config['docs_dir'])
    (docs / 'index.md').write_text(home_markdown(), encoding='utf-8')
    (docs / 'reference').mkdir(exist_ok=True)
    (docs / 'reference' / 'cli.md').write_text(cli_markdown(), encoding='utf-8')
    bench = docs / 'bench'
    bench.mkdir(exist_ok=True)
    for f in sorted((ROOT / 'bench').iterdir()):
        if f.suffix in ('.md', '.png', '.csv'):
            shutil.copy(f, bench / f.name)
