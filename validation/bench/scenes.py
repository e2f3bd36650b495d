"""The scenes of the speed-against-error benchmark, and the sweep of each backend on each.

The benchmark defines its own scenes rather than reusing validation/cases.py: a work-precision curve
needs a fixed duration and sampling that do not change with the main command's --quick, and
cases.py has no collision, free-rotation or chain case. Where cases.py has the scene, the physical
parameters are the same (rod L = 1 m, theta0 = 1 rad; disc of 2 kg, radius 0.25 m, pivot on its rim,
theta0 = 2 rad; disc rolling down 0.5 rad with friction 1; the four-body race on 0.3 rad).

Each scene gets, per backend, one Series per method or setting, each a sweep of dt from coarse to
fine (at least 6 values). The ranges are chosen per method so that each curve spans the errors the
method can reach (first-order methods go finer, sixth-order ones stop where round-off takes over)
within a bounded cost per run; they are the only tuning in the benchmark, and they are here.

MuJoCo settings: the backend's defaults (rbody.mjcf.to_mjcf: for impacts an undamped contact spring
K = (1/dt)^2 with solimp (0.99, 0.99, 0.001); for resting and rolling contact a critically damped
one of time constant 2 dt, elliptic cone, impratio 100; contacts and the constraint solver disabled on
models without contact pairs, validation.backends.mujoco.disable_unused) and the best found (measured
with this code, mujoco 4.0, by the sweeps that chose them):
- rolling: cone "pyramidal" and solimp (0.9999, 0.9999, 0.001) (MuJoCo's largest impedance): the
  slip of a soft contact scales with 1 - d, so the distance error at RK4 falls 100 to 1000 times
  (dt = 1e-3: 2.9e-10 m against 5.8e-7 m); the same with noslip_iterations = 20 as a third series
  (RK4: 6.0e-11 m at dt = 1e-3, 5.4e-13 m at 1e-4, falling as dt^2; without it 2.9e-10 and 3.4e-11 m);
  0.99999 is clamped to 0.9999.
  Beside the contact model, MuJoCo on rbody's own reduction (validation.bench.reduced): one slide
  with armature I/R^2 at each integrator, and a slide and a hinge tied by a joint equality (Euler, RK4).
- impacts: a stiffer spring K = 2/dt^2 (solref (-2/dt^2, 0)): the contact lasts fewer steps and the
  positions come out closer (line of three balls, dt = 1e-3: 9.7e-3 m against 1.5e-2 m; the pi scene
  counts right from dt = 3e-4 instead of 1e-4); K = 3/dt^2 and beyond blow up (omega dt > ~2) without
  MuJoCo noticing, a larger impedance (0.9999) miscounts more.
pymunk settings, per scene: its defaults (iterations 10, collision_slop 1e-6 of the smallest contact
shape; impacts: each shape's elasticity sqrt(e) so that the pair's product is e, exactly elastic) and,
as a second series, iterations 100 (pendulums, rolling, chain) or iterations 100 with collision_slop 0
(impacts): the defaults were the best found on every scene, more solver work buys nothing measurable
(on rolling, slop 0 makes the disc slip at coarse dt).
The peers (validation.backends.pinocchio and .bullet), on the scenes each can express:
- Pinocchio: its aba integrated by classical rk4 (the only scheme it is compared with: rbody's and MuJoCo's),
  on the contact-free trees (pendulums, free rotation, the chains); each step is a Python loop over aba calls,
  so its cost measures pin's Python bindings as much as its algorithm (stated in the summary).
- Bullet: semi-implicit Euler, its only integrator, so dt is its accuracy knob; on the trees nothing else
  matters (no constraint row reaches its solver: the same run at every solver setting), on contacts its
  sequential-impulse solver is swept: numSolverIterations 50 (Bullet's default) and 200 (the backend's), each
  at Bullet's contact ERP and at ERP 0.8 (split impulse on, restitution threshold 1e-6 m/s: the backend's).
"""


from __future__ import annotations

from dataclasses import dataclass
from typing import Any, Callable

