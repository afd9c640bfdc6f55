"""The README and docs/: short README, self-contained links, and facts that match the code
and the committed result files."""
import json
import re
from pathlib import Path
from urllib.parse import unquote

import pytest

from fall_predictor.contract.topics import TOPICS, topics_markdown_table
from fall_predictor.monitor.records import (CONTACT_MODE_NAMES, FALLEN_COM_HEIGHT_M, FEATURE_NAMES,
                                            GUARD_COM_HEIGHT_M, PUSH_DURATION_S)

ROOT = Path(__file__).resolve().parents[1]
README = ROOT / 'README.md'
DOCS = ROOT / 'docs'
RESULTS = DOCS / 'results.md'
METHOD = DOCS / 'method.md'
README_MAX_LINES = 250


def markdown_files() -> list[Path]:
    return [README, *sorted(DOCS.rglob('*.md'))]


def _without_code(text: str) -> str:
    """Markdown text with fenced code blocks and inline code removed (no links there)."""
    text = re.sub(r'^```.*?^```', '', text, flags=re.S | re.M)
    return re.sub(r'`[^`\n]*`', '', text)


#: ``[text](target)`` and ``![alt](target)``; the target ends at the first space or ``)``.
_LINK = re.compile(r'!?\[(?:[^\[\]]|\[[^\]]*\])*\]\(\s*<?([^)\s>]*)>?(?:\s+"[^"]*")?\s*\)')
#: Reference-style definitions: ``[label]: target``.
_REF_DEF = re.compile(r'^\s{0,3}\[[^\]]+\]:\s*<?(\S+?)>?(?:\s+.*)?$', re.M)


def links(path: Path) -> list[str]:
    text = _without_code(path.read_text(encoding='utf-8'))
    return _LINK.findall(text) + _REF_DEF.findall(text)


def heading_anchors(path: Path) -> set[str]:
    """GitHub-style anchors of the Markdown headings of ``path`` (duplicates get -1, -2, ...)."""
    text = re.sub(r'^```.*?^```', '', path.read_text(encoding='utf-8'), flags=re.S | re.M)
    anchors: set[str] = set()
    seen: dict[str, int] = {}
    for match in re.finditer(r'^#{1,6}\s+(.*?)\s*#*\s*$', text, flags=re.M):
        title = re.sub(r'!?\[([^\]]*)\]\([^)]*\)', r'\1', match.group(1))   # link -> its text
        slug = re.sub(r'[^\w\- ]', '', title.strip().lower()).replace(' ', '-')
        n = seen.get(slug, 0)
        seen[slug] = n + 1
        anchors.add(slug if n == 0 else f'{slug}-{n}')
    return anchors


def table_rows(text: str, first_header_cell: str) -> dict[str, list[str]]:
    """The body rows of the first Markdown table whose header's first cell is
    ``first_header_cell``, keyed by their first cell (cells stripped, ``**`` removed)."""
    lines = text.splitlines()
    for i, line in enumerate(lines):
        cells = [c.strip() for c in line.strip().strip('|').split('|')]
        if line.lstrip().startswith('|') and cells[0] == first_header_cell:
            rows = {}
            for row in lines[i + 2:]:
                if not row.lstrip().startswith('|'):
                    break
                cells = [c.strip().replace('**', '') for c in row.strip().strip('|').split('|')]
                rows[cells[0]] = cells[1:]
            return rows
    raise AssertionError(f'no table with first header cell {first_header_cell!r}')


def number(cell: str) -> float:
    """A table cell as a float (Unicode minus accepted)."""
    return float(cell.replace('−', '-'))


# -- README -----------------------------------------------------------------------------------

def test_readme_is_at_most_250_lines():
    n = len(README.read_text(encoding='utf-8').splitlines())
    assert n <= README_MAX_LINES, f'README.md has {n} lines (limit {README_MAX_LINES})'


def test_readme_topic_table_matches_the_contract():
    readme = README.read_text(encoding='utf-8')
    assert topics_markdown_table() in readme
    for spec in TOPICS:
        assert f'`{spec.ros_name}`' in readme


