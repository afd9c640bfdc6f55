"""Where the package's installed files (config, models, launch) are found."""
from __future__ import annotations

from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_share_directory

PACKAGE = 'fall_predictor'


DEFAULT_MODEL_NAME = 'default_model.json'


def default_model_path() -> Path:
    """``models/default_model.json`` of the package share directory (installed package) or of
    the source tree: the shipped model."""
    return package_share_dir() / 'models' / DEFAULT_MODEL_NAME


def package_share_dir() -> Path:
    """The package's share directory (``config/``, ``models/``, ``launch/``): from the ament
    index when the package is installed, else the source tree holding ``fall_predictor/``."""
    try:
        return Path(get_package_share_directory(PACKAGE))
    except (PackageNotFoundError, OSError):
        return Path(__file__).resolve().parents[2]
