"""validation: the same rbody scenes in rbody, MuJoCo and pymunk, compared with the exact solution."""

from __future__ import annotations

from rbody.scene import Scene
from rbody.trajectory import Trajectory
from validation.backends import BACKENDS, ENGINES, PEERS, get, supports
from validation.comparison import Comparison, Divergence, check_baseline, compare, save_baseline


def run(scene: Scene, backend: str, *, dt: float, t_end: float | None = None, **settings) -> Trajectory:
    """Run `scene` in `backend` (one of ENGINES: "rbody", "mujoco", "pymunk", "pinocchio", "bullet") with step dt [s].

    Returns a Trajectory with the same observable names as the native run. Raises ValueError for
    an unknown backend (listing the valid ones) and NotImplementedError when the backend cannot
    model the scene (saying why).
    """
    module = get(backend)
    module.check(scene)
    return module.run(scene, dt, t_end, **settings)


__all__ = ["BACKENDS", "ENGINES", "PEERS", "Comparison", "Divergence", "check_baseline", "compare", "run", "save_baseline", "supports"]
