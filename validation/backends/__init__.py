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
    """(True, "") when backend `name` can run `scene` at its default settings, else (False, the reason it
    gives): what the simulator cannot model (check), and, where a backend has a `preflight(scene)`, what
    it would refuse when building the model (MuJoCo: a body its compiler rejects). Raises ValueError for
    an unknown backend or a `scene` that is not an rbody Scene."""
    from rbody.scene import Scene

    module = get(name)
    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    try:
        module.check(scene)
        preflight = getattr(module, "preflight", None)
        if preflight is not None:
            preflight(scene)
    except (NotImplementedError, ValueError) as reason:  # ValueError: a layout the backend cannot build
        return False, str(reason)
    return True, ""
