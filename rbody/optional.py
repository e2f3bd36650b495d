"""Optional dependencies: a clear ImportError naming the extra that installs one, instead of a bare traceback.

rbody's engine needs numpy, scipy, numba and trimesh only; what the peers and the reports need comes with
extras of the package (pyproject.toml): `validation` (MuJoCo, pymunk, matplotlib, Dask, mpmath), `exact`
(mpmath alone, for the exact collision counts of the pi scene).
"""

from __future__ import annotations

import importlib
from types import ModuleType


def optional(module: str, extra: str, needed_for: str) -> ModuleType:
    """The module `module`, imported; ImportError saying what needs it and `pip install "rbody[extra]"` when it
    is not installed."""
    try:
        return importlib.import_module(module)
    except ImportError as error:
        raise ImportError(f"{needed_for} needs the package {module!r}, which is not installed: "
                          f'python -m pip install "rbody[{extra}]" (or -e ".[{extra}]" from a checkout)') from error
