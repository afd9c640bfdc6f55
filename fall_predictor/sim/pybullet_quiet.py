"""PyBullet, imported without the build banner it prints on stderr (a command's stderr is for
what went wrong: one line, and nothing else)."""
from __future__ import annotations

import os
import sys


def _quiet_import():
    sys.stderr.flush()
    try:
        saved = os.dup(2)
    except OSError:                         # no stderr to keep quiet
        import pybullet
        return pybullet
    try:
        with open(os.devnull, 'w') as null:
            os.dup2(null.fileno(), 2)
            import pybullet
    finally:
        os.dup2(saved, 2)
        os.close(saved)
    return pybullet


pb = _quiet_import()
