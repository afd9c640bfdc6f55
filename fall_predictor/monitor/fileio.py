"""Safe file I/O: atomic output (a file is either its old self or completely new, never half
written), and bounded reads of regular files only.

Every writer of the package (model files, dataset manifests and index rows, derived-data
caches, sweep results) goes through :func:`atomic_output`, so an interrupted run never leaves a
truncated file that a later run would trust.
"""
from __future__ import annotations

import os
import stat
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


class UnsafeFileError(OSError):
    """A file that must not be read as data: not a regular file, or too large."""


def read_regular_file(path: str | os.PathLike, max_bytes: int) -> bytes:
    """The bytes of ``path`` if it is a regular file of at most ``max_bytes`` bytes.

    Opened without blocking and checked on the open descriptor before anything is read, so a
    FIFO does not hang the caller, a device (``/dev/zero``) is not read until memory runs out,
    and an oversized file costs no memory. Raises :class:`UnsafeFileError` (an ``OSError``)
    naming the problem, or the ``OSError`` of the open.
    """
    if max_bytes < 0:
        raise ValueError(f'max_bytes must be >= 0, got {max_bytes}')
    descriptor = os.open(path, os.O_RDONLY | os.O_NONBLOCK | getattr(os, 'O_CLOEXEC', 0))
    try:
        info = os.fstat(descriptor)
        if not stat.S_ISREG(info.st_mode):
            raise UnsafeFileError(f'{path}: not a regular file (mode {stat.filemode(info.st_mode)})')
        if info.st_size > max_bytes:
            raise UnsafeFileError(f'{path}: {info.st_size} bytes, more than the limit of '
                                  f'{max_bytes} bytes')
        with os.fdopen(descriptor, 'rb', closefd=False) as stream:
            data = stream.read(max_bytes + 1)
    finally:
        os.close(descriptor)
    if len(data) > max_bytes:       # the file grew while being read
        raise UnsafeFileError(f'{path}: more than the limit of {max_bytes} bytes')
    return data
