"""The backends: one small module each, with `name`, `check(scene)` and
`run(scene, dt, t_end=None, **settings) -> rbody.Trajectory`.

`check` raises NotImplementedError saying what the simulator cannot model; `run` translates the
scene in, steps, and translates the result back into the scene's observables (scene.observe), so
that comparison code never knows who produced a trajectory.
"""

from __future__ import annotations

import importlib
from types import ModuleType

# The main command's engines (its scene table and baselines), and the peers that compare, and a URDF file, add.
BACKENDS = ("rbody", "mujoco", "pymunk")
PEERS = ("pinocchio", "bullet")
ENGINES = BACKENDS + PEERS
_MODULES = {"rbody": "validation.backends.native", "mujoco": "validation.backends.mujoco",
            "pymunk": "validation.backends.pymunk", "pinocchio": "validation.backends.pinocchio",
            "bullet": "validation.backends.bullet"}


def get(name: str) -> ModuleType:
    """The backend module called `name` (one of ENGINES). Raises ValueError for an unknown name, and
    NotImplementedError naming the package to install when the engine's package is missing (pinocchio: pin;
    bullet: pybullet, the extra rbody[bullet])."""
    if name not in _MODULES:
        raise ValueError(f"backend={name!r}: expected one of {', '.join(map(repr, ENGINES))}")
    try:
        return importlib.import_module(_MODULES[name])
    except ImportError as error:
        extra = {"bullet": "pip install 'rbody[bullet]' (pybullet)", "pinocchio": "pip install pin"}.get(name, "")
        raise NotImplementedError(f"engine {name!r} is not installed ({error}): {extra}") from None


def supports(scene, name: str) -> tuple[bool, str]:
    """(True, "") when backend `name` can run `scene` at its default settings, else (False, the reason it
    gives): what the simulator cannot model (check), and, where a backend has a `preflight(scene)`, what
    it would refuse when building the model (MuJoCo: a body its compiler rejects). Raises ValueError for
    an unknown backend or a `scene` that is not an rbody Scene."""
    from rbody.scene import Scene

    if not isinstance(scene, Scene):
        raise ValueError(f"scene={scene!r}: expected an rbody.Scene (see rbody.scenes)")
    try:
        module = get(name)
    except NotImplementedError as reason:
        return False, str(reason)
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
