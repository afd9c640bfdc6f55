"""The figures the pages state, read from the committed JSON that holds each (``docs/figures.yaml``).

An entry of ``docs/figures.yaml``::

    - page: README.md
      text: "the lead {} s at FPR {}"          # the page's words, a {} for each figure
      values:                                  # one per {}, in order
        - docs/prediction/asimo_like/heldout/default_model.json:tau_lead_s .2f
        - max(docs/a.json:fpr, docs/b.json:fpr) .3f

A value is ``SOURCE FORMAT``. ``SOURCE`` is ``FILE:PATH``: a JSON file of the repository and the
path to a number in it, keys and list indices separated by ``/`` (``runs/*/robots/g1/x``: ``*``
takes every item; a ``.jsonl`` file is the list of its lines); or ``AGG(SOURCE, SOURCE, ...)``
with ``AGG`` one of min, max, median, sum, len over every number the sources give, or abs of one. ``FORMAT`` is the page's rounding as a Python format
spec (``.3f``; ``.3g``; ``100*.0f`` for a fraction written in percent; ``_d`` for a count
written ``20 001``); ``int`` for a count,
``str`` for a string as it is, ``numerator`` for N of a string ``N/M``. ``[field=value,...]`` in a
path keeps the items of a list (or the values of a mapping) with those fields.
"""
from __future__ import annotations

import json
import re
import statistics
from functools import lru_cache
from pathlib import Path
from typing import Any

import yaml

ROOT = Path(__file__).resolve().parents[1]
FIGURES = ROOT / 'docs' / 'figures.yaml'
AGGREGATES = {'min': min, 'max': max, 'median': statistics.median, 'sum': sum, 'len': len,
              'abs': lambda values: abs(values[0]) if len(values) == 1 else None}
_AGGREGATE = re.compile(r'^(\w+)\((.*)\)$')


@lru_cache(maxsize=None)
def _json(file: str) -> Any:
    """A JSON file, or a JSON-lines file as the list of its lines."""
    text = (ROOT / file).read_text()
    if file.endswith('.jsonl'):
        return [json.loads(line) for line in text.splitlines() if line.strip()]
    return json.loads(text)


def _walk(value: Any, keys: list[str], where: str) -> list[Any]:
    if not keys:
        return [value]
    key, rest = keys[0], keys[1:]
    if key == '*' or key.startswith('['):
        items = list(value.values() if isinstance(value, dict) else value)
        if key.startswith('['):                # [field=value,...]: the items with those fields
            wanted = dict(pair.split('=', 1) for pair in key.strip('[]').split(','))
            items = [item for item in items if all(_same(item.get(k), v) for k, v in wanted.items())]
            if not items:
                raise KeyError(f'{where}: no item with {key}')
        return [v for item in items for v in _walk(item, rest, where)]
    if isinstance(value, list):
        return _walk(value[int(key)], rest, where)
    if not isinstance(value, dict) or key not in value:
        raise KeyError(f'{where}: no {key!r}')
    return _walk(value[key], rest, where)


def _same(value: Any, text: str) -> bool:
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        try:
            return float(text) == value
        except ValueError:
            return False
    return str(value) == text


def numbers(source: str) -> list[Any]:
    """Every value ``source`` names (module docstring)."""
    source = source.strip()
    match = _AGGREGATE.match(source)
    if match and match.group(1) in AGGREGATES:
        values = [v for part in match.group(2).split(',') for v in numbers(part)]
        return [AGGREGATES[match.group(1)](values)]
    file, _, path = source.partition(':')
    return _walk(_json(file), [k for k in path.split('/') if k], source)


def formatted(spec: str) -> str:
    """A value of an entry as the page writes it."""
    source, _, fmt = spec.strip().rpartition(' ')
    values = numbers(source)
    if len(values) != 1:
        raise ValueError(f'{spec}: {len(values)} values, wrap the source in min/max/...')
    value = values[0]
    if fmt == 'int':
        return str(int(value))
    if fmt == 'str':
        return str(value)
    if fmt == 'numerator':                     # "5/32" -> "5"
        return str(value).split('/')[0]
    scale, _, fmt = fmt.rpartition('*')
    value = value * float(scale or 1)
    if fmt.endswith('d'):                      # a count; _d: thousands apart by a space (20 001)
        return format(int(value), fmt).replace('_', ' ')
    return format(value, fmt)


def entries() -> list[dict]:
    return yaml.safe_load(FIGURES.read_text())


def expected_text(entry: dict) -> str:
    """The entry's text with its figures filled in from the JSON."""
    return entry['text'].format(*(formatted(v) for v in entry.get('values', [])))


def page_text(page: str) -> str:
    """A page's text with its line breaks as spaces (a figure's words may wrap)."""
    return re.sub(r'\s*\n\s*', ' ', (ROOT / page).read_text(encoding='utf-8'))