def test_readme_has_the_fresh_machine_commands_and_the_ros_usage():
    readme = README.read_text(encoding='utf-8')
    for needle in ('scripts/demo.sh', 'scripts/test.sh', 'colcon build', 'source install/setup.bash',
                   'ros2 launch fall_predictor fall_predictor.launch.py',
                   'ros2 launch fall_predictor monitor.launch.py', 'fall_predictor/state',
                   'examples/fall_consumer.py', 'config/monitor.yaml'):
        assert needle in readme, needle
    for script in ('scripts/demo.sh', 'scripts/test.sh', 'launch/fall_predictor.launch.py',
                   'launch/monitor.launch.py', 'examples/fall_consumer.py', 'config/monitor.yaml'):
        assert (ROOT / script).is_file(), script
    for node in ('simulator_node', 'controller_node', 'feature_node', 'predictor_node',
                 'recorder_node', 'fall_monitor'):
        assert f'`{node}`' in readme, node
    assert '[`docs/method.md`](docs/method.md)' in readme
    assert '[`docs/results.md`](docs/results.md)' in readme


def test_readme_cli_table_lists_exactly_the_cli_subcommands():
    import argparse

    from fall_predictor.cli import build_parser
    actions = [a for a in build_parser()._actions if isinstance(a, argparse._SubParsersAction)]
    assert len(actions) == 1
    subcommands = set(actions[0].choices)
    rows = table_rows(README.read_text(encoding='utf-8'), 'command')
    documented = {cell.strip('`').split()[0] for cell in rows}
    assert documented == subcommands


def test_contributing_layout_names_existing_sub_packages():
    rows = table_rows((ROOT / 'CONTRIBUTING.md').read_text(encoding='utf-8'), 'sub-package')
    assert len(rows) >= 6
    for cell in rows:
        assert (ROOT / cell.strip('`')).exists(), cell


# -- links --------------------------------------------------------------------------------------

@pytest.mark.parametrize('path', markdown_files(), ids=lambda p: str(p.relative_to(ROOT)))
def test_no_link_points_outside_the_repository(path):
    text = path.read_text(encoding='utf-8')
    for outside in ('../shared', 'SPEC.md', 'seed/000_'):   # machine paths: test_machine_paths.py
        assert outside not in text, f'{path.name} mentions {outside!r}'
    found = links(path)
    for target in found:
        if re.match(r'^(https?|mailto):', target):
            continue
        assert not re.match(r'^[a-zA-Z][a-zA-Z0-9+.-]*:', target), f'{path.name}: {target}'
        file_part, _, anchor = target.partition('#')
        assert not file_part.startswith('/'), f'{path.name}: absolute link {target}'
        resolved = (path.parent / unquote(file_part)).resolve() if file_part else path
        assert resolved == ROOT or ROOT in resolved.parents, \
            f'{path.name}: {target} points outside the repository'
        assert resolved.exists(), f'{path.name}: {target} does not exist'
        if anchor and resolved.suffix == '.md':
            assert anchor in heading_anchors(resolved), f'{path.name}: no heading for {target}'


def test_the_link_checker_catches_bad_links(tmp_path):
    page = tmp_path / 'page.md'
    page.write_text('# A title\n[x](../shared/SPEC.md) ![y](figures/a.png) [z](#a-title) '
                    '[w](#nope) `[no](code.md)`\n\n```\n[no](block.md)\n```\n[r]: ref.md\n')
    assert links(page) == ['../shared/SPEC.md', 'figures/a.png', '#a-title', '#nope', 'ref.md']
    assert heading_anchors(page) == {'a-title'}


# -- docs/results.md: the numbers agree with the committed result files ------------------------

