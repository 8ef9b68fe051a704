"""Folders of the example models and scene files shipped with the package."""

import pathlib

_PACKAGE = pathlib.Path(__file__).parent

models = _PACKAGE / "models"
"""Folder of the example models shipped with the package (MJCF and URDF)."""
scenes = _PACKAGE / "scenes"
"""Folder of the example scene files shipped with the package (TOML, see `SceneFile`)."""
