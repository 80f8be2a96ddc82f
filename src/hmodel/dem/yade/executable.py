"""The YADE executable (https://yade-dem.org): ``$HMODEL_YADE`` if set, else ``yade`` on PATH."""

from __future__ import annotations

import os
import shutil

from .errors import YadeNotFound

INSTALL_HINT = "apt-get install -y yade"


def find_yade() -> str:
    """Path of the YADE executable (``$HMODEL_YADE`` or ``yade`` on PATH).

    Raises
    ------
    YadeNotFound
    """
    override = os.environ.get("HMODEL_YADE")
    if override:
        path = shutil.which(override)
        if path is None:
            raise YadeNotFound(f"YADE is not installed: HMODEL_YADE={override!r} is not an executable "
                               f"({INSTALL_HINT})")
        return path
    path = shutil.which("yade")
    if path is None:
        raise YadeNotFound(f"YADE is not installed: {INSTALL_HINT}")
    return path


def available() -> bool:
    """Whether a YADE executable can be found."""
    try:
        find_yade()
    except YadeNotFound:
        return False
    return True
