"""Cross-simulator comparison of one model: run it in rbody, MuJoCo and pymunk, see where they disagree.

    comparison = compare(scene_or_path, engines=("rbody", "mujoco"), dt=1e-3, t_end=2.0, method="rk4")
    print(comparison.table())            # one row per observable and engine pair: max divergence, when
    comparison.assert_agree({"qpos": 1e-9, "energy": 1e-8})   # a test helper: AssertionError on a breach
    comparison.save_figure("divergence.png")
    found = check_baseline(comparison, "tests/baselines")       # [] or one message per regression

The model is an rbody Scene (one of rbody.scenes, a Scene.from_layout, or a user's subclass), a path to an
MJCF file, or "module:name" / "file.py:name" naming a Scene or a function returning one. A file is run as the
user runs it (validation.mujoco_file): MuJoCo compiles the file itself (not rbody's re-export), at its own step
with its own integrator, and rbody reads it (rbody.from_mjcf) and runs it with the file's integrator
(scene.file_method: mujoco_euler, implicitfast, implicit or rk4), both from the same state (reference pose,
keyframe=, qpos0=, qvel0=) under the same controls (ctrl=: a constant, an (n_steps, nu) array or a callable
ctrl(t, qpos, qvel)); when rbody refuses the file, the reason is rbody's row and MuJoCo still
runs. Every engine that can express the model runs it at the same dt over the same duration;
an engine that cannot is listed as refused with its reason (validation.backends.supports), an engine
whose run fails (a blow-up) as failed with its error: nothing is dropped.

The divergence of an observable between two engines at time t is the Euclidean norm of the difference
of their values over the observable's components, in its own unit (rad, m, J, ...); for an orientation
(an observable ending in ".quat") it is the angle of the rotation between the two [rad], which does not
see a quaternion's sign. Where the scene has a closed form (rbody's own scenes, scene.exact), each engine
is also compared with it, as the pair (engine, "exact").

Defaults, chosen to compare like with like: dt is the scene's own timestep when it has one (an MJCF
<option timestep>), else 1 ms; for a file, both engines run the file's integrator; otherwise rbody's method is
"rk4" wherever it applies, the scheme MuJoCo's RK4 uses on contact-free models, so that rbody and MuJoCo differ
by their models, not by their integrators. MuJoCo and
pymunk run at their backends' documented defaults (validation/backends).
"""

from __future__ import annotations

import dataclasses
import importlib
import importlib.util
import math
import time
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Iterable, Mapping, Sequence

import numpy as np

import rbody
from rbody.checks import run_times
from rbody.files import atomic_path, write_atomic
from rbody.scene import Scene
from rbody.trajectory import Trajectory
from validation import baselines
from validation.backends import BACKENDS, ENGINES, get, supports

EXACT = "exact"
DEFAULT_DT = 1e-3
MJCF_SUFFIXES = (".xml", ".mjcf")
URDF_SUFFIXES = (".urdf",)


# ----- what a comparison holds ----------------------------------------------------------------------------

@dataclass(frozen=True)
class EngineRun:
    """One engine's run: status "ran", "refused" (cannot express the model) or "failed" (raised).

    trajectory: the run (None unless it ran); seconds: wall time of the stepping [s]; note: the reason
    for a refusal or the error of a failure."""

    engine: str
    status: str
    trajectory: Trajectory | None = None
    seconds: float = 0.0
    note: str = ""


@dataclass(frozen=True)
class Divergence:
    """The largest divergence of one observable between two engines (or an engine and the exact solution).

    observable: its name; engines: (a, b); largest: max over the run of |a(t) - b(t)| [unit of the
    observable; rad for an orientation], inf when one side became non-finite; time: when it happens [s]."""

    observable: str
    engines: tuple[str, str]
    largest: float
    time: float

    @property
    def pair(self) -> str:
        """"rbody-mujoco": the label of the engine pair (also its baseline file name)."""
        return "-".join(self.engines)


