"""Optional dependencies: import them with an error that names the extra to install."""

from __future__ import annotations

import importlib
from types import ModuleType

# extra of pyproject.toml -> what it brings
EXTRAS = {
    "plots": "matplotlib and imageio (curves, GIFs)",
    "zoo": "rl_zoo3, optuna and psycopg (the rl-zoo3 bridge, --optimize)",
    "ray": "ray (benchmark --ray-address)",
    "football": "gfootball (the grf-* tasks; see scripts/install_football.sh)",
}


class MissingExtraError(ImportError):
    """An optional dependency is missing; the message names the extra that installs it."""


def require_extra(module: str, extra: str, purpose: str) -> ModuleType:
    """Import ``module`` or raise :class:`MissingExtraError` naming ``pip install 'sb3-saeir[<extra>]'``.

    :param module: module to import (e.g. ``"imageio.v2"``)
    :param extra: the package extra that provides it
    :param purpose: what needs it, for the message (e.g. ``"writing a GIF"``)
    """
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise MissingExtraError(
            f"{purpose} needs {module.split('.')[0]} ({error}); install the '{extra}' extra: "
            f"pip install 'sb3-saeir[{extra}]' (or bash scripts/install.sh {extra})."
        ) from error