@pytest.mark.parametrize('first_cell, evaluation_file', [
    ('default model (CV)', 'models/default_model.evaluation.json'),   # the shipped model's
    ('plain lists (CV)', 'docs/prediction/asimo_like/plain_lists/plain_model.evaluation.json'),  # the paper's lists
])
def test_results_table_2_analogue_matches_the_evaluation_and_the_papers_anchors(
        first_cell: str, evaluation_file: str) -> None:
    results = RESULTS.read_text(encoding='utf-8')
    table = table_rows(results, first_cell)
    evaluation = json.loads((ROOT / evaluation_file).read_text())
    cv = evaluation['cross_validated']
    # Columns: FP-L1 paper, ours, FP-L2 paper, ours, FP-L3 paper, ours.
    assert number(table['τ+ [s]'][3]) == cv['tau_plus_s'] == evaluation['tau_plus_s']
    assert number(table['τhis [s]'][3]) == cv['tau_his_s']
    assert number(table['FPR'][3]) == round(cv['fpr'], 3)
    assert number(table['τlead [s]'][3]) == round(cv['tau_lead_s'], 2)
    assert number(table['mean rule size'][3]) == round(cv['mean_rule_size'], 1)
    assert table['misses'][3] == f"{cv['n_missed']} / {cv['n_fallen']}"

    anchors = table_rows(METHOD.read_text(encoding='utf-8'), 'predictor')
    assert set(anchors) == {'FP-L1', 'FP-L2', 'FP-L3'}
    for column, name in ((0, 'FP-L1'), (2, 'FP-L2'), (4, 'FP-L3')):
        tau_plus, tau_his, fpr, tau_lead, rule_size = map(number, anchors[name])
        assert number(table['τ+ [s]'][column]) == tau_plus
        assert number(table['τhis [s]'][column]) == tau_his
        assert number(table['FPR'][column]) == fpr
        assert number(table['τlead [s]'][column]) == tau_lead
        assert number(table['mean rule size'][column]) == rule_size


def test_results_dataset_and_speed_figures_match_the_committed_json():
    results = RESULTS.read_text(encoding='utf-8')
    stats = json.loads((DOCS / 'robots' / 'asimo_like' / 'dataset_stats.json').read_text())
    assert f"**{stats['fall_fraction']:.3f}** over {stats['trajectories']} trajectories" in results
    lead = stats['oracle_lead_s']
    assert (f"median {lead['median']:.2f} s, mean {lead['mean']:.2f} s, max {lead['max']:.2f} s"
            in results)
    assert f"on {round(100 * stats['reflex_fired_fraction'])} % of trajectories" in results
    speed = json.loads((DOCS / 'scale_out' / 'sim_speed' / 'asimo_like_run1.json').read_text())
    full = speed['full_loop']
    assert (f"**{full['steps_per_s_wall']:.0f} steps/s = {full['real_time_factor_wall']:.2f}× "
            'real time**' in results)
    fig2 = json.loads((DOCS / 'robots' / 'asimo_like' / 'fig2.json').read_text())
    assert f"no fall below {fig2['smallest_force_that_fells_n']:.0f} N" in results


#: The page's sections, in order: each answers one question (no history, no issue numbers).
QUESTION_SECTIONS = ('the-robots-and-their-controllers', 'prediction-quality', 'falls-of-every-cause',
                     'time-to-fall-and-fall-direction', 'state-estimation-and-the-sensors',
                     'the-monitor-on-a-robot', 'scale-out-and-generation-speed', 'known-limitations',
                     'how-the-figures-are-rebuilt')
#: Robots and controllers: each has a subsection under the robots and under prediction quality.
ROBOTS_AND_CONTROLLERS = ('the-asimo-like-robot-under-c_bal', 'the-unitree-g1-under-c_bal',
                          'the-unitree-g1-under-unitrees-learned-walking-policy')


def _slug(title: str) -> str:
    title = re.sub(r'!?\[([^\]]*)\]\([^)]*\)', r'\1', title)
    return re.sub(r'[^\w\- ]', '', title.strip().lower()).replace(' ', '-')


def _sections(text: str) -> list[tuple[str, list[str]]]:
    """The page's ``##`` sections in order, each with the slugs of its ``###`` subsections."""
    text = re.sub(r'^```.*?^```', '', text, flags=re.S | re.M)
    sections: list[tuple[str, list[str]]] = []
    for level, title in re.findall(r'^(##|###)\s+(.*?)\s*$', text, flags=re.M):
        if level == '##':
            sections.append((_slug(title), []))
        else:
            sections[-1][1].append(_slug(title))
    return sections


def test_results_is_organised_by_question():
    text = RESULTS.read_text(encoding='utf-8')
    sections = _sections(text)
    assert [slug for slug, _ in sections] == list(QUESTION_SECTIONS)
    subsections = dict(sections)
    for robot in ROBOTS_AND_CONTROLLERS:
        assert robot in subsections['prediction-quality'], robot
        assert any(s.startswith(robot) for s in subsections['the-robots-and-their-controllers']), robot
    for topic in ('topics-and-streams', 'faults', 'speed-latency-and-cpu', 'the-executor'):
        assert topic in subsections['the-monitor-on-a-robot'], topic
    assert not re.search(r'\bissues?\s+\d', text, flags=re.I), 'an issue number on the page'
    assert not re.search(r'(?<![\w/.])#\d+\b', text), 'an issue number (#N) on the page'