@dataclass(frozen=True)
class Comparison:
    """The result of compare(): the runs, the table of divergences and the divergence against time.

    scene:  the model that was run; dt, t_end [s]; method: rbody's method
    runs:   engine -> EngineRun, in the order asked for
    rows:   one Divergence per (observable, engine pair), observables in the scene's order
    t:      (T,) the common times [s] of the curves
    curves: (observable, pair) -> (T,) divergence against time
    """

    scene: Scene
    dt: float
    t_end: float
    method: str | None
    runs: Mapping[str, EngineRun]
    rows: tuple[Divergence, ...]
    t: np.ndarray
    curves: Mapping[tuple[str, str], np.ndarray] = field(repr=False)
    source: str | None = None

    @property
    def trajectories(self) -> dict[str, Trajectory]:
        """engine -> Trajectory of every engine that ran."""
        return {e: r.trajectory for e, r in self.runs.items() if r.status == "ran"}

    @property
    def observables(self) -> tuple[str, ...]:
        return tuple(dict.fromkeys(r.observable for r in self.rows))

    def row(self, observable: str, a: str, b: str) -> Divergence:
        """The row of `observable` between engines a and b (in either order)."""
        for r in self.rows:
            if r.observable == observable and set(r.engines) == {a, b}:
                return r
        raise KeyError(f"no row for {observable!r} between {a!r} and {b!r}; rows: "
                       f"{sorted({(r.observable, r.pair) for r in self.rows})}")

    # ----- the test helper ------------------------------------------------------------------------

    def assert_agree(self, tolerances: float | Mapping[str, float], *, between: Iterable[str] | None = None) -> None:
        """Raise AssertionError listing every breach: an observable whose divergence between two engines
        (or from the exact solution) exceeds its tolerance, and every engine whose run failed.

        tolerances: one bound for every observable, or observable -> bound (in the observable's unit;
        "*" sets the bound of the observables not named; observables not named and no "*": not checked).
        between:    only the pairs of these engines ("exact" for the closed form), e.g. ("rbody", "mujoco")
                    for a tight bound where both run the same scheme; default every pair
        Raises ValueError for a tolerance that is negative or not a number, or that names an observable
        the comparison does not have, or an engine in `between` it did not try (a typo would otherwise check
        nothing)."""
        bounds = _tolerances(tolerances, self.observables)
        chosen = set(self.runs) | {EXACT}
        if between is not None:
            chosen = {between} if isinstance(between, str) else set(between)
            unknown = chosen - set(self.runs) - {EXACT}
            if unknown:
                raise ValueError(f"between={sorted(unknown)}: not engines of this comparison ({list(self.runs)})")
        breaches = [f"engine {e} failed: {r.note}" for e, r in self.runs.items()
                    if r.status == "failed" and e in chosen]
        checked = 0
        for r in self.rows:
            bound = bounds.get(r.observable, bounds.get("*"))
            if bound is None or not set(r.engines) <= chosen:
                continue
            checked += 1
            if not r.largest <= bound:
                breaches.append(f"{r.observable} {r.pair}: {r.largest:.3g} > {bound:.3g} at t = {r.time:.6g} s")
        if not checked and not breaches:
            ran = ", ".join(self.trajectories) or "none"
            raise AssertionError(f"nothing was compared: engines that ran: {ran}; refused: "
                                 + "; ".join(f"{e} ({r.note})" for e, r in self.runs.items() if r.status == "refused"))
        if breaches:
            raise AssertionError(f"{self.scene.name}: {len(breaches)} breach(es) of the tolerances\n  "
                                 + "\n  ".join(breaches))

    # ----- text --------------------------------------------------------------------------------------

    def table(self, *, markdown: bool = False) -> str:
        """One line per observable and engine pair: the largest divergence and when it happens."""
        header = ("observable", "engines", "max divergence", "at t [s]")
        lines = [(r.observable, r.pair, f"{r.largest:.3g}", f"{r.time:.4g}") for r in self.rows]
        return _format(header, lines, markdown)

    def runs_table(self, *, markdown: bool = False) -> str:
        """One line per engine: status, stepping time, settings or reason."""
        header = ("engine", "status", "time [s]", "note")
        lines = [(e, r.status, f"{r.seconds:.3g}" if r.status == "ran" else "-", r.note or _settings(r))
                 for e, r in self.runs.items()]
        return _format(header, lines, markdown)

    def to_markdown(self, figure: str | None = None, regressions: Sequence[str] | None = None,
                    animation: str | None = None) -> str:
        """A Markdown report: the model and settings, the runs, the divergence table, the figure and the
        animation of the runs (file names relative to the report) and, when given, the regressions against a
        baseline."""
        from validation.baselines import versions
        from validation.machine import describe_machine

        parts = [f"# Cross-simulator comparison: {self.scene.name}", "",
                 f"- model: {self.scene.describe()}" + (f", from {self.source}" if self.source else ""),
                 f"- dt = {self.dt:g} s, t_end = {self.t_end:g} s, rbody method: {self.method or 'default'}",
                 f"- machine: {describe_machine()}",
                 "- versions: " + ", ".join(f"{k} {v}" for k, v in versions().items()), "",
                 "## Runs", "", self.runs_table(markdown=True), "",
                 "## Largest divergence of each observable", "",
                 "The divergence is the norm of the difference over the observable's components, in its "
                 "unit; for an orientation (`.quat`), the angle between the two rotations [rad]. The pair "
                 "`engine-exact` compares an engine with the scene's closed form.", "",
                 self.table(markdown=True) if self.rows else "(nothing to compare: fewer than two runs)", ""]
        notes = getattr(self.scene, "import_notes", ())
        if notes:
            parts += ["## Import notes", ""] + [f"- {n}" for n in notes] + [""]
        if figure:
            parts += ["## Divergence against time", "", f"![Divergence against time]({figure})", ""]
        if animation:
            ran = ", ".join(self.trajectories)
            parts += ["## The runs in motion", "", f"Each engine's run side by side ({ran}), drawn by rbody.animate.",
                      "", f"![The runs in motion]({animation})", ""]
        if regressions is not None:
            parts += ["## Regressions against the baseline", ""] + ([f"- {m}" for m in regressions] or ["none"])
            parts.append("")
        return "\n".join(parts)

    # ----- figures -----------------------------------------------------------------------------------

    def figure(self):
        """A matplotlib Figure: the divergence of each observable against time, one panel per observable
        (per kind of body observable when there are many: the largest over the bodies), log scale."""
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        groups = _groups(self.observables)
        rows = max(1, math.ceil(len(groups) / 2))
        columns = 1 if len(groups) <= 1 else 2
        fig, axes = plt.subplots(rows, columns, figsize=(6 * columns, 2.6 * rows + 0.6), squeeze=False)
        pairs = list(dict.fromkeys(r.pair for r in self.rows))
        floor = 1e-17  # exact agreement (0) drawn here, below double round-off of unit-sized values
        for axis, (title, members) in zip(axes.ravel(), groups.items()):
            for k, pair in enumerate(pairs):
                series = [self.curves[(m, pair)] for m in members if (m, pair) in self.curves]
                if series:
                    worst = np.max(np.stack(series), axis=0)
                    axis.semilogy(self.t, np.maximum(worst, floor), ("-", "--", ":", "-.")[k % 4], lw=1.1, color=f"C{k}",
                                  label=pair)
            axis.set(title=title, xlabel="t [s]", ylabel="divergence")
            axis.grid(True, which="major", alpha=0.3)
        for axis in axes.ravel()[len(groups):]:
            axis.set_visible(False)
        if pairs:
            axes.ravel()[0].legend(fontsize=8)
        fig.suptitle(f"{self.scene.name}: divergence between engines (dt = {self.dt:g} s)")
        fig.tight_layout()
        return fig

    def save_figure(self, path: str | Path) -> Path:
        """Write figure() as PNG to `path` (to a temporary name in the same folder, then renamed)."""
        import matplotlib.pyplot as plt

        path = Path(path)
        fig = self.figure()
        try:
            path.parent.mkdir(parents=True, exist_ok=True)
            with atomic_path(path) as temporary:
                fig.savefig(temporary, format="png", dpi=110)
        finally:
            plt.close(fig)
        return path


# ----- compare ------------------------------------------------------------------------------------------

