"""Data derived from a dataset's bags (features, capture-point distances), cached beside them.

One cache for every kind of derived data: an entry ``DATA/cache/<name>.npz`` holds named
arrays, the kind's format string and the fingerprint of the bag it was computed from. An entry
is used only if both match, so a bag that changed (rewritten, repaired, replaced) is derived
again, and so is an entry that cannot be read. Entries are written atomically.
"""
from __future__ import annotations

import hashlib
from collections.abc import Callable, Mapping
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


def cached_arrays(cache_file: Path, bag_dir: Path, kind: str,
                  compute: Callable[[], Mapping[str, np.ndarray]],
                  ) -> tuple[dict[str, np.ndarray], bool]:
    """The arrays derived from ``bag_dir``: from ``cache_file`` when it is up to date, else
    from ``compute()`` (then cached). Returns them and whether they were computed.

    ``kind`` names the derived data and its version (``'fall_predictor/features-cache/v1'``);
    ``compute`` may raise, and then nothing is cached. ``OSError`` from fingerprinting the bag
    propagates.
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
