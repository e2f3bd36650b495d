"""The backends: one small module each, with `name`, `check(scene)` and
`run(scene, dt, t_end=None, **settings) -> rbody.Trajectory`.

`check` raises NotImplementedError saying what the simulator cannot model; `run` translates the
scene in, steps, and translates the result back into the scene's observables (scene.observe), so
that comparison code never knows who produced a trajectory.
"""

from __future__ import annotations

import importlib
from types import ModuleType

BACKENDS = ("rbody", "mujoco", "pymunk")
_MODULES = {"rbody": "validation.backends.native", "mujoco": "validation.backends.mujoco",
            "pymunk": "validation.backends.pymunk"}


def get(name: str) -> ModuleType:
    """The backend module called `name` (one of BACKENDS)."""
    if name not in _MODULES:
        raise ValueError(f"backend={name!r}: expected one of {', '.join(map(repr, BACKENDS))}")
    return importlib.import_module(_MODULES[name])


def supports(scene, name: str) -> tuple[bool, str]:
    """(True, "") when backend `name` can run `scene`, else (False, the reason it gives)."""
    try:
        get(name).check(scene)
    except NotImplementedError as reason:
        return False, str(reason)
    return True, ""