def compare(model: Scene | str | Path, engines: Iterable[str] | None = None, *, dt: float | None = None,
            t_end: float | None = None, method: str | None = None,
            progress: Callable[[str], None] | None = None, client: Any = None, keyframe: int | str | None = None,
            qpos0=None, qvel0=None, ctrl: Any = None, overlapping_geoms: str | None = None) -> Comparison:
    """Run `model` in each engine and measure where they disagree.

    model:    an rbody Scene (unbatched), a path to an MJCF file, or "module:name" / "file.py:name"
    engines:  names among validation.BACKENDS (default: all); engines that cannot express the model are
              listed as refused, with the reason
    dt:       time step [s] of every engine (default: the scene's timestep, else 1e-3)
    t_end:    duration [s] (default: the scene's)
    method:   rbody's method (default "rk4" where it applies, else rbody's default; for an MJCF file, the
              file's own integrator: rbody's mujoco_euler, implicitfast, implicit or rk4)
    progress: called with one line per engine as it finishes (the command prints it to stderr)
    client:   a dask.distributed.Client: each engine's run is one task on its cluster (validation.cluster),
              the comparison the same as here (Scene models)
    An MJCF file runs as the user runs it (_compare_file): MuJoCo compiles the file itself (never rbody's
    re-export), so that an import error shows as a divergence; rbody reads it with from_mjcf, and a file rbody
    refuses is a row saying why. Only for a file: keyframe (index or name), qpos0 (nq,), qvel0 (nv,) (MuJoCo's
    layout) the initial state; ctrl the controls of both engines (as rbody.simulate takes them: None, (nu,),
    (n_steps, nu) or a callable ctrl(t, qpos, qvel)); overlapping_geoms="sum" for rbody's reader.
    Raises ValueError for bad input (a missing file, an unknown engine, dt <= 0, a batched scene, a method
    that does not apply), and for a run of any engine beyond the limits of rbody's own runs (engine_work: too many
    steps, or more memory than the process can still allocate), before any run.
    """
    if not isinstance(model, Scene) and Path(str(model)).suffix.lower() in MJCF_SUFFIXES:
        return _compare_file(Path(str(model)), _engine_names(engines), dt=dt, t_end=t_end, method=method,
                             progress=progress, keyframe=keyframe, qpos0=qpos0, qvel0=qvel0, ctrl=ctrl,
                             overlapping_geoms=overlapping_geoms)
    given = [k for k, v in (("keyframe", keyframe), ("qpos0", qpos0), ("qvel0", qvel0), ("ctrl", ctrl),
                            ("overlapping_geoms", overlapping_geoms)) if v is not None]
    if given:
        raise ValueError(f"{', '.join(given)}: for an MJCF file only; give a Scene its own state and controls")
    scene = load_model(model, t_end=t_end) if not isinstance(model, Scene) else model
    engines = _engine_names(engines, scene)
    if scene.batch_shape:
        raise ValueError(f"scene {scene.name!r} is a batch of shape {scene.batch_shape}: compare runs one model "
                         "in several engines; pick one with scene.item(i)")
    dt = _default_dt(scene) if dt is None else dt
    dt, t_end = run_times(scene.t_end, dt, t_end)  # ValueError for dt <= 0, dt > t_end, t_end <= 0
    method = _method(scene, method)
    able = {engine: supports(scene, engine) for engine in engines}
    refuse_large_runs(scene, [engine for engine in engines if able[engine][0]], dt, t_end)

    runs: dict[str, EngineRun] = {}
    if client is not None:
        runs = _runs_on_cluster(client, scene, [e for e in engines if able[e][0]], dt, t_end, method)
    for k, engine in enumerate(engines, 1):
        ok, reason = able[engine]
        if not ok:
            runs[engine] = EngineRun(engine, "refused", note=reason)
        elif engine not in runs:
            runs[engine] = _run(scene, engine, dt, t_end, method)
        if progress is not None:
            r = runs[engine]
            what = f"{r.seconds:.3g} s" if r.status == "ran" else f"{r.status}: {r.note}"
            progress(f"[{k}/{len(engines)}] {engine}: {what}")
    t, rows, curves = _divergences(scene, {e: r.trajectory for e, r in runs.items() if r.status == "ran"})
    source = None if isinstance(model, Scene) else str(model)
    return Comparison(scene, dt, t_end, method, runs, tuple(rows), t, curves, source)


# MuJoCo's backend steps in chunks of this many bytes of rollout output, held twice (the run and its replay with
# sensors): validation/backends/mujoco.py's _CHUNK_BYTES.
MUJOCO_CHUNK_BYTES = 64 * 2**20


def engine_work(scene: Scene, engine: str, dt: float, t_end: float) -> dict[str, float]:
    """The work of `engine`'s run of `scene` (unbatched) over t_end [s] at step dt [s], every step saved, in the
    terms of rbody.simulation.estimate_work, whose limits refuse_large applies to every engine alike:
    rbody: estimate_work itself. MuJoCo: per saved step its state (time, qpos, qvel) and 13 sensor numbers per
    body, kept from the rollout and stacked (3 copies), and the observables formed from them (2 copies), plus its
    chunk buffers. pymunk: 6 numbers per body per saved step, and the observables (2 copies)."""
    from rbody.simulation import estimate_work, observed_numbers, run_work

    if engine == "rbody":
        return estimate_work(scene, dt, t_end, 1)
    steps = max(1.0, math.ceil(t_end / dt * (1 - 1e-12))) if t_end / dt < 2.0**62 else t_end / dt
    bodies = len(scene.layout.bodies) if not scene.event_driven else getattr(scene, "n", 1)
    if scene.event_driven:
        state, observed = 2.0 * bodies, 4.0 * bodies
    else:
        state = float(scene.native_model.y0.shape[1])
        observed = observed_numbers(scene) + state + 13.0 * bodies  # what scene.observe forms from body states
    if engine == "mujoco":
        numbers = 3.0 * (1.0 + state + 13.0 * bodies) + 2.0 * observed
        extra = 2.0 * min(MUJOCO_CHUNK_BYTES, 8.0 * steps * (1.0 + state + 13.0 * bodies))
    else:
        numbers, extra = 6.0 * bodies + 2.0 * observed, 0.0
    return run_work(steps, steps + 1.0, numbers, extra_bytes=extra)


def refuse_large_runs(scene: Scene, engines: Sequence[str], dt: float, t_end: float) -> None:
    """ValueError, before any run, when the run of any of `engines` is beyond the limits of rbody's own runs
    (rbody.simulation.work_problems on engine_work: steps, saved samples, the memory at the peak), naming each."""
    from rbody.simulation import work_problems

    problems = []
    for engine in engines:
        found = work_problems(engine_work(scene, engine, dt, t_end))
        if found:
            problems.append(f"{engine}: " + "; ".join(found))
    if problems:
        raise ValueError(f"run refused before it starts (dt={dt:g} s, t_end={t_end:g} s; every engine's run obeys "
                         "the limits of rbody's own): " + " | ".join(problems))