#: The held-out tables of the shipped models: first header cell -> the folder of their
#: ``fall-predictor evaluate --json`` files (one per model, named after it) and baselines.json.
HELDOUT = {'ASIMO-like': DOCS / 'prediction' / 'asimo_like' / 'heldout',
           'G1': DOCS / 'prediction' / 'g1_c_bal' / 'heldout',
           "G1 under Unitree's policy": DOCS / 'prediction' / 'g1_unitree_rl' / 'heldout'}
#: The FPR budgets of each baseline table's columns, in order.
BUDGET_COLUMNS = {'ASIMO-like': (0.06, 0.01, 0.0), 'G1': (0.06, 0.01, 0.0),
                  "G1 under Unitree's policy": (0.06, 0.02, 0.01, 0.0)}
BASELINES = {'momentum': 'momentum', 'IMU tilt': 'imu_tilt', 'capture point': 'capture_point',
             'CoM height': 'com_height'}
#: ``N/M at LEAD`` or ``N/M = FPR [LO, HI] at LEAD``, optionally ``, MISSED``.
_ALARMS_AT = re.compile(r'^(\d+)/(\d+)(?: = ([\d.]+) \[([\d.]+), ([\d.]+)\])? at ([\d.]+)(?:, (\d+))?$')


def _fpr(e: dict) -> str:
    low, high = e['fpr_ci95']
    return f"{e['n_false_positives']}/{e['n_balanced']} = {e['fpr']:.3f} [{low:.3f}, {high:.3f}]"


@pytest.mark.parametrize('robot', sorted(HELDOUT))
def test_results_held_out_models_match_their_evaluations(robot: str) -> None:
    rows = table_rows(RESULTS.read_text(encoding='utf-8'), f'model ({robot}, held out)')
    files = sorted(HELDOUT[robot].glob('*_model.json'))
    assert {f'`{f.name}`' for f in files} == set(rows)
    for file in files:
        evaluation = json.loads(file.read_text())
        assert evaluation['model'] == f'models/{file.name}' and (ROOT / evaluation['model']).is_file()
        _settings, fpr, lead, missed, fraction = rows[f'`{file.name}`']
        assert fpr == _fpr(evaluation), file.name
        low, high = evaluation['tau_lead_ci95']
        assert lead == f"{evaluation['tau_lead_s']:.2f} [{low:.2f}, {high:.2f}]", file.name
        assert missed == f"{evaluation['n_missed']} / {evaluation['n_fallen']}", file.name
        assert number(fraction) == round(evaluation['tau_lead_s'] / evaluation['oracle_lead_s'], 2)


@pytest.mark.parametrize('robot', sorted(HELDOUT))
def test_results_held_out_baselines_match_their_json(robot: str) -> None:
    rows = table_rows(RESULTS.read_text(encoding='utf-8'), f'baseline ({robot}), budget')
    found = json.loads((HELDOUT[robot] / 'baselines.json').read_text())['baselines']
    by_budget = {(b['baseline'], b['fpr_budget']): b['test'] for b in found}
    checked = 0
    for name, key in BASELINES.items():
        for cell, budget in zip(rows[name], BUDGET_COLUMNS[robot]):
            match = _ALARMS_AT.match(cell)
            if not match:                        # words: "same", no threshold within the budget
                continue
            test = by_budget[key, budget]
            n_fp, n_balanced, fpr, low, high, lead, missed = match.groups()
            assert (int(n_fp), int(n_balanced)) == (test['n_false_positives'], test['n_balanced'])
            if fpr is not None:
                assert f'{n_fp}/{n_balanced} = {fpr} [{low}, {high}]' == _fpr(test), (name, budget)
            assert number(lead) == round(test['tau_lead_s'], 2), (name, budget)
            if missed is not None:
                assert int(missed) == test['n_missed'], (name, budget)
            checked += 1
    assert checked >= 8


def _cause_table_module():
    import importlib.util
    spec = importlib.util.spec_from_file_location('cause_table',
                                                  ROOT / 'scripts' / 'rebuild' / 'cause_table.py')
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


