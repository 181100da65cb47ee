"""The optional dependencies of the viewers (the ``viz`` extra) and the error when one is absent."""

from __future__ import annotations

import importlib
from types import ModuleType

from hubo_cli.errors import InputError

EXTRA_INSTALL = "pip install 'hubo-cli[viz]'"
# import name -> the package that provides it
PACKAGES = {"rerun": "rerun-sdk", "foxglove": "foxglove-sdk", "mcap": "mcap",
            "imageio_ffmpeg": "imageio-ffmpeg"}


class MissingOptionalDependency(InputError):
    """An optional package a command needs is not installed (exit code 2).

    Args:
        module: the import name that failed.
        purpose: what it is needed for (e.g. ``"the MP4 video"``).
    """

    def __init__(self, module: str, purpose: str) -> None:
        package = PACKAGES.get(module, module)
        super().__init__(f"{purpose} needs the package {package}, which is not installed",
                         hint=f"install the viewers' extra: {EXTRA_INSTALL} "
                              f"(or: pip install {package})")
        self.module = module
        self.package = package


def require(module: str, purpose: str) -> ModuleType:
    """Import an optional module or raise :class:`MissingOptionalDependency`."""
    try:
        return importlib.import_module(module)
    except ImportError as err:
        raise MissingOptionalDependency(module, purpose) from err