@dataclass(frozen=True)
class FileModel:
    """The model of an MJCF file that rbody could not read: what a Comparison needs of a scene (a name for the
    report and baselines, no observables or closed form of its own)."""

    name: str
    source: str
    refusal: str
    observables: tuple = ()
    import_notes: tuple = ()
    batch_shape: tuple = ()

    def describe(self) -> str:
        return f"{self.name} ({self.source}; rbody refused it: {self.refusal})"

    def exact(self, t):
        raise NotImplementedError("a model read from a file has no closed form")


def _compare_file(path: Path, engines: Sequence[str], *, dt, t_end, method, progress, keyframe, qpos0, qvel0, ctrl,
                  overlapping_geoms) -> Comparison:
    """compare() of a user's MJCF file (module docstring of validation.mujoco_file): every engine on the same dt
    (the file's timestep by default), t_end (rbody's from_mjcf default, 1 s), initial state and controls."""
    from rbody.mjcf import MJCFError
    from rbody.mjcf.parse import DEFAULT_T_END
    from validation import mujoco_file

    if not path.is_file():
        raise ValueError(f"model {str(path)!r}: no such file")
    from rbody.mjcf.document import read_source

    read_source(path)  # a file that is not XML at all is bad input (MJCFError, a ValueError), before any run
    if isinstance(keyframe, str) and keyframe.strip().lstrip("-").isdigit():
        keyframe = int(keyframe)
    duration = DEFAULT_T_END if t_end is None else t_end
    options = {"t_end": duration, "keyframe": keyframe, "qpos0": qpos0, "qvel0": qvel0}
    if overlapping_geoms is not None:
        options["overlapping_geoms"] = overlapping_geoms
    try:
        compiled, mujoco_refusal = mujoco_file.load(path), ""
    except ValueError as error:
        compiled, mujoco_refusal = None, str(error)
    if compiled is not None:  # a state or keyframe the model cannot take is bad input, before any run
        import mujoco

        mujoco_file.initial_state(compiled, mujoco.MjData(compiled), keyframe, qpos0, qvel0)
    try:
        scene, refusal = rbody.from_mjcf(path, **options), ""
    except MJCFError as error:  # rbody cannot model the file: a row that says why, MuJoCo still runs it
        scene, refusal = None, str(error)
    timestep = scene.timestep if scene is not None else (compiled.opt.timestep if compiled is not None else DEFAULT_DT)
    dt = float(timestep) if dt is None else dt
    dt, duration = run_times(duration, dt, duration)
    if scene is not None:
        method = _file_method(scene, method)
    runs: dict[str, EngineRun] = {}
    for k, engine in enumerate(engines, 1):
        if engine == "mujoco":
            if compiled is None:
                runs[engine] = EngineRun(engine, "refused", note=mujoco_refusal)
            else:
                start = time.perf_counter()
                try:
                    trajectory = mujoco_file.run_file(path, t_end=duration, dt=dt, keyframe=keyframe, qpos0=qpos0,
                                                      qvel0=qvel0, ctrl=ctrl, scene=scene)
                    runs[engine] = EngineRun(engine, "ran", trajectory, trajectory.meta["step_seconds"])
                except (ValueError, RuntimeError) as error:
                    runs[engine] = EngineRun(engine, "failed", seconds=time.perf_counter() - start,
                                             note=f"{type(error).__name__}: {error}")
        elif scene is None:
            runs[engine] = EngineRun(engine, "refused", note=f"rbody cannot read the file: {refusal}")
        else:
            ok, reason = supports(scene, engine)
            runs[engine] = (_run(scene, engine, dt, duration, method, ctrl) if ok else
                            EngineRun(engine, "refused", note=reason))
        if progress is not None:
            r = runs[engine]
            what = f"{r.seconds:.3g} s" if r.status == "ran" else f"{r.status}: {r.note}"
            progress(f"[{k}/{len(engines)}] {engine}: {what}")
    model = scene if scene is not None else FileModel(path.stem, str(path), refusal)
    t, rows, curves = _divergences(model, {e: r.trajectory for e, r in runs.items() if r.status == "ran"})
    return Comparison(model, dt, duration, method, runs, tuple(rows), t, curves, str(path))


def _file_method(scene, method: str | None) -> str | None:
    """rbody's method on a file: the file's own integrator (MJCFScene.file_method) by default, where it applies."""
    if method is not None:
        return _method(scene, method)
    own = getattr(scene, "file_method", None)
    if own is not None and own in scene.methods:
        return own
    return _method(scene, None)


def _settings_of(scene: Scene, engine: str, method: str | None) -> dict:
    """rbody: the method; MuJoCo: the model's own integrator where it records one (an MJCF <option>), as the
    user runs it, else the backend's default (RK4 without impacts); pymunk: its defaults."""
    if engine == "rbody":
        return {"method": method}
    if engine == "pinocchio":  # the same scheme as rbody's where Pinocchio's backend has it
        from validation.backends.pinocchio import METHODS

        return {"method": method if method in METHODS else "rk4"}
    if engine == "mujoco" and getattr(scene, "integrator", None):
        return {"integrator": scene.integrator}
    return {}


def _run(scene: Scene, engine: str, dt: float, t_end: float, method: str | None, ctrl: Any = None) -> EngineRun:
    start = time.perf_counter()
    try:
        settings = _settings_of(scene, engine, method)
        if ctrl is not None and engine == "rbody":
            settings["ctrl"] = ctrl
        trajectory = get(engine).run(scene, dt, t_end, **settings)
        _within_limits(scene, trajectory, engine)
    except Exception as error:  # a blow-up or a simulator's error is a result to report, not to hide
        return EngineRun(engine, "failed", seconds=time.perf_counter() - start, note=f"{type(error).__name__}: {error}")
    seconds = float(trajectory.meta.get("step_seconds", time.perf_counter() - start))
    return EngineRun(engine, "ran", trajectory, seconds)


