"""Derived-data cache keyed to the bag, the settings and the code that derived the data."""
import numpy as np
import pytest

from fall_predictor.data import cache
from fall_predictor.data.cache import (_imported_modules, cached_arrays, code_fingerprint,
                                       derivation_key, files_fingerprint)


def test_imports_are_found_also_inside_functions_and_relative_ones_resolved():
    source = ('import os\nfrom fall_predictor.monitor import features\n'
              'from .bagio import read_trajectory\n'
              'def f():\n    from fall_predictor.data.estimation import estimated_run\n')
    found = _imported_modules('fall_predictor.data.dataset', source)
    assert {'fall_predictor.monitor', 'fall_predictor.monitor.features', 'fall_predictor.data.bagio',
            'fall_predictor.data.estimation'} <= found
    assert 'os' not in found


def _fingerprint_with(monkeypatch, module, extra):
    """The fingerprint of the feature derivation with ``extra`` appended to ``module``'s source."""
    original = cache._module_source

    def patched(name):
        found = original(name)
        return (found[0], found[1] + extra) if found and name == module else found

    monkeypatch.setattr(cache, '_module_source', patched)
    code_fingerprint.cache_clear()
    try:
        return code_fingerprint(('fall_predictor.data.dataset',))
    finally:
        monkeypatch.setattr(cache, '_module_source', original)
        code_fingerprint.cache_clear()


def test_the_fingerprint_follows_the_code_the_derivation_imports_and_nothing_else(monkeypatch):
    code_fingerprint.cache_clear()
    base = code_fingerprint(('fall_predictor.data.dataset',))
    # The estimator is imported only inside a function of the dataset module, two levels down.
    assert _fingerprint_with(monkeypatch, 'fall_predictor.monitor.estimator', '\n# changed\n') != base
    assert _fingerprint_with(monkeypatch, 'fall_predictor.monitor.features', '\nX = 1\n') != base
    # Training code does not derive features: changing it keeps the cache.
    assert _fingerprint_with(monkeypatch, 'fall_predictor.learning.training', '\n# changed\n') == base
    assert code_fingerprint(('fall_predictor.data.dataset',)) == base


def test_files_fingerprint_follows_content(tmp_path):
    a = tmp_path / 'profile.yaml'
    a.write_text('sole_rpy_in_foot: [0, 0, 0]\n')
    first = files_fingerprint([a, tmp_path / 'absent.urdf'])
    a.write_text('sole_rpy_in_foot: [0, 0, 1]\n')
    assert files_fingerprint([a, tmp_path / 'absent.urdf']) != first


def test_an_entry_is_reused_only_under_the_same_key_and_bag(tmp_path):
    bag = tmp_path / 'bag'
    bag.mkdir()
    (bag / 'x.mcap').write_bytes(b'abc')
    calls = []

    def compute():
        calls.append(1)
        return {'x': np.arange(3)}

    entry = tmp_path / 'cache' / 'e.npz'
    key = derivation_key('kind/v1', ('fall_predictor.data.bagio',), 'settings=a')
    assert cached_arrays(entry, bag, key, compute)[1] is True
    arrays, built = cached_arrays(entry, bag, key, compute)
    assert built is False and np.array_equal(arrays['x'], np.arange(3)) and len(calls) == 1
    other = derivation_key('kind/v1', ('fall_predictor.data.bagio',), 'settings=b')
    assert cached_arrays(entry, bag, other, compute)[1] is True
    (bag / 'x.mcap').write_bytes(b'abcd')                      # the bag changed
    assert cached_arrays(entry, bag, other, compute)[1] is True
    entry.write_bytes(b'not an npz')                           # an unreadable entry
    assert cached_arrays(entry, bag, other, compute)[1] is True and len(calls) == 4
    with pytest.raises(ValueError, match='may not be named'):
        cached_arrays(tmp_path / 'f.npz', bag, key, lambda: {'format': np.zeros(1)})
