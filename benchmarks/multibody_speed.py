"""Cost of the general multibody engine (rbody.Multibody, Scene.from_layout) against rbody's hand-written
kernels, MuJoCo and Pinocchio, and the accuracy of rotations under rk4 in rbody and in MuJoCo.

    python benchmarks/multibody_speed.py [--repeats 3]

Prints the machine and versions, then
1. rk4, ns per step, one scene: the swinging rod (general engine vs its hand kernel), N-link chains N = 2, 8, 32
   (general engine: Scene.from_layout, which takes its planar path for these planar trees
   (rbody/engine/planar.py; benchmarks/planar_speed.py times the 3-D path beside it), the hand-written
   chain_rhs (the scene's hand_model(), whatever its native() runs), MuJoCo RK4 through mujoco.rollout, contacts and
   constraints disabled, the same model written by rbody.to_mjcf);
2. forward dynamics, ns per evaluation against N (the articulated-body algorithm over a batch of states),
   beside Pinocchio's pin.aba per call (from Python: its figure includes the call overhead) when installed;
3. 10^5 double pendulums in one rk4 batch: ns per pendulum-step (general engine and hand kernel);
4. a tumbling body (free joint, no gravity): error against the exact Jacobi-elliptic motion at three steps
   and the observed order, for rbody's rk4 (Runge-Kutta-Munthe-Kaas) and MuJoCo's RK4.
Every figure is the minimum over --repeats runs after a warm-up. Benchmarks are not tests; the machine may
be shared (the load average is printed): compare figures of one run with each other.
"""

from __future__ import annotations

import argparse
import os
import platform
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mujoco  # noqa: E402
import numba  # noqa: E402
from mujoco import rollout  # noqa: E402

import rbody  # noqa: E402
from rbody import Scene  # noqa: E402
from rbody.engine import integrators  # noqa: E402
from validation.machine import describe_machine  # noqa: E402

DT = 1e-3
MUJOCO_REPORTED_US = {2: 5.9, 8: 10.7, 32: 39.0}  # the MuJoCo figures, for reference


def best(function, repeats: int, clock=time.perf_counter) -> float:
    """Minimum time [s] of function() on `clock` (default wall time) over `repeats` runs after one warm-up."""
    function()
    times = []
    for _ in range(repeats):
        start = clock()
        function()
        times.append(clock() - start)
    return min(times)


def rk4_step_ns(model, steps: int, repeats: int) -> float:
    """ns per rk4 step of a native model (its whole batch), the compiled loop alone."""
    out = np.empty((2,) + model.y0.shape)
    seconds = best(lambda: integrators.run_rk4(model.rhs, model.y0, model.params, DT, steps, steps, out,
                                               finish=model.finish), repeats)
    return seconds / steps * 1e9


def mujoco_model(scene, dt: float = DT):
    model = mujoco.MjModel.from_xml_string(rbody.to_mjcf(scene, dt=dt, integrator="RK4"))
    model.opt.disableflags |= mujoco.mjtDisableBit.mjDSBL_CONTACT | mujoco.mjtDisableBit.mjDSBL_CONSTRAINT
    data = mujoco.MjData(model)
    mujoco.mj_resetDataKeyframe(model, data, 0)
    return model, data


def mujoco_step_ns(scene, steps: int, repeats: int) -> float:
    model, data = mujoco_model(scene)
    kind = mujoco.mjtState.mjSTATE_FULLPHYSICS
    state = np.empty(mujoco.mj_stateSize(model, kind))
    mujoco.mj_getState(model, data, state, kind)
    seconds = best(lambda: rollout.rollout(model, data, state[None], nstep=steps), repeats)
    return seconds / steps * 1e9


def chain(n: int):
    return rbody.scenes.pendulum_chain(n, theta0=np.linspace(0.3, 0.6, n), t_end=1.0)


def section_steps(repeats: int) -> None:
    print("\n1. rk4, ns per step, one scene (dt = 1e-3 s)")
    rod = rbody.scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0)
    rod_tree = Scene.from_layout(rod.layout, t_end=1.0)
    hand, tree = rk4_step_ns(rod.hand_model(), 200_000, repeats), rk4_step_ns(rod_tree.native_model, 50_000, repeats)
    print(f"   swinging rod: general engine {tree:9.0f}   hand kernel {hand:7.0f}   ratio {tree / hand:6.1f} "
          "(target <= 2)")
    print("   chain N   general engine   hand chain_rhs   MuJoCo RK4 (rollout)   MuJoCo / general (target >= 5)")
    for n in (2, 8, 32):
        scene = chain(n)
        tree_scene = Scene.from_layout(scene.layout, t_end=1.0)
        steps = 40_000 if n < 32 else 10_000
        general = rk4_step_ns(tree_scene.native_model, steps, repeats)
        handwritten = rk4_step_ns(scene.hand_model(), steps, repeats)
        theirs = mujoco_step_ns(scene, steps, repeats)
        print(f"   {n:7d}   {general:14.0f}   {handwritten:14.0f}   {theirs:20.0f}   {theirs / general:8.2f}"
              f"   (issue's MuJoCo figure {MUJOCO_REPORTED_US[n]} us)")