def _runs_on_cluster(client: Any, scene: Scene, engines: Sequence[str], dt: float, t_end: float,
                     method: str | None) -> dict[str, EngineRun]:
    """The runs of the engines that support `scene`, each one task on the cluster of `client`."""
    from rbody.engine.distributed import portable
    from validation.cluster import run_tasks

    able = [engine for engine in engines if supports(scene, engine)[0]]
    shipped = portable(scene)  # without its cached model (compiled functions), which each worker builds
    done = run_tasks(client, [(engine, _run_task, (shipped, engine, dt, t_end, method)) for engine in able],
                     what="compare")
    return dict(zip(able, done))


def _run_task(scene: Scene, engine: str, dt: float, t_end: float, method: str | None) -> EngineRun:
    """_run with every lazy observable computed, as a task on a worker sends its run back."""
    run = _run(scene, engine, dt, t_end, method)
    if run.trajectory is None:
        return run
    trajectory = run.trajectory
    computed = Trajectory(trajectory.t, {name: trajectory[name] for name in trajectory.observables},
                          trajectory.events, trajectory.meta)
    return dataclasses.replace(run, trajectory=computed)


def _within_limits(scene: Scene, trajectory: Trajectory, engine: str) -> None:
    """Raise SimulationError when a coordinate of the model leaves a declared range (an MJCF joint limit:
    rbody.mjcf.MJCFScene.limit_violation) that the engine does not model: rbody holds a joint's own range rigidly
    and MuJoCo softly (how far it lets a joint pass its stop is its divergence from the rigid limit, which the
    comparison shows); a range declared beside the joints (scene.limits only) no engine models."""
    check = getattr(scene, "limit_violation", None)
    if check is None or not scene.limits or "qpos" not in trajectory:
        return
    tree = getattr(scene, "tree", None)
    held = {j.name for j in tree.joints if j.range is not None} if tree is not None else set()
    if engine in ("rbody", "mujoco") and set(scene.limits) <= held:
        return
    violation = check(trajectory.t, trajectory["qpos"])
    if violation:
        raise rbody.SimulationError(f"{engine}: {violation}; no engine here models joint limits")


def _engine_names(engines: Iterable[str] | str | None, scene: Scene | None = None) -> tuple[str, ...]:
    """The engines asked for: None is BACKENDS (rbody, MuJoCo, pymunk: the main command's), or every engine
    (ENGINES: with Pinocchio and Bullet) for a model read from URDF; "all" is every engine."""
    if engines is None:
        return ENGINES if getattr(scene, "floating_base", None) is not None else BACKENDS
    if isinstance(engines, str) and engines.strip() == "all":
        return ENGINES
    names = tuple(engines.split(",")) if isinstance(engines, str) else tuple(engines)
    names = tuple(n.strip() for n in names)
    for n in names:
        if n not in ENGINES:
            raise ValueError(f"engine {n!r}: expected one of {', '.join(map(repr, ENGINES))} or 'all'")
    if not names or len(set(names)) != len(names):
        raise ValueError(f"engines={list(names)}: expected one or more distinct engines of {list(ENGINES)}")
    return names


def _default_dt(scene: Scene) -> float:
    timestep = getattr(scene, "timestep", None)
    return float(timestep) if timestep else DEFAULT_DT


def _method(scene: Scene, method: str | None) -> str | None:
    """rbody's method, checked before any run: "rk4" by default where it applies (MuJoCo's scheme)."""
    if scene.event_driven:
        if method not in (None, "events"):
            raise ValueError(f"method={method!r}: scene {scene.name!r} is event-driven (impacts found exactly); "
                             "leave the method out")
        return None
    if method is None:
        return "rk4" if "rk4" in scene.methods else None
    if method not in rbody.METHODS:
        raise ValueError(f"method={method!r}: expected one of {', '.join(map(repr, rbody.METHODS))}")
    if scene.methods and method not in scene.methods:
        raise ValueError(f"method={method!r} cannot run scene {scene.name!r}: {scene.why_not(method)}; methods "
                         f"that apply: {', '.join(scene.methods)}")
    return method


# ----- the model ----------------------------------------------------------------------------------------

def load_model(source: str | Path, *, t_end: float | None = None, constraints: bool = True) -> Scene:
    """The Scene named by `source`: an MJCF file (rbody.from_mjcf, given t_end when set), a URDF file
    (rbody.from_urdf; constraints=False: its limits, friction and mimics recorded, not applied), or "module:name" / "file.py:name"
    where name is a Scene or a function of no arguments returning one. Raises ValueError naming what is
    wrong (no such file, not an MJCF file, no such name, not a Scene) before any run."""
    if isinstance(source, Scene):
        return source
    if not isinstance(source, (str, Path)):
        raise ValueError(f"model={source!r}: expected a Scene, a path to an MJCF file or 'module:name'")
    text = str(source)
    path = Path(text)
    if path.suffix.lower() in URDF_SUFFIXES:
        if not path.is_file():
            raise ValueError(f"model {text!r}: no such file")
        return rbody.from_urdf(path, constraints=constraints, **({} if t_end is None else {"t_end": t_end}))
    if path.suffix.lower() in MJCF_SUFFIXES or (path.exists() and path.suffix.lower() != ".py"):
        if not path.is_file():
            raise ValueError(f"model {text!r}: no such file")
        from_mjcf = getattr(rbody, "from_mjcf", None)
        if from_mjcf is None:
            raise ValueError(f"model {text!r}: this rbody cannot read MJCF (rbody.from_mjcf is missing); pass a "
                             "Scene instead")
        return from_mjcf(path, **({} if t_end is None else {"t_end": t_end}))
    if ":" not in text:
        raise ValueError(f"model {text!r}: expected an MJCF file ({'/'.join(MJCF_SUFFIXES)}), a URDF file (.urdf) or "
                         "'module:name' / "
                         "'file.py:name' naming a Scene")
    where, attribute = text.rsplit(":", 1)
    if where.endswith(".py"):
        if not Path(where).is_file():
            raise ValueError(f"model {text!r}: no such file {where!r}")
        spec = importlib.util.spec_from_file_location(Path(where).stem, where)
        module = importlib.util.module_from_spec(spec)
        try:
            spec.loader.exec_module(module)
        except Exception as error:  # noqa: BLE001 - any failure of the user's file is a problem with the input
            raise ValueError(f"model {text!r}: running {where!r} failed ({type(error).__name__}: "
                             f"{_short(str(error))})") from None
    else:
        try:
            module = importlib.import_module(where)
        except Exception as error:  # noqa: BLE001 - ImportError, or the module's own error on import
            raise ValueError(f"model {text!r}: cannot import module {where!r} ({type(error).__name__}: "
                             f"{_short(str(error))})") from None
    if not hasattr(module, attribute):
        raise ValueError(f"model {text!r}: {where!r} has no {attribute!r}")
    value = getattr(module, attribute)
    if callable(value) and not isinstance(value, Scene):
        try:
            value = value()
        except TypeError as error:
            raise ValueError(f"model {text!r}: {attribute}() must build the Scene without arguments ({error})") from None
        except Exception as error:  # noqa: BLE001 - the user's function failed: a problem with the input
            raise ValueError(f"model {text!r}: {attribute}() failed ({type(error).__name__}: "
                             f"{_short(str(error))})") from None
    if not isinstance(value, Scene):
        raise ValueError(f"model {text!r}: {attribute!r} is a {type(value).__name__}, expected an rbody Scene")
    return value