CAUSE_TABLES = DOCS / 'prediction' / 'causes.yaml'


def test_results_per_cause_tables_match_their_evaluations() -> None:
    """Every row of the per-cause tables (scripts/rebuild/cause_table.py from the evaluations
    docs/prediction/causes.yaml names) is on the results page as the script writes it."""
    cause_table = _cause_table_module()
    tables = cause_table.tables(CAUSE_TABLES)
    assert len(tables) >= 3 and all(len(lines) > 2 for lines in tables.values())
    assert cause_table.missing(CAUSE_TABLES, RESULTS) == []


def test_the_cause_table_check_fails_on_a_changed_figure(tmp_path) -> None:
    """The check can fail: a page whose first row says one false alarm more is caught."""
    cause_table = _cause_table_module()
    first_row = next(line for lines in cause_table.tables(CAUSE_TABLES).values()
                     for line in lines[2:] if line.startswith('|'))
    cells = first_row.split(' | ')
    cells[2] = '999/999'
    page = tmp_path / 'results.md'
    page.write_text(RESULTS.read_text(encoding='utf-8').replace(first_row, ' | '.join(cells)))
    assert first_row in cause_table.missing(CAUSE_TABLES, page)


# -- docs/method.md: the method with the numbers the code uses -------------------------------

def test_method_lists_the_contact_modes_and_features_of_the_code():
    method = METHOD.read_text(encoding='utf-8')
    section_7 = method.split('\n## 7.')[1].split('\n## 8.')[0]
    bullets = '\n'.join(line for line in section_7.splitlines() if line.startswith('- '))
    listed_modes = re.findall(r'`((?:LR|L|R)-[A-Z-]+|OUTSIDE)`', bullets)
    assert sorted(listed_modes) == sorted(CONTACT_MODE_NAMES)
    for name in FEATURE_NAMES:
        assert f'`{name}`' in method, name


def test_method_states_the_numbers_the_code_uses():
    method = METHOD.read_text(encoding='utf-8')
    sections = re.findall(r'^## (\d+)\. ', method, flags=re.M)
    assert sections == [str(i) for i in range(1, 14)]
    assert f'{GUARD_COM_HEIGHT_M:g} m' in method
    assert f'{FALLEN_COM_HEIGHT_M:g} m' in method
    assert f'{PUSH_DURATION_S:g} s' in method
    for needle in ('42.1 kg', '0.225 m', '0.157 m', 'U[0, 500] N', 'U[-180, 180] deg',
                   'U[-0.05, 0.25] m', 'weight 4', 'weight 1', '[t - tau_his, t]',
                   '[t_height_drop + tau_plus, t_fallen]', '10 folds', 'Wilson 95 %',
                   'U[0, 0.25] m/s', 'U[0.45, 0.7] s', 'U[0.16, 0.22] m', '10 %',
                   '[0, 1e7] s', '[0, 2] m', '20 m/s', '5e5 N', '2e5 N m'):
        assert needle in method, needle


# -- the typed interface ------------------------------------------------------------------------

def _msg_fields_and_constants(name: str) -> tuple[list[str], list[str]]:
    """Field names and constant names of msg/<name>.msg (comments stripped)."""
    fields, constants = [], []
    for line in (ROOT / 'msg' / f'{name}.msg').read_text().splitlines():
        line = line.split('#', 1)[0].strip()
        if not line:
            continue
        kind, rest = line.split(None, 1)
        if '=' in rest:
            constants.append(rest.split('=')[0].strip())
        else:
            fields.append(rest.strip())
    return fields, constants


def test_readme_describes_every_field_of_the_monitors_messages():
    """The README's interface bullets name every field of FallState and every status constant,
    and the events of FallEvent: a field added to the message must be documented."""
    readme = README.read_text(encoding='utf-8')
    fields, constants = _msg_fields_and_constants('FallState')
    for field in fields:
        if field != 'header':
            assert f'`{field}`' in readme, f'FallState.{field} is not in the README'
    for constant in constants:
        if constant.startswith('STATUS_'):
            assert f'`{constant}`' in readme, f'FallState.{constant} is not in the README'
    assert '`CONTACT_MODE_*`' in readme
    _, events = _msg_fields_and_constants('FallEvent')
    for event in events:
        assert event.removeprefix('EVENT_') in readme, f'FallEvent.{event} is not in the README'
