"""The package's own message definitions (``msg/*.msg``), as text: for tools that register the
types themselves (the rosbags type store of the bag tools).

Found in the source tree (``msg/`` beside the Python package) or, installed, in the package's share
folder (``share/fall_predictor/msg`` under a prefix of ``AMENT_PREFIX_PATH`` or of this Python).
"""
from __future__ import annotations

import os
import sys
from functools import lru_cache
from pathlib import Path

PACKAGE = 'fall_predictor'


def definitions_dir() -> Path:
    """The folder holding ``FallState.msg`` and the others (FileNotFoundError if none does)."""
    candidates = [Path(__file__).resolve().parents[2] / 'msg']
    prefixes = [p for p in os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep) if p]
    candidates += [Path(p) / 'share' / PACKAGE / 'msg' for p in (*prefixes, sys.prefix)]
    for folder in candidates:
        if (folder / 'FallState.msg').is_file():
            return folder
    raise FileNotFoundError(f'no {PACKAGE} message definitions in {[str(c) for c in candidates]}')


@lru_cache(maxsize=1)
def message_definitions() -> dict[str, str]:
    """``{'fall_predictor/msg/FallState': text, ...}`` for every message of the package."""
    return {f'{PACKAGE}/msg/{path.stem}': path.read_text()
            for path in sorted(definitions_dir().glob('*.msg'))}
