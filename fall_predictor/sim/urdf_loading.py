"""A robot profile's URDF made loadable by PyBullet.

Two things stand between a published URDF and PyBullet:

- mesh paths as ROS packages (``package://example-robot-data/robots/...``): PyBullet does not
  resolve them. They are rewritten to absolute paths, the package found on ``AMENT_PREFIX_PATH``
  (a ROS install) or in an installed Python distribution that ships it as data under
  ``cmeel.prefix/share/<package>`` (the ``example-robot-data`` wheel does);
- links with no ``<inertial>`` (frames: IMUs, cameras): PyBullet gives each 1 kg, which the real
  robot does not have (the G1 would weigh 37.3 kg, not 33.3 kg). They get a zero inertial.

The rewritten file is written once per source file and content into the user's cache directory.
"""
from __future__ import annotations

import hashlib
import importlib.metadata
import os
import re
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Optional

from fall_predictor.errors import TeamFileError

_PACKAGE_URI = re.compile(r'package://([^/"\s]+)/')
_ZERO_INERTIAL = ('<inertial><origin xyz="0 0 0" rpy="0 0 0"/><mass value="0"/>'
                  '<inertia ixx="0" ixy="0" ixz="0" iyy="0" iyz="0" izz="0"/></inertial>')


class MissingPackageError(TeamFileError, RuntimeError):
    """A mesh package the URDF names is not installed; the message says how to install it."""


def _distribution_share(package: str) -> Optional[Path]:
    """``cmeel.prefix/share/<package>`` of an installed distribution named like the package."""
    for name in (package, package.replace('_', '-')):
        try:
            dist = importlib.metadata.distribution(name)
        except importlib.metadata.PackageNotFoundError:
            continue
        path = Path(str(dist.locate_file(f'cmeel.prefix/share/{package}')))
        if path.is_dir():
            return path
    return None


def find_package(package: str) -> Path:
    """The share directory of ROS package ``package`` (MissingPackageError if none)."""
    for prefix in filter(None, os.environ.get('AMENT_PREFIX_PATH', '').split(os.pathsep)):
        path = Path(prefix) / 'share' / package
        if path.is_dir():
            return path
    found = _distribution_share(package)
    if found is None:
        raise MissingPackageError(
            f'the robot\'s URDF takes its meshes from the package {package!r}, which is not '
            f'installed: `pip install {package}` (or source a ROS install that has it)')
    return found


def resolve_urdf_text(text: str) -> str:
    """``text`` with ``package://`` paths made absolute and empty links given a zero inertial."""
    packages = {name: find_package(name) for name in set(_PACKAGE_URI.findall(text))}
    text = _PACKAGE_URI.sub(lambda m: f'{packages[m.group(1)]}/', text)
    root = ET.fromstring(text)
    empty = [link.get('name') for link in root.iter('link') if link.find('inertial') is None]
    for name in empty:
        # <link name="x"></link> or <link name="x"/>: give it the zero inertial.
        pattern = re.compile(rf'<link\s+name="{re.escape(name)}"\s*(/>|>\s*</link>)')
        text = pattern.sub(f'<link name="{name}">{_ZERO_INERTIAL}</link>', text, count=1)
    return text


#: A ``filename`` attribute naming a file relative to the URDF's folder (no scheme, not absolute).
_RELATIVE_FILENAME = re.compile(r'filename="(?![a-z]+://)(?!/)([^"]+)"')


def missing_mesh_files(path: Path) -> list[str]:
    """The mesh files the URDF at ``path`` names that are not there (``package://`` resolved;
    MissingPackageError for a package not installed)."""
    root = ET.fromstring(resolve_urdf_text(Path(path).read_text()))
    folder = Path(path).resolve().parent
    missing = []
    for mesh in root.iter('mesh'):
        name = mesh.get('filename', '')
        if '://' in name and not name.startswith('file://'):
            continue
        file = Path(name.removeprefix('file://'))
        if not (file if file.is_absolute() else folder / file).is_file():
            missing.append(name)
    return list(dict.fromkeys(missing))


def _cache_dir() -> Path:
    base = os.environ.get('XDG_CACHE_HOME') or os.path.join(os.path.expanduser('~'), '.cache')
    return Path(base) / 'fall_predictor' / 'urdf'


def pybullet_urdf(path: Path) -> Path:
    """A file PyBullet can load for the URDF at ``path``: ``path`` itself when nothing needs
    rewriting, else the rewritten copy in the cache."""
    text = Path(path).read_text()
    resolved = resolve_urdf_text(text)
    if resolved == text:
        return Path(path)
    # The copy lives elsewhere: mesh files named relative to the URDF's folder are named whole.
    folder = Path(path).resolve().parent
    resolved = _RELATIVE_FILENAME.sub(lambda m: f'filename="{folder / m.group(1)}"', resolved)
    digest = hashlib.sha256(resolved.encode()).hexdigest()[:16]
    out = _cache_dir() / f'{Path(path).stem}-{digest}.urdf'
    if not out.exists():
        out.parent.mkdir(parents=True, exist_ok=True)
        tmp = out.with_suffix(f'.tmp{os.getpid()}')
        tmp.write_text(resolved)
        os.replace(tmp, out)
    return out