def section_forward(repeats: int) -> None:
    print("\n2. forward dynamics, ns per evaluation (ABA over a batch of 2000 random states)")
    try:
        import pinocchio as pin
    except ImportError:  # the benchmark peer is optional
        pin = None
    rng = np.random.default_rng(0)
    for n in (2, 8, 32):
        scene = chain(n)
        model = Scene.from_layout(scene.layout, t_end=1.0).multibody
        q, v, tau = (rng.uniform(-1, 1, (2000, model.nv)) for _ in range(3))
        ours = best(lambda: model.forward_dynamics(q, v, tau), repeats) / 2000 * 1e9
        line = f"   N = {n:2d}: rbody {ours:8.0f}"
        if pin is not None:
            line += f"   pinocchio pin.aba {pinocchio_aba_ns(pin, scene, q, v, tau, repeats)}"
        print(line)
    if pin is None:
        print("   (pinocchio not installed: no peer figure)")


def pinocchio_aba_ns(pin, scene, q, v, tau, repeats: int) -> str:
    """pin.aba per call [ns] on the model rbody.to_mjcf writes, called from Python (overhead included), and
    its largest difference from rbody's qacc; or why it could not be built."""
    import tempfile

    with tempfile.TemporaryDirectory() as folder:
        path = os.path.join(folder, "model.xml")
        with open(path, "w") as handle:
            handle.write(rbody.to_mjcf(scene))
        try:
            model = pin.buildModelFromMJCF(path)
        except Exception as error:  # noqa: BLE001 - report any failure of the optional peer
            return f"(could not read the MJCF: {type(error).__name__}: {str(error)[:60]})"
    data = model.createData()
    if model.nq != q.shape[1]:
        return f"(nq = {model.nq}, expected {q.shape[1]})"
    rows = [(np.ascontiguousarray(q[i]), np.ascontiguousarray(v[i]), np.ascontiguousarray(tau[i])) for i in range(200)]

    def calls():
        for qi, vi, ti in rows:
            pin.aba(model, data, qi, vi, ti)

    seconds = best(calls, repeats) / len(rows)
    return f"{seconds * 1e9:8.0f} per call from Python"


def section_batch(repeats: int) -> None:
    print("\n3. 10^5 double pendulums in one rk4 batch, ns per pendulum-step (target <= 50)")
    count = 100_000
    rng = np.random.default_rng(1)
    theta = rng.uniform(-1, 1, (count, 2))
    scene = rbody.scenes.pendulum_chain(2, theta0=theta, t_end=1.0)
    tree = Scene.from_layout(scene.item(0).layout, t_end=1.0, qpos0=np.column_stack([theta[:, 0], np.diff(theta)[:, 0]]))
    for name, model in (("general engine", tree.native_model), ("hand chain_rhs", scene.hand_model())):
        per = rk4_step_ns(model, 10, repeats) / count
        print(f"   {name}: {per:6.1f} ns per pendulum-step ({numba.get_num_threads()} threads)")


def section_rotation() -> None:
    print("\n4. tumbling body (free joint, no gravity, I = diag(1, 2, 2.5), omega0 = (0.3, 4, 0.5) rad/s, 3 s):")
    print("   max error of the quaternion against the exact motion, rbody rk4 (RKMK) and MuJoCo RK4")
    inertia = rbody.Inertia(1.0, np.zeros(3), np.diag([1.0, 2.0, 2.5]))
    exact_scene = rbody.scenes.free_rotation(inertia, omega0=[0.3, 4.0, 0.5], t_end=3.0)
    tree = Scene.from_layout(exact_scene.layout, t_end=3.0, gravity=0.0)
    errors = {"rbody": [], "mujoco": []}
    steps = (0.02, 0.01, 0.005)
    for dt in steps:
        run = rbody.simulate(tree, dt=dt, method="rk4")
        exact = exact_scene.exact(run.t)["quaternion"]
        errors["rbody"].append(float(np.max(np.abs(run["body.quat"] - exact))))
        model, data = mujoco_model(tree, dt)
        quats = [data.qpos[3:7].copy()]
        for _ in range(run.t.size - 1):
            mujoco.mj_step(model, data)
            quats.append(data.qpos[3:7].copy())
        quats = np.array(quats)
        quats *= np.sign(np.sum(quats * exact, axis=1))[:, None]
        errors["mujoco"].append(float(np.max(np.abs(quats - exact))))
    for name, values in errors.items():
        orders = [np.log2(values[i] / values[i + 1]) for i in range(len(values) - 1)]
        print(f"   {name:7s} " + "  ".join(f"dt={dt:g}: {e:.3e}" for dt, e in zip(steps, values))
              + "   observed orders " + ", ".join(f"{o:.2f}" for o in orders))


def print_header() -> None:
    """The machine, its load and the package versions, printed before the figures."""
    load = ", ".join(f"{x:.2f}" for x in os.getloadavg())
    print(f"machine    {describe_machine()}; numba threads {numba.get_num_threads()}; load avg {load}")
    print(f"versions   python {platform.python_version()}  numpy {np.__version__}  numba {numba.__version__}  "
          f"mujoco {mujoco.__version__}")


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeats", type=int, default=3)
    args = parser.parse_args()
    print_header()
    section_steps(args.repeats)
    section_forward(args.repeats)
    section_batch(args.repeats)
    section_rotation()


if __name__ == "__main__":
    main()