import numpy as np

import rbody
from rbody import scenes
from rbody.scene import Scene

MUJOCO_INTEGRATORS = ("Euler", "RK4", "implicit", "implicitfast")
SAMPLES = 200  # error samples per run (the sampling interval is t_end / SAMPLES)


@dataclass(frozen=True)
class Series:
    """One curve: a backend with one method and one setting, over a sweep of dt.

    method:   rbody method, MuJoCo integrator, or "chipmunk" (pymunk has one)
    settings: a label of the settings ("default" or what differs from it)
    kwargs:   dt -> keyword settings for validation.run (MuJoCo's impact stiffness depends on dt)
    dts:      the time steps [s], coarse to fine (event-driven rbody: the sampling intervals)
    runner:   run(scene, dt, t_end, save_every=..., **kwargs) -> Trajectory in place of the backend's own
              (MuJoCo on rbody's reduction: validation.bench.reduced.run); None: the backend's
    """

    backend: str
    method: str
    settings: str
    kwargs: Callable[[float], dict]
    dts: tuple[float, ...]
    runner: Callable | None = None


@dataclass(frozen=True)
class BenchScene:
    """A scene of the benchmark.

    measure:   observable whose max abs error over the run is the error [its unit]
    reference: truth is rbody's "reference" run (DOP853, rtol 1e-13) instead of scene.exact
    counted:   impacts are counted; a run with the wrong count is a failure
    rolling:   a run whose slip exceeds SLIP_FRACTION of the peak exact speed is a failure
    """

    name: str
    scene: Scene
    measure: str
    unit: str
    series: tuple[Series, ...]
    reference: bool = False
    counted: bool = False
    rolling: bool = False
    note: str = ""


def sweep(coarse: float, fine: float, n: int, sample: float) -> tuple[float, ...]:
    """n time steps [s] from coarse to fine, geometric, each snapped to sample/k or sample*k (k whole)
    so that every run finer than the sampling interval `sample` is saved on the same time grid."""
    out = []
    for dt in np.geomspace(coarse, fine, n):
        snapped = sample / round(sample / dt) if dt <= sample else sample * round(dt / sample)
        if snapped not in out:
            out.append(float(snapped))
    return tuple(out)


def _fixed(**kwargs: Any) -> Callable[[float], dict]:
    return lambda dt: dict(kwargs)


def _rbody(scene: Scene, ranges: dict[str, tuple[float, float]], n: int, sample: float) -> list[Series]:
    """One series per method that applies (scene.methods without "reference", the chain's truth)."""
    if scene.event_driven:
        coarse, fine = ranges["events"]
        return [Series("rbody", "events", "exact impacts; dt = sampling only", _fixed(),
                       sweep(coarse, fine, n, sample))]
    series = []
    for method in scene.methods:
        if method == "reference":
            continue
        coarse, fine = ranges.get(method, ranges["*"])
        series.append(Series("rbody", method, "default", _fixed(method=method), sweep(coarse, fine, n, sample)))
    return series


def _mujoco(coarse: float, fine: float, n: int, sample: float, *best: tuple[str, Callable],
            quick: bool = False) -> list[Series]:
    """Every integrator at the backend's default contact settings and, unless quick, at each of the best
    found."""
    dts = sweep(coarse, fine, n, sample)
    series = []
    for integrator in MUJOCO_INTEGRATORS:
        series.append(Series("mujoco", integrator, "default", _fixed(integrator=integrator), dts))
        for label, settings in (() if quick else best):
            series.append(Series("mujoco", integrator, label,
                                 lambda dt, i=integrator, s=settings: dict(s(dt), integrator=i), dts))
    return series


def _pymunk(coarse: float, fine: float, n: int, sample: float, impacts: bool = False,
            quick: bool = False) -> list[Series]:
    """pymunk's defaults and, unless quick, more solver work (iterations 100, and slop 0 for impacts)."""
    dts = sweep(coarse, fine, n, sample)
    other = dict(iterations=100, collision_slop=0.0) if impacts else dict(iterations=100)
    label = ", ".join(f"{k}={v:g}" for k, v in other.items())
    series = [Series("pymunk", "chipmunk", "default", _fixed(), dts)]
    return series if quick else series + [Series("pymunk", "chipmunk", label, _fixed(**other), dts)]