def _short(text: str, limit: int = 300) -> str:
    """`text` cut to `limit` characters (a message never echoes a huge value whole)."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


# ----- the divergences ---------------------------------------------------------------------------------

def divergence(name: str, a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """(T,) divergence of observable `name` between values a and b (T, ...): the norm of a - b over the
    components; for an orientation (name ending ".quat", (T, 4) unit quaternions) the rotation angle
    between them, 4 asin(min(|a - b|, |a + b|) / 2) [rad] (accurate for small angles, blind to the sign)."""
    a, b = np.asarray(a, float).reshape(len(a), -1), np.asarray(b, float).reshape(len(b), -1)
    if name.endswith(".quat") and a.shape[1] == 4:
        a = a / np.linalg.norm(a, axis=1, keepdims=True)
        b = b / np.linalg.norm(b, axis=1, keepdims=True)
        chord = np.minimum(np.linalg.norm(a - b, axis=1), np.linalg.norm(a + b, axis=1))
        return 4 * np.arcsin(np.minimum(chord / 2, 1.0))
    return np.linalg.norm(a - b, axis=1)


def _common_times(trajectories: Mapping[str, Trajectory]) -> tuple[np.ndarray, bool]:
    """The times every run is compared at: the runs' own when they agree, else the coarsest run's within
    the span all runs cover (the others interpolated linearly)."""
    grids = [tr.t for tr in trajectories.values()]
    first = grids[0]
    if all(g.shape == first.shape and np.allclose(g, first, rtol=1e-12, atol=0) for g in grids):
        return first, False
    end = min(g[-1] for g in grids)
    coarsest = min(grids, key=len)
    return coarsest[coarsest <= end * (1 + 1e-12)], True


def _at(values: np.ndarray, t_run: np.ndarray, t: np.ndarray, interpolate: bool) -> np.ndarray:
    values = np.asarray(values, dtype=float)
    if not interpolate:
        return values
    flat = values.reshape(len(t_run), -1)
    columns = [np.interp(t, t_run, flat[:, k]) for k in range(flat.shape[1])]
    return np.stack(columns, axis=-1).reshape((len(t),) + values.shape[1:])


def _divergences(scene: Scene, trajectories: Mapping[str, Trajectory]):
    if not trajectories:
        return np.zeros(0), [], {}
    t, interpolate = _common_times(trajectories)
    values = {e: {n: _at(tr[n], tr.t, t, interpolate) for n in tr.observables} for e, tr in trajectories.items()}
    try:
        values[EXACT] = {n: np.asarray(v, dtype=float) for n, v in scene.exact(t).items()}
    except NotImplementedError:
        pass
    engines = list(values)
    pairs = [(a, b) for i, a in enumerate(engines) for b in engines[i + 1:]]
    pairs.sort(key=lambda pair: EXACT in pair)  # engine against engine first, then each against the closed form
    order = list(dict.fromkeys(list(scene.observables) + [n for v in values.values() for n in v]))
    rows, curves = [], {}
    for name in order:
        for a, b in pairs:
            if name not in values[a] or name not in values[b]:
                continue
            x, y = values[a][name], values[b][name]
            if x.shape != y.shape:
                continue
            d = divergence(name, x, y)
            bad = ~np.isfinite(d)
            k = int(np.argmax(bad)) if bad.any() else int(np.argmax(d))
            largest = math.inf if bad.any() else float(d[k])
            row = Divergence(name, (a, b), largest, float(t[k]))
            rows.append(row)
            curves[(name, row.pair)] = d
    return t, rows, curves


# ----- baselines -----------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _BaselineRow:
    """A Divergence as validation.baselines stores it: case = the model, backend = the engine pair,
    metric = the observable."""

    case: str
    backend: str
    metric: str
    value: float


def _baseline_rows(comparison: Comparison) -> list[_BaselineRow]:
    return [_BaselineRow(comparison.scene.name, r.pair, r.observable, r.largest) for r in comparison.rows
            if math.isfinite(r.largest)]


def save_baseline(comparison: Comparison, path: str | Path) -> list[Path]:
    """Record the comparison's largest divergences in folder `path` (created if needed): one JSON file per
    engine pair, as validation.baselines writes them, the whole folder replaced at once (an interrupted update
    leaves the old baselines); other models' divergences in the same files are kept (a file that cannot be read is
    rewritten with this model's alone: the update repairs it). Returns the files written."""
    directory = _folder(path)
    keep: dict[str, dict[str, float]] = {}
    prefix = f"{comparison.scene.name}/"
    for file in _baseline_files(directory):
        try:
            metrics = baselines.read(file)["metrics"]
        except baselines.BaselineError:
            continue
        others = {key: value for key, value in metrics.items() if not key.startswith(prefix)}
        if others:
            keep[file.stem] = others
    return baselines.save(_baseline_rows(comparison), directory, keep=keep)


def _baseline_files(directory: Path) -> list[Path]:
    """The baseline files of a compare baseline folder: its *.json files, never a temporary an interrupted write
    left behind (hidden: rbody.files.is_temporary)."""
    from rbody.files import is_temporary

    if not directory.is_dir():
        return []
    return sorted(file for file in directory.glob("*.json") if not file.name.startswith(".") and not is_temporary(file))


