"""Mistakes in a team's own files, said in one line: which file, which field, what to do.

A robotics team brings its robot profile, URDF, MJCF, deploy config, network, models and
datasets; each reader of such a file raises a :class:`TeamFileError` subclass when the file is
wrong (``ProfileError``, ``PolicyConfigError``, ``TorchScriptError``, ``DescriptionError``,
``ModelFileError``, ...). The command line and the nodes print it as one line (:func:`one_line`)
and exit 2, the traceback only on request (``--debug``).

The package root: every sub-package may import it.
"""
from __future__ import annotations

from pathlib import Path
from typing import Optional, Union


class TeamFileError(ValueError):
    """A file a team wrote is missing, malformed, or does not fit the rest of its files.

    Built either from a message that already names the file and the field (the readers' style),
    or from its parts: ``TeamFileError(problem, file=..., field=..., fix=...)`` reads
    ``FILE: FIELD: PROBLEM; FIX``. ``file``, ``field`` and ``fix`` stay available as attributes
    (None when the message alone was given)."""

    def __init__(self, problem: str = '', *, file: Optional[Union[str, Path]] = None,
                 field: Optional[str] = None, fix: Optional[str] = None) -> None:
        self.problem = problem
        self.file = None if file is None else str(file)
        self.field = field
        self.fix = fix
        parts = [p for p in (self.file, field) if p]
        text = ': '.join(parts + [problem]) if parts else problem
        if fix:
            text += f'; {fix}'
        super().__init__(text)


#: ``--debug`` on the command line: the places that say an error in one line raise it instead.
_DEBUG = {'on': False}


def set_debug(on: bool) -> None:
    """Keep tracebacks (``--debug``): :func:`debug` tells the one-line printers."""
    _DEBUG['on'] = bool(on)


def debug() -> bool:
    return _DEBUG['on']


def one_line(error: Union[BaseException, str]) -> str:
    """``error``'s message on one line (a YAML or XML parser's multi-line message joined), with
    its type named when the message alone would not say what it is."""
    text = str(error) if not isinstance(error, str) else error
    lines = [line.strip() for line in text.splitlines() if line.strip()]
    text = '; '.join(dict.fromkeys(lines))          # parsers repeat the marker line
    if not isinstance(error, str) and not text:
        text = type(error).__name__
    return text