ROLLING_BEST = ("cone=pyramidal, solimp=(0.9999, 0.9999, 0.001)",
                lambda dt: dict(cone="pyramidal", solimp=(0.9999, 0.9999, 0.001)))
ROLLING_NOSLIP = ("cone=pyramidal, solimp=(0.9999, 0.9999, 0.001), noslip_iterations=20",
                  lambda dt: dict(cone="pyramidal", solimp=(0.9999, 0.9999, 0.001), noslip_iterations=20))
# MuJoCo on rbody's reduction of rolling (validation.bench.reduced): variant -> integrators swept.
REDUCED_INTEGRATORS = {"slide": MUJOCO_INTEGRATORS, "slide+hinge": ("Euler", "RK4")}
REDUCED_LABEL = "reduced: "  # settings labels of MuJoCo series on rbody's reduction start with this


def _mujoco_reduced(coarse: float, fine: float, n: int, sample: float, quick: bool = False) -> list[Series]:
    """MuJoCo on the reduction rbody runs: one slide with armature I/R^2, and a slide and a hinge tied by a
    joint equality (quick: the slide at RK4 only)."""
    from validation.bench import reduced

    dts = sweep(coarse, fine, n, sample)
    variants = {"slide": ("RK4",)} if quick else REDUCED_INTEGRATORS
    labels = {"slide": "slide + armature I/R^2", "slide+hinge": "slide + hinge + joint equality x = R phi"}
    return [Series("mujoco", integrator, REDUCED_LABEL + labels[variant],
                   lambda dt, v=variant, i=integrator: dict(variant=v, integrator=i), dts, runner=reduced.run)
            for variant, integrators in variants.items() for integrator in integrators]
IMPACT_BEST = ("solref=(-2/dt^2, 0): stiffer spring", lambda dt: dict(solref=(-2.0 / dt**2, 0.0)))
BULLET_CONTACT_SETTINGS = (("solver_iterations=50 (Bullet's default)", dict(solver_iterations=50)),
                           ("solver_iterations=200", dict(solver_iterations=200)),
                           ("solver_iterations=50, erp=0.8", dict(solver_iterations=50, erp=0.8)),
                           ("solver_iterations=200, erp=0.8", dict(solver_iterations=200, erp=0.8)))


def _pinocchio(coarse: float, fine: float, n: int, sample: float) -> list[Series]:
    """Pinocchio's aba by rk4 (the scheme rbody and MuJoCo RK4 run)."""
    return [Series("pinocchio", "rk4", "default", _fixed(method="rk4"), sweep(coarse, fine, n, sample))]


def _bullet(coarse: float, fine: float, n: int, sample: float, contacts: bool = False,
            quick: bool = False) -> list[Series]:
    """Bullet's semi-implicit Euler over dt; with contacts, each solver setting of BULLET_CONTACT_SETTINGS (quick:
    the backend's 200 iterations only)."""
    dts = sweep(coarse, fine, n, sample)
    if not contacts:
        return [Series("bullet", "semi-implicit Euler", "default", _fixed(), dts)]
    chosen = BULLET_CONTACT_SETTINGS[1:2] if quick else BULLET_CONTACT_SETTINGS
    return [Series("bullet", "semi-implicit Euler", label, _fixed(**kwargs), dts) for label, kwargs in chosen]


