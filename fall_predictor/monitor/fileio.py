"""Atomic file output: a file is either its old self or completely new, never half written.

Every writer of the package (model files, dataset manifests and index rows, derived-data
caches, sweep results) goes through :func:`atomic_output`, so an interrupted run never leaves a
truncated file that a later run would trust.
"""
from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path


@contextmanager
def atomic_output(path: str | os.PathLike) -> Iterator[Path]:
    """Yield a temporary path beside ``path``; when the block ends without error, rename it
    onto ``path`` (one atomic ``os.replace``), else delete it.

    The temporary name keeps ``path``'s suffix, so writers that add one (``numpy.savez``) do
    not rename it, and holds the process id, so concurrent writers never share it. Files get
    the usual permissions (umask), unlike ``tempfile.mkstemp``'s 0600.
    """
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    temporary = path.with_name(f'.{path.stem}.{os.getpid()}.tmp{path.suffix}')
    try:
        yield temporary
        os.replace(temporary, path)
    finally:
        temporary.unlink(missing_ok=True)


def atomic_write_text(path: str | os.PathLike, text: str) -> None:
    """Write ``text`` (UTF-8) to ``path`` atomically."""
    with atomic_output(path) as temporary:
        temporary.write_text(text, encoding='utf-8')
