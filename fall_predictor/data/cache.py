"""Data derived from a dataset's bags (features, capture-point distances), cached beside them.

One cache for every kind of derived data: an entry ``DATA/cache/<name>.npz`` holds named
arrays, the key it was derived under and the fingerprint of the bag it was computed from. An
entry is used only if both match, so a bag that changed (rewritten, repaired, replaced) is
derived again, and so is an entry that cannot be read. Entries are written atomically.

The key names the kind of data and its settings, and holds the fingerprint of the code that
derived it (:func:`code_fingerprint`): the source of the deriving modules and of every module of
the package they import. A changed estimator or feature extractor derives its data again; no
version string has to be remembered.
"""
from __future__ import annotations

import ast
import functools
import hashlib
import importlib.util
from collections.abc import Callable, Iterable, Mapping
from pathlib import Path

import numpy as np

from fall_predictor.monitor.fileio import atomic_output


def bag_fingerprint(bag_dir: Path) -> str:
    """Identifies a bag's content cheaply: relative names, sizes and modification times of its
    files (also inside the parts of a split recording).

    Raises ``OSError`` if the bag directory cannot be listed.
    """
    h = hashlib.sha256()
    root = Path(bag_dir)
    for f in sorted(p for p in root.rglob('*') if p.is_file()):
        st = f.stat()
        h.update(f'{f.relative_to(root).as_posix()}:{st.st_size}:{st.st_mtime_ns};'.encode())
    return h.hexdigest()[:32]


PACKAGE = 'fall_predictor'


def _imported_modules(name: str, source: str) -> set[str]:
    """The package's modules that module ``name`` imports anywhere (also inside functions)."""
    out: set[str] = set()
    package = name if name.endswith('__init__') else name.rpartition('.')[0]
    for node in ast.walk(ast.parse(source)):
        if isinstance(node, ast.Import):
            out.update(alias.name for alias in node.names)
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ''
            if node.level:                               # relative: from .x import y
                parent = package.rsplit('.', node.level - 1)[0] if node.level > 1 else package
                base = f'{parent}.{base}' if base else parent
            out.add(base)
            out.update(f'{base}.{alias.name}' for alias in node.names)   # from pkg import module
    return {m for m in out if m == PACKAGE or m.startswith(PACKAGE + '.')}


def _module_source(name: str) -> tuple[str, str] | None:
    """(resolved name, source) of a module of the package; None for a name that is not a
    module (an attribute imported with ``from``)."""
    try:
        spec = importlib.util.find_spec(name)
    except (ImportError, ValueError):
        return None
    if spec is None or not spec.origin or not spec.origin.endswith('.py'):
        return None
    return name, Path(spec.origin).read_text(encoding='utf-8')


@functools.lru_cache(maxsize=None)
def code_fingerprint(modules: tuple[str, ...]) -> str:
    """Fingerprint of the code in ``modules`` (module names of the package) and in every module
    of the package they import, directly or not: a change to any of them changes it."""
    h = hashlib.sha256()
    seen: set[str] = set()
    todo = list(modules)
    sources: dict[str, str] = {}
    while todo:
        name = todo.pop()
        if name in seen:
            continue
        seen.add(name)
        found = _module_source(name)
        if found is None:
            continue
        sources[name] = found[1]
        todo.extend(_imported_modules(name, found[1]) - seen)
    for name in sorted(sources):
        h.update(f'{name}\0{sources[name]}\0'.encode())
    return h.hexdigest()[:16]


def files_fingerprint(files: Iterable[Path]) -> str:
    """Fingerprint of the content of ``files`` (data a derivation reads besides the bag, such
    as a robot profile); a missing file counts as empty."""
    h = hashlib.sha256()
    for f in sorted(Path(p) for p in files):
        h.update(f'{f.name}\0'.encode())
        h.update(f.read_bytes() if f.is_file() else b'')
    return h.hexdigest()[:16]


def derivation_key(kind: str, derived_by: Iterable[str], *extra: str) -> str:
    """The key of data of ``kind`` derived by the modules ``derived_by`` (and what they import)
    with the settings or inputs named by ``extra``."""
    return '&'.join([kind, f'code={code_fingerprint(tuple(sorted(derived_by)))}', *extra])


def cached_arrays(cache_file: Path, bag_dir: Path, kind: str,
                  compute: Callable[[], Mapping[str, np.ndarray]],
                  ) -> tuple[dict[str, np.ndarray], bool]:
    """The arrays derived from ``bag_dir``: from ``cache_file`` when it is up to date, else
    from ``compute()`` (then cached). Returns them and whether they were computed.

    ``kind`` is the derivation's key (:func:`derivation_key`: the kind of data, the code that
    derives it, its settings); ``compute`` may raise, and then nothing is cached. ``OSError``
    from fingerprinting the bag propagates.
    """
    fingerprint = bag_fingerprint(bag_dir)
    if cache_file.exists():
        try:
            with np.load(cache_file, allow_pickle=False) as z:
                if str(z['format']) == kind and str(z['fingerprint']) == fingerprint:
                    return {name: z[name] for name in z.files if name not in ('format', 'fingerprint')}, False
        except (OSError, ValueError, KeyError, EOFError):
            pass  # an unreadable entry is derived again from the bag
    arrays = {name: np.asarray(value) for name, value in compute().items()}
    if {'format', 'fingerprint'} & set(arrays):
        raise ValueError("derived arrays may not be named 'format' or 'fingerprint'")
    with atomic_output(cache_file) as temporary:
        np.savez(temporary, format=kind, fingerprint=fingerprint, **arrays)
    return arrays, True
