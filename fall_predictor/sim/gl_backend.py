"""An off-screen OpenGL back end for MuJoCo's renders, chosen before MuJoCo is imported.

MuJoCo picks its OpenGL back end once, at import, from ``MUJOCO_GL``; a back end the machine lacks
fails only at the first render, deep in a run. :func:`choose_mujoco_gl` keeps a user's choice,
else tries EGL (a GPU's driver, or Mesa's) and then OSMesa (software) each in a short-lived
process, and keeps the first that makes a context; if none does it says which to install.
PyBullet's renders need none of this: its TinyRenderer draws on the CPU.
"""
from __future__ import annotations

import os
import subprocess
import sys

from fall_predictor.errors import TeamFileError

#: The back ends tried, in order.
BACKENDS = ('egl', 'osmesa')
_PROBE = 'import mujoco; c = mujoco.GLContext(8, 8); c.make_current(); c.free()'


class NoOffscreenGL(TeamFileError):
    """No off-screen OpenGL back end works on this machine."""


def backend_works(name: str, timeout_s: float = 30.0) -> bool:
    """Whether MuJoCo makes an off-screen context with ``MUJOCO_GL=name`` (in a new process)."""
    env = dict(os.environ, MUJOCO_GL=name, PYOPENGL_PLATFORM=name)
    try:
        return subprocess.run([sys.executable, '-c', _PROBE], env=env, capture_output=True,
                              timeout=timeout_s).returncode == 0
    except (OSError, subprocess.TimeoutExpired):
        return False


def choose_mujoco_gl(probe=backend_works) -> str:
    """The back end MuJoCo will render with (``MUJOCO_GL`` set for this process); NoOffscreenGL
    saying what to install when none works. A ``MUJOCO_GL`` already set is kept (the user's
    choice), as is a back end MuJoCo was imported with."""
    chosen = os.environ.get('MUJOCO_GL')
    if chosen or 'mujoco' in sys.modules:
        return chosen or ''
    for name in BACKENDS:
        if probe(name):
            os.environ['MUJOCO_GL'] = name
            os.environ.setdefault('PYOPENGL_PLATFORM', name)
            return name
    raise NoOffscreenGL('MuJoCo finds no off-screen OpenGL (tried EGL and OSMesa)', field='MUJOCO_GL',
                        fix='install one (Debian/Ubuntu: apt install libegl1 for EGL, or '
                            'libosmesa6 for OSMesa) and set MUJOCO_GL=egl or osmesa, or render in '
                            'PyBullet (--simulator pybullet)')
