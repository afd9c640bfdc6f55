"""Where the package's installed files (config, models, launch) are found."""
from __future__ import annotations

from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

from fall_predictor.profiles.profile import DEFAULT_ROBOT, load_profile

PACKAGE = 'fall_predictor'


def default_model_path(robot: str = DEFAULT_ROBOT) -> Path:
    """The shipped model of ``robot`` (a profile name or file) under its default controller, as
    its profile names it, in ``models/`` of the package share directory (installed package) or
    of the source tree. Raises ProfileError if the profile cannot be loaded."""
    return package_share_dir() / 'models' / load_profile(robot).model_for()


def package_share_dir() -> Path:
    """The package's share directory (``config/``, ``models/``, ``launch/``): from the ament
    index when the package is installed, else the source tree holding ``fall_predictor/``."""
    try:
        return Path(get_package_share_directory(PACKAGE))
    except (PackageNotFoundError, OSError):
        return Path(__file__).resolve().parents[2]
