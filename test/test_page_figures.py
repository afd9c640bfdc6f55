"""Each figure the pages state is the one its committed JSON holds (``docs/figures.yaml``,
read by ``page_figures``): a page that says another figure, or a JSON measured again, fails
here until the page is written again."""
from __future__ import annotations

import json

import pytest

import page_figures
from page_figures import ROOT, entries, expected_text, formatted, numbers, page_text

ENTRIES = entries()


def _id(entry: dict) -> str:
    return f"{entry['page']}: {entry['text'][:50]}"


@pytest.mark.parametrize('entry', ENTRIES, ids=[_id(e) for e in ENTRIES])
def test_the_page_states_the_figures_of_its_json(entry):
    text = expected_text(entry)
    assert text in page_text(entry['page']), f'{entry["page"]} should say: {text}'


def test_every_page_and_json_of_the_table_is_in_the_repository():
    assert len(ENTRIES) >= 25
    for entry in ENTRIES:
        assert (ROOT / entry['page']).is_file(), entry['page']
        assert entry['text'].count('{}') == len(entry.get('values', [])), _id(entry)


def test_sources_paths_selectors_aggregates_and_formats(tmp_path, monkeypatch):
    data = {'runs': [{'x': 1.04, 'n': '5/32'}, {'x': 2.5}],
            'rows': [{'name': 'a', 'budget': 0.06, 'v': 0.123}, {'name': 'b', 'budget': 0.0, 'v': 0.5}],
            'by': {'m1': {'robot': 'g1', 'r': 1.3}, 'm2': {'robot': 'g1', 'r': 1.31}, 'm3': {'robot': 'x', 'r': 9}}}
    monkeypatch.setattr(page_figures, '_json', lambda file: data)
    assert numbers('f.json:runs/*/x') == [1.04, 2.5]
    assert numbers('max(f.json:runs/*/x, f.json:rows/1/v)') == [2.5]
    assert formatted('f.json:rows/[name=a,budget=0.06]/v .3f') == '0.123'
    assert formatted('min(f.json:by/[robot=g1]/r) .2f') == '1.30'
    assert formatted('f.json:rows/1/v 100*.0f') == '50'
    assert formatted('f.json:runs/0/n numerator') == '5'
    with pytest.raises(ValueError):
        formatted('f.json:runs/*/x .1f')              # two values where the page states one
    with pytest.raises(KeyError):
        formatted('f.json:rows/[name=c]/v .1f')


def test_a_changed_measurement_fails_the_page(monkeypatch):
    """The check can fail: the first entry's JSON with its first figure moved."""
    entry = ENTRIES[0]
    source = entry['values'][0].rsplit(' ', 1)[0]
    file, _, path = source.partition(':')
    changed = json.loads((ROOT / file).read_text())
    keys = path.split('/')
    node = changed
    for key in keys[:-1]:
        node = node[int(key)] if isinstance(node, list) else node[key]
    node[keys[-1]] += 0.5
    original = page_figures._json
    monkeypatch.setattr(page_figures, '_json', lambda f: changed if f == file else original(f))
    assert expected_text(entry) not in page_text(entry['page'])
