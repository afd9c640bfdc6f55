#!/usr/bin/env python3
"""Write ``models/README.md``: a card per shipped model, from the model files themselves, their
held-out evaluations and their measured cost (the JSON the results page shows), and the words
of ``models/cards.yaml`` (robot, controller, data, intended use, when to choose it, limits).

    python scripts/model_cards.py            # rewrite models/README.md
    python scripts/model_cards.py --check    # exit 1 if models/README.md is not what it would write

The figures are never typed by hand: change a model or its evaluation, run this, and the cards
follow (``test/test_model_cards.py`` fails until then).
"""
from __future__ import annotations

import argparse
import json
import sys
from pathlib import Path

import yaml

ROOT = Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / 'scripts' / 'rebuild'))
from heldout_table import fpr_cell  # noqa: E402  (the rebuild tables' cell, one format)
sys.path.insert(0, str(ROOT))
from fall_predictor.learning.deployment import cause_row, walking_line  # noqa: E402
MODELS = ROOT / 'models'
CARDS = MODELS / 'cards.yaml'
COST = 'docs/monitor/model_cost.json'   # benchmarks/bench_model_cost.py
OUT = MODELS / 'README.md'

HEADER = """# Shipped models

A model belongs to one robot **and its controller**: it has learned what that controller cannot
recover from. Each robot profile names its default model (`model:` in `profile.yaml`, per
controller under `controllers:`), which the nodes load when `robot:=NAME` is given without a
`model_path`. The figures below are held out: runs of a seed used for no choice, evaluated once
(FPR: survived runs with a false alarm, Wilson 95 %; lead: mean time from the alarm to the fall,
bootstrap 95 %; misses: falls not called before the robot was down). This page is written by
`python scripts/model_cards.py` from the model files, their evaluations and `cards.yaml`.

"""


def _load(path: str) -> dict:
    return json.loads((ROOT / path).read_text())


def _interval(values, digits: int) -> str:
    return f'[{values[0]:.{digits}f}, {values[1]:.{digits}f}]'


def _setting(model: dict) -> str:
    training = model['training']
    learner = training['learner']
    name = {'BoostedTreesLearner': 'boosted trees', 'TreeListLearner': 'decision lists (CART)',
            'CoveringListLearner': 'decision lists (covering)'}.get(learner['name'], learner['name'])
    attitude = len(model['input_names']) > len(model['feature_names'])
    parts = [name + (' on the features and the base\'s attitude' if attitude else ' on the 15 features')]
    if training.get('mirror'):
        parts.append('trained with mirror images')
    parts.append(f'τ+ {training["tau_plus_s"]:+.2f} s'.replace('-', '−'))
    threshold = learner['params'].get('decision_threshold')
    if threshold is not None:
        parts.append(f'decision threshold {threshold:g} (log-odds)')
    parts.append(f'τhis {model["recommended_tau_his_s"]:.3f} s')
    parts.append(f'{training["state"]} state')
    return ', '.join(parts)


def _heldout_row(e: dict) -> str:
    lead = f'{e["tau_lead_s"]:.2f} s {_interval(e["tau_lead_ci95"], 2)}'
    return (f'{fpr_cell(e)} | {lead} | {e["n_missed"]} / {e["n_fallen"]} | '
            f'{e["lead_fraction"]:.2f} | {e.get("n_pre_push_alarms", 0)}')


def _median(summary) -> str:
    return '—' if not summary or summary.get('median') is None else f'{summary["median"]:.3g}'


def _cost(name: str) -> str:
    """The model's onboard cost from the one run that timed every shipped model (cost JSON)."""
    run = _load(COST)
    row, reference = run['models'][name], run['reference']
    ref = run['models'][reference]
    ratio = row['ratio_to_reference']
    same_robot = row['robot'] == ref['robot']
    relative = ('the reference the other cards compare with' if name == reference else
                f'{ratio["features_plus_predictor"]:.2f}× `{reference}`\'s in the same run')
    return (f'{row["features_plus_predictor_us"]:.1f} µs a sample for the features and the model, '
            f'{relative}; the state estimator {row["estimator_us"]:.0f} µs'
            + ('' if same_robot else f' ({ratio["estimator"]:.2f}× the `{ref["robot"]}` robot\'s)')
            + f' ([JSON](../{COST}): CPU without ROS, all models in one process on a busy machine: '
            'the ratios carry over, the microseconds are that day\'s)')


def _remeasured_row(entry: dict) -> list[str]:
    if not entry.get('remeasured'):
        return []
    e = _load(entry['remeasured'])
    return [f'| {_heldout_row(e)} | {entry["remeasured_data"].strip()} ([evaluation]({Path("..") / entry["remeasured"]})) |']


