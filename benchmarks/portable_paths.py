#!/usr/bin/env python3
"""Paths as a committed JSON file may hold them: relative to the repository, never a folder of the
machine that measured (``test/test_machine_paths.py`` fails on one in any tracked file).

* a path inside the repository: relative to its root (``data/d1000s``, ``docs/.../x.runs.csv``);
* a path in the temporary folder: ``<tmp>/`` and the rest (``<tmp>/bench_soak_x1/bags``): the name
  the logs and messages of that run used, without the machine's folder;
* any other absolute path: ``<outside the repository>/`` and its last component.

The benchmarks pass their JSON through :func:`portable` before writing it; a JSON written by
another command (``fall-predictor evaluate --json`` names its ``--per-run`` file as given) is
rewritten in place with::

    python benchmarks/portable_paths.py FILE.json [FILE.json ...]
"""
from __future__ import annotations

import json
import re
import sys
import tempfile
from pathlib import Path
from typing import Any

ROOT = Path(__file__).resolve().parents[1]
#: An absolute POSIX path: a string starting with ``/`` and a name, or such a path inside text
#: (a log line, a message), preceded by a space, a quote or ``=``.
_ABSOLUTE = re.compile(r'(?:^|(?<=[\s\'"=(]))/[A-Za-z0-9_.][^\s\'"(),;]*')


def portable_path(path: str | Path) -> str:
    """``path`` as a committed file may name it (module docstring)."""
    path = Path(path)
    if not path.is_absolute():
        return path.as_posix()
    resolved = path.resolve()
    for root, prefix in ((ROOT, ''), (Path(tempfile.gettempdir()).resolve(), '<tmp>/')):
        if resolved == root or root in resolved.parents:
            return prefix + (resolved.relative_to(root).as_posix() or '.')
    return f'<outside the repository>/{path.name}'


def _portable_text(text: str) -> str:
    return _ABSOLUTE.sub(lambda m: portable_path(m.group(0)) if _is_machine_path(m.group(0))
                         else m.group(0), text)


def _is_machine_path(text: str) -> bool:
    """A path of this machine's file system, not a ROS name (``/fall_predictor/state``): its
    first component exists here (``/tmp``, ``/home``) or it lies inside the repository."""
    first = text.split('/')[1]
    return bool(first) and Path('/', first).exists() and first not in ('dev', 'proc')


def portable(value: Any) -> Any:
    """A JSON value with every absolute path of this machine made portable (module docstring)."""
    if isinstance(value, dict):
        return {portable(k) if isinstance(k, str) else k: portable(v) for k, v in value.items()}
    if isinstance(value, (list, tuple)):
        return [portable(v) for v in value]
    if isinstance(value, str):
        return _portable_text(value)
    return value


def write_json(path: Path, value: Any, indent: int | None = 1) -> str:
    """Write ``value`` made portable to ``path`` (its folder created); return the text."""
    text = json.dumps(portable(value), indent=indent)
    path.parent.mkdir(parents=True, exist_ok=True)
    path.write_text(text + '\n')
    return text


def main(argv: list[str] | None = None) -> int:
    files = [Path(a) for a in (sys.argv[1:] if argv is None else argv)]
    if not files:
        print(__doc__, file=sys.stderr)
        return 2
    for file in files:             # the text edited where it names a path, its layout kept
        text = file.read_text()
        edited = _portable_text(text)
        if json.loads(edited) != portable(json.loads(text)):
            raise SystemExit(f'{file}: a path inside an escaped string; rewrite it by hand')
        if edited != text:
            file.write_text(edited)
    return 0


if __name__ == '__main__':
    raise SystemExit(main())
