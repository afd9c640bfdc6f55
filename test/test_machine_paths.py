"""No folder of one machine in any tracked file: a committed JSON, page, script or test names
files relative to the repository (``benchmarks/portable_paths.py`` makes a benchmark's paths so),
and a page's commands work from any clone."""
from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'benchmarks'))
from portable_paths import portable, portable_path  # noqa: E402

#: The roots of one machine's own folders: temporary, home, user, mounted, system-local ones.
MACHINE_ROOTS = ('tmp', 'home', 'root', 'work', 'Users', 'mnt', 'media', 'var', 'private',
                 'scratch', 'srv', 'opt', 'usr')
#: An absolute path under one of them, not inside a longer path or a URL.
MACHINE_PATH = re.compile(r'(?<![\w.~<>/{}()$-])/(?:' + '|'.join(MACHINE_ROOTS) + r')/[^\s\'"`)]*')
#: What must be absolute, and why.
ALLOWED = {
    '/usr/bin/env': 'a script\'s interpreter line: env finds the interpreter on any machine',
    '/usr/bin:/bin': 'the minimal PATH a test gives a child process',
    '/opt/ros/': 'where a ROS 2 install lives, in the instructions for one',
    '/opt/python/cp311-cp311': "the path baked into the ROS wheels' CMake files, which "
                                'scripts/build_interfaces.sh replaces',
}
#: Binary and bulky files: no text to read.
BINARY = ('.png', '.jpg', '.gif', '.pt', '.npz', '.onnx', '.mcap', '.db3', '.stl', '.dae', '.obj',
          '.so', '.zip')


def tracked_text_files() -> list[Path]:
    names = subprocess.run(['git', 'ls-files'], cwd=ROOT, capture_output=True, text=True,
                           check=True).stdout.splitlines()
    return [ROOT / n for n in names if not n.lower().endswith(BINARY) and (ROOT / n).is_file()]


def machine_paths(text: str) -> list[str]:
    found = (m.group(0).rstrip(',;:.') for m in MACHINE_PATH.finditer(text))
    return [path for path in found if not any(path.startswith(allowed) for allowed in ALLOWED)]


def test_the_check_finds_machine_paths_and_only_them():
    tmp, work, home = ('/' + root for root in ('tmp', 'work', 'home'))   # not one in this file
    text = (f'"per_run": "{tmp}/remeasure/x.runs.csv", default {work}/.mirror/repo, {home}/me/a '
            '#!/usr/bin/env bash; source /opt/ros/jazzy/setup.bash; https://example.org/tmp/x; '
            '`/fall_predictor/state`, docs/tmp/x, <tmp>/bench_x, /dev/zero')
    assert machine_paths(text) == [f'{tmp}/remeasure/x.runs.csv', f'{work}/.mirror/repo', f'{home}/me/a']


def test_no_tracked_file_names_a_folder_of_one_machine():
    files = tracked_text_files()
    assert len(files) > 100
    found = {}
    for path in files:
        try:
            text = path.read_text(encoding='utf-8')
        except UnicodeDecodeError:
            continue
        if hits := machine_paths(text):
            found[str(path.relative_to(ROOT))] = hits[:3]
    assert not found, f'machine paths in tracked files (benchmarks/portable_paths.py): {found}'


def test_each_per_run_file_an_evaluation_names_is_committed():
    """The held-out JSON name their per-run CSV by its place in the repository."""
    checked = 0
    for path in tracked_text_files():
        if path.suffix != '.json' or '"per_run"' not in path.read_text(encoding='utf-8'):
            continue
        per_run = json.loads(path.read_text())['per_run']
        if isinstance(per_run, str):             # a file's name (else the runs themselves)
            assert (ROOT / per_run).is_file(), (str(path.relative_to(ROOT)), per_run)
            checked += 1
    assert checked >= 10


def test_portable_paths_are_relative_to_the_repository_or_the_temporary_folder(tmp_path):
    assert portable_path(ROOT / 'docs' / 'results.md') == 'docs/results.md'
    assert portable_path('data/d1000s') == 'data/d1000s'
    in_tmp = portable_path(tmp_path / 'bags')          # pytest's tmp_path is in the temporary folder
    assert in_tmp.startswith('<tmp>/') and in_tmp.endswith(f'{tmp_path.name}/bags'), in_tmp
    value = {'dataset': str(tmp_path / 'data'), 'note': f'logs in {ROOT / "runs"} and /fall_predictor/state',
             'list': [str(ROOT / 'models' / 'g1_model.json')]}
    made = portable(value)
    assert made['list'] == ['models/g1_model.json']
    assert made['note'] == 'logs in runs and /fall_predictor/state'
    assert not machine_paths(json.dumps(made)), made


@pytest.mark.parametrize('name', ['bench_latency.py', 'bench_robot_streams.py', 'bench_soak.py'])
def test_benchmarks_that_record_folders_write_them_portable(name):
    assert 'portable(' in (ROOT / 'benchmarks' / name).read_text()


_DOCS_PATH = re.compile(r'(?<![\w/.-])(docs/[\w./-]+\.(?:json|jsonl|png|md|csv))')


def _strings(value):
    if isinstance(value, dict):
        for v in value.values():
            yield from _strings(v)
    elif isinstance(value, list):
        for v in value:
            yield from _strings(v)
    elif isinstance(value, str):
        yield value


def test_the_docs_paths_a_committed_json_names_are_where_the_files_are():
    """A command or output a JSON records names the folder of docs/ its file is committed in (not
    where it was written before the pages were reorganised), so that it can be run again."""
    wrong = {}
    for path in tracked_text_files():
        if path.suffix != '.json' or not path.is_relative_to(ROOT / 'docs'):
            continue
        for text in _strings(json.loads(path.read_text())):
            for named in _DOCS_PATH.findall(text):
                if not (ROOT / named).parent.is_dir():
                    wrong.setdefault(str(path.relative_to(ROOT)), set()).add(named)
    assert not wrong, wrong


def test_the_command_rewrites_a_json_in_place_keeping_its_layout(tmp_path):
    """What scripts/rebuild/ runs on evaluate's JSON: the per-run file named as the repository
    knows it, the rest of the text untouched."""
    import portable_paths
    csv = ROOT / 'docs' / 'prediction' / 'g1_c_bal' / 'heldout' / 'g1_model.runs.csv'
    file = tmp_path / 'g1_model.json'
    file.write_text(json.dumps({'fpr': 0.027, 'per_run': str(csv), 'model': 'models/g1_model.json'}))
    assert portable_paths.main([str(file)]) == 0
    assert file.read_text() == json.dumps({'fpr': 0.027, 'per_run': 'docs/prediction/g1_c_bal/heldout/g1_model.runs.csv',
                                           'model': 'models/g1_model.json'})