def _cause_lines(entry: dict) -> list[str]:
    """The card's per-cause figures (``causes:`` in cards.yaml): the held-out runs of every cause,
    the same on randomised worlds, the ambiguous pushes, the hours of undisturbed walking."""
    causes = entry.get('causes')
    if not causes:
        return []
    lines = ['', f'**Per cause**, held out (the falls caught, the FPR over the survived runs, '
             f'alarms before the onset, the lead and its share of the time from the onset to the '
             f'fall; method §5):', '',
             '| runs | cause | falls caught | FPR [Wilson 95 %] (false alarms / survived) | alarms '
             'before onset | median lead [s] [95 %] | onset to fall [s] (median) | lead / onset '
             'to fall (median) |', '|---|---|---|---|---|---|---|---|']
    for key in ('nominal', 'randomized', 'ambiguous'):
        if key not in causes:
            continue
        e = _load(causes[key]['evaluation'])['deployment']
        label = f'[{causes[key]["label"].strip()}]({Path("..") / causes[key]["evaluation"]})'
        lines += [cause_row(f'{label} | {cause}', f) for cause, f in e['by_cause'].items()]
    for key in ('walking',):
        if key in causes:
            walking = walking_line(_load(causes[key]['evaluation'])['deployment']['walking'])
            lines += ['', f'{walking[0].upper()}{walking[1:]} ({causes[key]["label"].strip()}, '
                      f'[evaluation]({Path("..") / causes[key]["evaluation"]})).']
    return lines


def card(name: str, entry: dict) -> str:
    model = _load(f'models/{name}')
    e = _load(entry['heldout'])
    lines = [f'## `{name}`', '', entry['summary'].strip(), '',
             '| | |', '|---|---|',
             f'| robot, controller | `{entry["robot"]}` profile, {entry["controller"]} |',
             f'| learner and operating point | {_setting(model)} |',
             f'| trained on | {entry["data"].strip()} (fingerprint `{model["dataset_fingerprint"]}`) |',
             f'| training command | `{entry["command"].strip()}` |',
             f'| held out on | {entry["heldout_data"].strip()} ([evaluation]({Path("..") / entry["heldout"]})) |',
             '', '| FPR [95 %] | lead [95 %] | missed | lead / oracle | alarms before the push | runs |',
             '|---|---|---|---|---|---|', f'| {_heldout_row(e)} | the held-out set above |',
             *_remeasured_row(entry), *_cause_lines(entry), '',
             f'- **Time to fall** at its triggers, median error: {_median(e.get("time_to_fall_error_s"))} s; '
             f'**direction**, median error: {_median(e.get("direction_error_deg"))}° '
             f'(the momentum\'s: {_median(e.get("direction_error_deg_momentum"))}°).',
             f'- **Cost**: {_cost(name)}.',
             f'- **Choose it** {entry["choose"].strip()}',
             f'- **Limits**: {entry["limits"].strip()}', '']
    return '\n'.join(lines)


def summary_table(cards: dict) -> str:
    rows = ['| robot, controller | model | FPR held out | lead | choose it |', '|---|---|---|---|---|']
    for name, entry in cards.items():
        e = _load(entry['heldout'])
        default = ' (profile default)' if entry.get('default') else ''
        fpr = f'{e["fpr"]:.3f} {_interval(e["fpr_ci95"], 3)}'
        if entry.get('remeasured'):          # a second held-out measurement: both, the reading first
            again = _load(entry['remeasured'])
            fpr = (f'{entry["read_fpr_as"].strip()}: ' if entry.get('read_fpr_as') else '') + \
                f'{fpr}; {again["fpr"]:.3f} re-made'
        rows.append(f'| `{entry["robot"]}`, {entry["controller"]} | [`{name}`](#{name.replace(".", "")}){default} '
                    f'| {fpr} | {e["tau_lead_s"]:.2f} s '
                    f'| {entry["choose_short"].strip()} |')
    return '\n'.join(rows) + '\n'


def render() -> str:
    cards = yaml.safe_load(CARDS.read_text())
    return HEADER + summary_table(cards) + '\n' + '\n'.join(card(n, e) for n, e in cards.items())


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument('--check', action='store_true', help='exit 1 if models/README.md is stale')
    args = parser.parse_args(argv)
    text = render()
    if args.check:
        if OUT.read_text() != text:
            print(f'{OUT} is stale: run python scripts/model_cards.py', file=sys.stderr)
            return 1
        return 0
    OUT.write_text(text)
    print(f'wrote {OUT}')
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