def check_baseline(comparison: Comparison, path: str | Path) -> list[str]:
    """[] when every divergence is within its baseline in folder `path` (str or Path), else one message per
    problem: a divergence worse than recorded (validation.baselines' margin: a factor 2 plus 1e-13); a recorded
    (observable, pair) of this model between engines the comparison ran or tried that it no longer measures
    (an engine that failed or now refuses); a divergence measured now with no baseline (not a pass).
    Raises ValueError when `path` is not a folder holding baselines of this model, and
    validation.baselines.BaselineError (a ValueError) for a broken baseline file."""
    regressions, missing = baseline_findings(comparison, path)
    return regressions + missing


def baseline_findings(comparison: Comparison, path: str | Path) -> tuple[list[str], list[str]]:
    """(regressions, missing) of check_baseline: worse than recorded or no longer measured, and measured
    without a baseline (the command exits 1 on the first, 2 on the second alone)."""
    directory = _folder(path)
    if not directory.is_dir():
        raise ValueError(f"baseline {str(path)!r}: no such folder (record one with save_baseline or "
                         "--update-baseline)")
    recorded = _recorded(directory, comparison.scene.name)
    if not recorded:
        raise ValueError(f"baseline {str(path)!r} holds no divergences of model {comparison.scene.name!r}")
    rows = _baseline_rows(comparison)
    regressions, _ = baselines.compare(rows, directory)
    missing = [f"no baseline for {r.backend} {r.case}/{r.metric} in {str(path)!r}: record it with "
               f"`python -m validation compare MODEL --baseline {path} --update-baseline` (or save_baseline)"
               for r in rows if (r.backend, r.metric) not in recorded]
    measured = {(r.backend, r.metric) for r in rows}
    asked = set(comparison.runs) | {EXACT}
    for pair, observable in sorted(recorded):
        # a pair of engines asked for (refused, failed, or an observable gone) must still be measured
        if set(pair.split("-")) <= asked and (pair, observable) not in measured:
            regressions.append(f"{pair} {comparison.scene.name}/{observable}: recorded in the baseline, not "
                               "measured now")
    return regressions, missing


def _folder(path: str | Path) -> Path:
    if not isinstance(path, (str, Path)) or str(path) == "":
        raise ValueError(f"path={path!r}: expected a folder (str or Path)")
    return Path(path)


def _recorded(directory: Path, case: str) -> set[tuple[str, str]]:
    """(pair, observable) of every divergence of model `case` recorded in `directory` (each file read and
    checked by validation.baselines.read: BaselineError naming a broken one)."""
    out = set()
    prefix = f"{case}/"
    for file in _baseline_files(directory):
        metrics = baselines.read(file)["metrics"]
        for key, value in metrics.items():
            if value < 0:  # a divergence is a norm: a negative one was edited in, and abs() would have hidden it
                raise baselines.BaselineError(
                    f"baseline file {str(file)!r} has divergence {key!r} = {value!r}: a divergence is >= 0 (a norm); "
                    f"rewrite it with `python -m validation compare MODEL --baseline {directory} --update-baseline`")
        out.update((file.stem, key[len(prefix):]) for key in metrics if key.startswith(prefix))
    return out


# ----- helpers --------------------------------------------------------------------------------------------

def _tolerances(tolerances: float | Mapping[str, float], observables: Sequence[str]) -> dict[str, float]:
    def bound(value, name: str) -> float:
        if isinstance(value, bool) or not isinstance(value, (int, float, np.floating, np.integer)):
            raise ValueError(f"tolerance of {name}={value!r}: expected a number >= 0")
        value = float(value)
        if not value >= 0:
            raise ValueError(f"tolerance of {name}={value!r}: expected a number >= 0")
        return value

    if not isinstance(tolerances, Mapping):
        return {"*": bound(tolerances, "every observable")}
    unknown = [k for k in tolerances if k != "*" and k not in observables]
    if unknown:
        raise ValueError(f"tolerances name {unknown}, which the comparison does not measure; its observables: "
                         f"{list(observables)}")
    return {k: bound(v, k) for k, v in tolerances.items()}


def _groups(observables: Sequence[str]) -> dict[str, list[str]]:
    """Panels of the figure: one per observable, or, beyond eight, one per kind (the part after the last
    dot: every body's com in one panel, as its worst over the bodies)."""
    if len(observables) <= 8:
        return {n: [n] for n in observables}
    groups: dict[str, list[str]] = {}
    for n in observables:
        kind = n.rsplit(".", 1)[-1]
        groups.setdefault(kind if "." in n else n, []).append(n)
    return {(f"{k} (worst body)" if len(v) > 1 else k): v for k, v in groups.items()}


def _settings(run: EngineRun) -> str:
    if run.trajectory is None:
        return ""
    meta = run.trajectory.meta
    shown = {k: meta[k] for k in ("method", "integrator", "settings") if k in meta}
    return "; ".join(f"{k} {v}" for k, v in shown.items())


def _format(header: Sequence[str], lines: list[Sequence[str]], markdown: bool) -> str:
    if markdown:
        out = ["| " + " | ".join(header) + " |", "|" + "---|" * len(header)]
        return "\n".join(out + ["| " + " | ".join(str(c).replace("|", "/") for c in line) + " |" for line in lines])
    widths = [max([len(h)] + [len(str(line[k])) for line in lines]) for k, h in enumerate(header)]
    fmt = "  ".join(f"{{:<{w}}}" for w in widths)
    return "\n".join([fmt.format(*header), fmt.format(*("-" * w for w in widths))]
                     + [fmt.format(*map(str, line)) for line in lines])


def write_report(comparison: Comparison, out: str | Path, regressions: Sequence[str] | None = None, *,
                 animate: bool = False, say: Callable[[str], None] | None = None) -> Path:
    """out/<model>.md with the tables, and its figure out/<model>_divergence.png; with animate, also the
    animation of every engine's run side by side, out/<model>_motion.gif (rbody.animate; `say` gets its summary:
    frames, stride, size). Every file written to a temporary name and renamed into place. Returns the report's
    path."""
    out = Path(out)
    out.mkdir(parents=True, exist_ok=True)
    stem = "".join(c if c.isalnum() or c in "-_." else "_" for c in comparison.scene.name)
    figure = None
    if comparison.rows:
        figure = comparison.save_figure(out / f"{stem}_divergence.png").name
    motion = None
    if animate:
        drawable = {}
        for engine, trajectory in comparison.trajectories.items():
            try:
                comparison.scene.body_poses(trajectory)
                drawable[engine] = trajectory
            except ValueError as error:  # e.g. a run that blew up: its bodies have no place to be drawn
                if say is not None:
                    say(f"animation: {engine}'s run not drawn: {error}")
        if drawable:
            animation = rbody.animate(comparison.scene, drawable, out / f"{stem}_motion.gif")
            motion = animation.path.name
            if say is not None:
                say(f"animation: {animation.summary()}")
    text = comparison.to_markdown(figure, regressions, motion)
    path = out / f"{stem}.md"
    write_atomic(path, text)
    return path