def bench_scenes(quick: bool = False) -> list[BenchScene]:
    """Every scene of the benchmark; quick: shorter runs and sweeps, MuJoCo and pymunk at their default
    settings only (the smoke test)."""
    n = 6 if quick else 7
    out = []

    # --- pendulums: exact by Jacobi elliptic functions --------------------------------------------
    t_end = 2.0 if quick else 10.0
    sample = t_end / SAMPLES
    pendulum_ranges = {"euler": (1e-2, 1e-5 if quick else 1e-6), "symplectic_euler": (1e-1, 1e-5 if quick else 1e-6),
                       "verlet": (1e-1, 1e-5 if quick else 1e-6), "rk4": (2e-1, 1e-4),
                       "yoshida6": (2e-1, 2e-3 if quick else 1e-3), "gauss6": (2e-1, 2e-3 if quick else 1e-3),
                       "*": (1e-1, 1e-4)}
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=t_end)
    disc = rbody.Inertia.disc(2.0, 0.25, "y")
    compound = scenes.compound_pendulum(disc, pivot=(0.25, 0.0, 0.0), theta0=2.0, t_end=t_end,
                                        shapes=(rbody.Shape("disc", "cylinder", (0.25, 0.01),
                                                            quat=(np.sqrt(0.5), np.sqrt(0.5), 0, 0)),))
    for name, scene in (("swinging_rod", rod), ("compound_pendulum", compound)):
        series = (_rbody(scene, pendulum_ranges, n, sample)
                  + _mujoco(1e-1, 1e-3 if quick else 1e-4, n, sample, quick=quick)
                  + _pymunk(1e-1, 1e-4 if quick else 1e-5, n, sample, quick=quick)
                  + _pinocchio(2e-1, 2e-3 if quick else 1e-3, n, sample)
                  + _bullet(1e-2, 1e-4 if quick else 1e-5, n, sample))
        out.append(BenchScene(name, scene, "theta", "rad", tuple(series)))

    # --- rolling: constant accelerations, exact ---------------------------------------------------------
    exact_ranges = {"euler": (1e-1, 1e-5 if quick else 1e-6), "*": (1e-1, 1e-4)}
    # 1 s in both modes: with t_end = 0.5 s (a shorter incline in the layout) MuJoCo's disc slips by
    # 0.047 m/s in its first step at dt = 1e-2, a transient of the contact that 1 s does not show.
    rolling = scenes.rolling("disc", radius=0.1, incline=0.5, friction=1.0, t_end=1.0)
    race = scenes.rolling_race(("disc", "hollow_cylinder", "solid_sphere", "spherical_shell"), radius=0.1,
                               incline=0.3, length=0.5 if quick else 2.0)
    for name, scene in (("rolling_disc", rolling), ("rolling_race", race)):
        sample = scene.t_end / SAMPLES
        series = (_rbody(scene, exact_ranges, n, sample)
                  + _mujoco(1e-2, 1e-4 if quick else 1e-5, n, sample, ROLLING_BEST, ROLLING_NOSLIP, quick=quick)
                  + _mujoco_reduced(1e-1, 1e-4 if quick else 1e-5, n, sample, quick)
                  + _pymunk(1e-2, 1e-4 if quick else 1e-5, n, sample, quick=quick)
                  + _bullet(1e-2, 1e-4 if quick else 2e-5, n, sample, contacts=True, quick=quick))
        out.append(BenchScene(name, scene, "distance", "m", tuple(series), rolling=True))

    # --- impacts: event-driven and exact -----------------------------------------------------------------
    line = scenes.line_collisions([1.0, 2.0, 1.0], [0.5, 1.0, 1.5], [1.0, 0.0, -0.5], radii=0.05,
                                  walls=(0.0, 2.0), t_end=2.0 if quick else 5.0)
    if quick:  # 31 impacts in 5.9 s
        pi = scenes.pi_collisions(1, speed=0.1, spacing=0.2, radius=0.05)
    else:      # 314 impacts in 34 s; the heavy ball at 10^-digits m/s keeps the light one near 1 m/s
        pi = scenes.pi_collisions(2, speed=1e-2, spacing=0.05, radius=0.01)
    for name, scene in (("line_collisions", line), ("pi_collisions", pi)):
        sample = scene.t_end / SAMPLES
        events = {"events": (scene.t_end / 20, scene.t_end / (200 if quick else 2000))}
        series = (_rbody(scene, events, n, sample)
                  + _mujoco(3e-3, 3e-4 if quick else 1e-4, n, sample, IMPACT_BEST, quick=quick)
                  + _pymunk(3e-3, 1e-4 if quick else 3e-5, n, sample, impacts=True, quick=quick)
                  + _bullet(3e-3, 1e-4 if quick else 3e-5, n, sample, contacts=True, quick=quick))
        out.append(BenchScene(name, scene, "positions", "m", tuple(series), counted=True,
                              note=f"Exact count {int(scene.exact([scene.t_end])['collisions'][-1])} impacts; a run "
                                   "with another count is a failure"))

    # --- free rotation: Euler's equations, exact (MuJoCo only: pymunk is planar) ----------------------
    t_end = 2.0 if quick else 5.0
    sample = t_end / SAMPLES
    body = rbody.Inertia.box(1.0, (0.1, 0.2, 0.3))
    rotation = scenes.free_rotation(body, omega0=(1.0, 2.0, 3.0), t_end=t_end)
    rotation_ranges = {"euler": (1e-2, 1e-5 if quick else 1e-6), "splitting": (1e-1, 1e-5),
                       "rk4": (1e-1, 1e-4), "yoshida6": (1e-1, 1e-3), "gauss6": (1e-1, 1e-3), "*": (1e-1, 1e-4)}
    series = (_rbody(rotation, rotation_ranges, n, sample)
              + _mujoco(3e-2, 3e-4 if quick else 3e-5, n, sample, quick=quick)
              + _pinocchio(1e-1, 2e-3 if quick else 1e-3, n, sample)
              + _bullet(1e-2, 1e-4 if quick else 1e-5, n, sample))
    out.append(BenchScene("free_rotation", rotation, "omega_body", "rad/s", tuple(series)))

    # --- the chain: no closed form, truth from the tight reference run --------------------------------
    t_end = 2.0 if quick else 5.0
    sample = t_end / SAMPLES
    chain = scenes.pendulum_chain(3, theta0=(0.6, 0.4, 0.2), t_end=t_end)
    chain_ranges = {"euler": (1e-2, 1e-5 if quick else 1e-6), "rk4": (1e-1, 1e-4), "gauss6": (1e-1, 1e-3),
                    "*": (1e-1, 1e-4)}
    series = (_rbody(chain, chain_ranges, n, sample)
              + _mujoco(1e-2, 1e-4 if quick else 3e-5, n, sample, quick=quick)
              + _pymunk(1e-2, 1e-4 if quick else 1e-5, n, sample, quick=quick)
              + _pinocchio(1e-1, 2e-3 if quick else 1e-3, n, sample)
              + _bullet(1e-2, 1e-4 if quick else 1e-5, n, sample))
    out.append(BenchScene("pendulum_chain", chain, "theta", "rad", tuple(series), reference=True,
                          note="Truth: rbody's reference run (scipy DOP853, rtol 1e-13); the finest gauss6, rk4 and "
                               "MuJoCo RK4 runs agree with it to about 6e-14 rad, the floor of this measure"))

    # --- the same chain on the general engine: any Layout tree, by the articulated-body algorithm ----------
    general = Scene.from_layout(chain.layout, t_end=t_end, name="chain_general")
    series = (_rbody(general, chain_ranges, n, sample)
              + _mujoco(1e-2, 1e-4 if quick else 3e-5, n, sample, quick=quick))
    if quick:  # the smoke test: rk4 and gauss6 against MuJoCo's RK4
        series = tuple(s for s in series if s.method in ("rk4", "gauss6", "RK4") and s.backend != "pinocchio")
    out.append(BenchScene("chain_general", general, "qpos", "rad", tuple(series), reference=True,
                          note="The three-link chain above as a user's model: Scene.from_layout(chain.layout), run by "
                               "rbody's general engine (articulated-body algorithm) instead of the chain's own kernel; "
                               "truth: its reference run (DOP853, rtol 1e-13); MuJoCo with contacts and constraints "
                               "disabled"))
    return out