# ----- the command ----------------------------------------------------------------------------------------

def load_ctrl(text: str | None):
    """--ctrl: FILE.npy (an array: a constant (nu,) or a schedule (n_steps, nu)) or module:function /
    file.py:function (a callable ctrl(t, qpos, qvel) -> (nu,)); None for None."""
    if text is None:
        return None
    if text.endswith(".npy"):
        if not Path(text).is_file():
            raise ValueError(f"--ctrl {text!r}: no such file")
        return np.load(text)
    if ":" not in text:
        raise ValueError(f"--ctrl {text!r}: expected FILE.npy or module:function / file.py:function")
    where, attribute = text.rsplit(":", 1)
    module = _import(where, f"--ctrl {text!r}")
    function = getattr(module, attribute, None)
    if not callable(function):
        raise ValueError(f"--ctrl {text!r}: {where!r} has no function {attribute!r}")
    return function


def _import(where: str, what: str):
    if where.endswith(".py"):
        if not Path(where).is_file():
            raise ValueError(f"{what}: no such file {where!r}")
        spec = importlib.util.spec_from_file_location(Path(where).stem, where)
        module = importlib.util.module_from_spec(spec)
        spec.loader.exec_module(module)
        return module
    try:
        return importlib.import_module(where)
    except ImportError as error:
        raise ValueError(f"{what}: cannot import module {where!r} ({error})") from None


def _vector(text: str | None, what: str):
    """A vector given as MJCF writes one: numbers separated by spaces."""
    if text is None:
        return None
    try:
        return np.array([float(x) for x in text.split()], dtype=np.float64)
    except ValueError:
        raise ValueError(f"{what} {text!r}: expected numbers separated by spaces") from None


def main(args) -> int:
    """python -m validation compare MODEL ...: 0 agreed with the baseline (or none given), 1 a regression
    against the baseline, 2 bad input (a message on stderr, no traceback) or a divergence without a baseline
    (as the main command: a missing baseline is not a pass), 3 nothing compared (fewer than two engines ran the
    model: each refusal or failure is listed with its reason)."""
    import sys

    def say(line: str) -> None:
        print(line, file=sys.stderr, flush=True)

    try:
        if args.update_baseline and args.baseline is None:
            raise ValueError("--update-baseline needs --baseline DIR: the folder to record the divergences in")
        if args.baseline is not None:
            from rbody.files import remove_stale_temporaries

            remove_stale_temporaries(args.baseline)  # what an interrupted update left behind
        if args.baseline is not None and not args.update_baseline and not Path(args.baseline).is_dir():
            raise ValueError(f"--baseline {str(args.baseline)!r}: no such folder (record one with --update-baseline)")
        file_options = {"keyframe": getattr(args, "keyframe", None),
                        "qpos0": _vector(getattr(args, "qpos0", None), "--qpos0"),
                        "qvel0": _vector(getattr(args, "qvel0", None), "--qvel0"),
                        "ctrl": load_ctrl(getattr(args, "ctrl", None)),
                        "overlapping_geoms": "sum" if getattr(args, "overlapping_geoms", False) else None}
        is_file = Path(str(args.model)).suffix.lower() in MJCF_SUFFIXES
        if is_file:
            if not Path(args.model).is_file():
                raise ValueError(f"model {str(args.model)!r}: no such file")
            from rbody.mjcf.document import read_source

            read_source(Path(args.model))  # not XML at all: bad input, before any run
            scene = None
            name = Path(args.model).stem
            engines = _engine_names(args.engines)
        else:
            if any(v is not None for v in file_options.values()):
                raise ValueError("--keyframe, --qpos0, --qvel0, --ctrl and --overlapping-geoms are for an MJCF file")
            scene = load_model(args.model, t_end=args.t_end, constraints=not getattr(args, "no_constraints", False))
            name = scene.name
            engines = _engine_names(args.engines, scene)
            if getattr(args, "animate", False):
                from rbody.animation import check_animatable

                check_animatable(scene)  # before any run
        if args.baseline is not None and not args.update_baseline and not _recorded(Path(args.baseline), name):
            # every file read and checked before the run (BaselineError names a broken one)
            raise ValueError(f"baseline {str(args.baseline)!r} holds no divergences of model {name!r} "
                             "(record them with --update-baseline)")
        say(f"comparing {scene.describe() if scene is not None else args.model} in {', '.join(engines)}")
        from validation.cluster import connect

        if is_file:  # the user's own file, in MuJoCo as it is
            comparison = compare(args.model, engines, dt=args.dt, t_end=args.t_end, method=args.method,
                                 progress=say, **file_options)
        else:
            with connect(getattr(args, "scheduler", None), getattr(args, "workers", None)) as client:
                comparison = compare(scene, engines, dt=args.dt, t_end=args.t_end, method=args.method,
                                     progress=say, client=client)
        found, missing = None, []
        if args.baseline is not None and not args.update_baseline:
            found, missing = baseline_findings(comparison, args.baseline)
    except ValueError as error:
        say(f"error: {error}")
        return 2
    print(comparison.table())
    if args.update_baseline:
        for path in save_baseline(comparison, args.baseline):
            say(f"baseline written: {path}")
    try:
        path = write_report(comparison, args.out, None if found is None else found + missing,
                            animate=getattr(args, "animate", False), say=say)
    except ValueError as error:  # the runs cannot be drawn (found after them: e.g. a run that blew up)
        say(f"error: {error}")
        return 2
    say(f"report: {path}")
    for message in found or ():
        say(f"REGRESSION {message}")
    for message in missing:
        say(f"MISSING {message}")
    if not comparison.rows:
        say("NOTHING COMPARED: fewer than two engines ran the model: "
            + "; ".join(f"{e} {r.status}" + (f" ({r.note})" if r.note else "") for e, r in comparison.runs.items()))
        return 3
    return 1 if found else 2 if missing else 0
