"""The constraint layer against MuJoCo: MuJoCo's divergence from the rigid limit as its softness and step shrink,
the cost per step of each on models with limits and dry friction, and which published models now load.

    python benchmarks/constraints_vs_mujoco.py [--repeats 5] [--models DIR] [--skip-sweep] [--skip-cost]
                                               [--published FILE.xml ...]

Prints the machine and versions, then
1. the sweep: on the limit pendulum (a rod falling onto its stop, e = 0) and the dry-friction oscillator
   (validation.hard.constraints), MuJoCo (RK4) at every step dt in DTS and every time constant of its constraint
   springs in TIMECONSTS (solreflimit / solreffriction "timeconst 1", critically damped), each run measured against
   the closed form by the same function as rbody's run at the same dt. MuJoCo clamps a time constant below 2 dt to
   2 dt (its refsafe flag): such a row is marked "clamped";
2. the cost per step, contacts off: a humanoid-like tree (validation.hard.constraints.LIMBS: torso fixed, 19 dofs,
   limits on every joint, ball cones, dry friction and damping everywhere) and a quadruped-like one of this script
   (a free torso, four legs of three hinges, limits and dry friction on each, started with every joint moving), 2 s
   at dt = 2 ms: rbody's event-driven run (rk4 between events, events counted), its time-stepping (moreau) and the
   time-stepping with MuJoCo's Euler step as its free motion (mujoco_euler: the scheme MuJoCo's Euler runs, with
   rigid constraints), the whole simulate call per step; MuJoCo's Euler and RK4, mj_step in a loop, per step. Minimum, median and maximum
   over --repeats runs after a warm-up;
3. with --models DIR: every *.xml in DIR (e.g. a checkout of dm_control's suite, or of mujoco_menagerie) read by
   rbody.from_mjcf as it is (overlapping geoms summed as MuJoCo does: overlapping_geoms="sum", what a user is told
   to pass), and again with contacts disabled (<flag contact="disable"/>, the contact layer being
   another issue); each that loads is run 2 s from its reference pose at its own timestep, and MuJoCo runs the same
   file: how far MuJoCo's joints pass their stops (rbody's never do beyond round-off), and the largest difference of
   the two runs' joint coordinates;
4. with --published FILE...: each file (a published quadruped, a humanoid) with contacts disabled, run 1 s by both
   engines with the file's own integrator at its own step (rbody: scene.file_method, the constraint layer's
   time-stepping with MuJoCo's step as its free motion): the cost per step with its spread, and the largest
   difference of the two runs' joint coordinates; with --with-contacts, the files as published (their contacts on:
   the pairs rbody computes).
Benchmarks are not tests: compare figures of one run with each other; the machine may be shared.
"""

from __future__ import annotations

import argparse
import re
import sys
import time
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parents[1]))

import mujoco  # noqa: E402
import numba  # noqa: E402
import scipy  # noqa: E402

import rbody  # noqa: E402
from rbody import from_mjcf, simulate  # noqa: E402
from validation.hard import constraints as hard  # noqa: E402
from validation.machine import describe_machine  # noqa: E402

DTS = (1e-3, 5e-4, 2.5e-4, 1e-4)
TIMECONSTS = (0.02, 0.005, 0.002, 0.0005)

QUADRUPED = """<mujoco model="quadruped_like">
  <compiler angle="degree"/>
  <option timestep="0.002"><flag contact="disable"/></option>
  <default><joint axis="0 1 0" damping="0.05" frictionloss="0.2" armature="0.01"/>
    <geom type="capsule" size="0.03" density="800" contype="0" conaffinity="0"/></default>
  <worldbody>
    <body name="torso" pos="0 0 0.6"><freejoint/><geom type="box" size="0.3 0.12 0.06" density="500"/>
      {legs}
    </body>
  </worldbody>
</mujoco>"""
LEG = """<body name="{n}_hip" pos="{x} {y} 0"><joint name="{n}_abduct" axis="1 0 0" range="-30 30"/>
        <geom fromto="0 0 0 0 {s}0.05 0" size="0.04"/>
        <body name="{n}_thigh" pos="0 {s}0.05 0"><joint name="{n}_swing" range="-60 60"/>
          <geom fromto="0 0 0 0 0 -0.25"/>
          <body name="{n}_shin" pos="0 0 -0.25"><joint name="{n}_knee" range="-150 -10"/>
            <geom fromto="0 0 0 0 0 -0.25" size="0.025"/></body></body></body>"""


def quadruped_xml() -> str:
    legs = "".join(LEG.format(n=n, x=x, y=y, s="-" if y < 0 else "")
                   for n, x, y in (("fl", 0.25, 0.12), ("fr", 0.25, -0.12), ("hl", -0.25, 0.12), ("hr", -0.25, -0.12)))
    return QUADRUPED.format(legs=legs)


def header() -> None:
    print(describe_machine())
    print(f"rbody {rbody.__file__}; numpy {np.__version__}, numba {numba.__version__}, scipy {scipy.__version__}, "
          f"mujoco {mujoco.__version__}")
    print()


# ----- 1. the sweep ---------------------------------------------------------------------------------------------

def sweep() -> None:
    print("1. MuJoCo's divergence from the rigid limit against its time constant and step (RK4), rbody beside it")
    for name, key in (("limit_pendulum", "solreflimit"), ("friction_oscillator", "solreffriction")):
        print(f"\n{name} ({hard.CASES[name].summary}); MuJoCo's {key} = 'timeconst 1'")
        rows = []
        for dt in DTS:
            ours = hard.divergence(name, "rbody", dt)
            rows.append((f"{dt:g}", "rbody (rigid)", "", ours))
            for timeconst in TIMECONSTS:
                theirs = hard.divergence(name, "mujoco", dt, {key: f"{timeconst} 1"})
                clamped = "clamped to 2 dt" if timeconst < 2 * dt else ""
                rows.append((f"{dt:g}", f"mujoco tc={timeconst:g}", clamped, theirs))
        metrics = [k for k in rows[0][3] if k != "seconds"]
        print("| dt [s] | engine | note | " + " | ".join(metrics) + " |")
        print("|---|---|---|" + "---|" * len(metrics))
        for dt, engine, note, values in rows:
            print(f"| {dt} | {engine} | {note} | " + " | ".join(f"{values[m]:.3g}" for m in metrics) + " |")


# ----- 2. cost per step ------------------------------------------------------------------------------------------

def spread(samples: list[float]) -> str:
    values = np.array(samples) * 1e6
    return f"{values.min():.1f} / {np.median(values):.1f} / {values.max():.1f}"


def mujoco_step_seconds(xml: str | Path, qpos0, qvel0, dt: float, steps: int, integrator: str) -> float:
    """Seconds per mj_step of the model (an XML string, or a file whose assets resolve beside it)."""
    model = mujoco.MjModel.from_xml_path(str(xml)) if isinstance(xml, Path) else mujoco.MjModel.from_xml_string(xml)
    model.opt.timestep = dt
    model.opt.integrator = getattr(mujoco.mjtIntegrator, f"mjINT_{integrator.upper()}")
    data = mujoco.MjData(model)
    data.qpos[:] = qpos0
    data.qvel[:] = qvel0
    start = time.perf_counter()
    for _ in range(steps):
        mujoco.mj_step(model, data)
    return (time.perf_counter() - start) / steps


def cost(repeats: int) -> None:
    print("\n2. Cost per step [us] (min / median / max over the repeats), contacts off, dt = 2 ms, 2 s")
    dt, t_end = 2e-3, 2.0
    steps = int(round(t_end / dt))
    print("| model | dofs | constraints | rbody events (rk4) | rbody moreau | rbody mujoco_euler | MuJoCo Euler | "
          "MuJoCo RK4 | events |")
    print("|---|---|---|---|---|---|---|---|---|")
    rng = np.random.default_rng(0)
    for name, xml in (("humanoid-like (LIMBS)", hard.LIMBS), ("quadruped-like", quadruped_xml())):
        scene = from_mjcf(xml, t_end=t_end)
        qvel0 = np.zeros(scene.multibody.nv)
        if "quadruped" in name:
            qvel0[6:] = rng.uniform(-3, 3, scene.multibody.nv - 6)
            scene = from_mjcf(xml, t_end=t_end, qvel0=qvel0)
        units = len(scene.constraint_table.units)
        figures, events = {}, 0
        for method in ("rk4", "moreau", "mujoco_euler"):
            run = simulate(scene, dt=dt, method=method)  # warm-up (compilation, caches)
            events = run.meta["events"] if method == "rk4" else events
            samples = []
            for _ in range(repeats):
                start = time.perf_counter()
                simulate(scene, dt=dt, method=method)
                samples.append((time.perf_counter() - start) / steps)
            figures[method] = spread(samples)
        for integrator in ("Euler", "RK4"):
            mujoco_step_seconds(xml, scene.qpos0, qvel0, dt, 100, integrator)
            figures[integrator] = spread([mujoco_step_seconds(xml, scene.qpos0, qvel0, dt, steps, integrator)
                                          for _ in range(repeats)])
        print(f"| {name} | {scene.multibody.nv} | {units} units | {figures['rk4']} | {figures['moreau']} | "
              f"{figures['mujoco_euler']} | {figures['Euler']} | {figures['RK4']} | {events} |")


# ----- 3. published models ---------------------------------------------------------------------------------------

def without_contacts(text: str) -> str:
    """The document with <flag contact="disable"/> in its <option> (one added when it has none)."""
    if re.search(r"<flag\b[^>]*\bcontact=", text):
        return re.sub(r'(<flag\b[^>]*\bcontact=)"[a-z]*"', r'\1"disable"', text, count=1)
    if re.search(r"<flag\b", text):
        return re.sub(r"<flag\b", '<flag contact="disable"', text, count=1)
    if re.search(r"<option\b[^>]*/>", text):
        return re.sub(r"<option\b([^>]*)/>", r'<option\1><flag contact="disable"/></option>', text, count=1)
    if re.search(r"<option\b[^>]*>", text):
        return re.sub(r"(<option\b[^>]*>)", r'\1<flag contact="disable"/>', text, count=1)
    return re.sub(r"(<mujoco\b[^>]*>)", r'\1<option><flag contact="disable"/></option>', text, count=1)


def first_line(error: Exception) -> str:
    text = str(error).split("\n")[0]
    return text if len(text) < 160 else text[:157] + "..."


def published(folder: Path) -> None:
    print(f"\n3. Published models in {folder}: as they are, and with contacts disabled; 2 s from the reference pose")
    print("| model | as is | contacts off | rbody 2 s | events | MuJoCo past its stops [rad] | max |dq| rbody-MuJoCo |")
    print("|---|---|---|---|---|---|---|")
    for path in sorted(folder.glob("*.xml")):
        text = path.read_text()
        if "<worldbody" not in text:
            continue
        try:
            from_mjcf(path, overlapping_geoms="sum")  # MuJoCo's own sum of overlapping geoms, as a user would ask
            as_is = "loads"
        except Exception as error:  # noqa: BLE001 - the report names every refusal
            as_is = f"refused: {first_line(error)}"
        modified = path.with_name(f".{path.stem}.nocontact.xml")
        modified.write_text(without_contacts(text))
        try:
            try:
                scene = from_mjcf(modified, t_end=2.0, overlapping_geoms="sum")
                loads = "loads"
            except Exception as error:  # noqa: BLE001
                print(f"| {path.name} | {as_is} | refused: {first_line(error)} | | | | |")
                continue
            dt = float(scene.timestep)
            start = time.perf_counter()
            try:
                run = simulate(scene, dt=dt, allow_large=True)
                ran = f"ran ({time.perf_counter() - start:.1f} s)"
                events = run.meta.get("events", 0)
            except Exception as error:  # noqa: BLE001
                print(f"| {path.name} | {as_is} | {loads} | failed: {first_line(error)} | | | |")
                continue
            t, qpos, _sites, _seconds = hard.run_mujoco(modified, scene.qpos0, 2.0, dt,
                                                        integrator=str(scene.integrator or "Euler"))
            past = hard._excursions(t, qpos, modified).max() if scene.limits else 0.0
            count = min(len(t), len(run.t))
            difference = float(np.abs(qpos[:count] - run["qpos"][:count]).max())
            print(f"| {path.name} | {as_is} | {loads} | {ran} | {events} | {past:.3g} | {difference:.3g} |")
        finally:
            modified.unlink(missing_ok=True)


def published_cost(paths: list[Path], repeats: int, t_end: float = 1.0, contacts: bool = False) -> None:
    """Cost per step of published files with their limits and dry friction, contacts off (contacts=True: as
    published, their contacts on), each engine with the file's own integrator at the file's own step (rbody:
    scene.file_method, the constraint layer's time-stepping with that step as its free motion): the whole simulate
    call per step against mj_step in a loop, min / median / max."""
    print(f"\n4. Published models, contacts {'on' if contacts else 'off'}, the file's integrator and step, {t_end:g} s "
          "from the reference pose: cost per step [us] (min / median / max over the repeats)")
    print("| model | dofs | constraint units | integrator, dt | rbody | MuJoCo | ratio (medians) | max |dq| rbody-MuJoCo |")
    print("|---|---|---|---|---|---|---|---|")
    for path in paths:
        modified = path.with_name(f".{path.stem}.{'copy' if contacts else 'nocontact'}.xml")
        modified.write_text(path.read_text() if contacts else without_contacts(path.read_text()))
        try:
            scene = from_mjcf(modified, t_end=t_end, overlapping_geoms="sum")
            dt, method = float(scene.timestep), scene.file_method
            steps = int(round(t_end / dt))
            run = simulate(scene, dt=dt, method=method, allow_large=True)  # warm-up (compilation, caches)
            samples = []
            for _ in range(repeats):
                start = time.perf_counter()
                simulate(scene, dt=dt, method=method, allow_large=True)
                samples.append((time.perf_counter() - start) / steps)
            integrator = str(scene.integrator or "Euler")
            mujoco_step_seconds(modified, scene.qpos0, np.zeros(scene.multibody.nv), dt, 100, integrator)
            theirs = [mujoco_step_seconds(modified, scene.qpos0, np.zeros(scene.multibody.nv), dt, steps,
                                          integrator) for _ in range(repeats)]
            t, qpos, _sites, _seconds = hard.run_mujoco(modified, scene.qpos0, t_end, dt, integrator=integrator)
            count = min(len(t), len(run.t))
            difference = float(np.abs(qpos[:count] - run["qpos"][:count]).max())
            units = len(scene.constraint_table.units) if scene.constraint_table is not None else 0
            print(f"| {path.name} | {scene.multibody.nv} | {units} | {integrator}, {dt:g} | {spread(samples)} | "
                  f"{spread(theirs)} | {np.median(samples) / np.median(theirs):.1f} | {difference:.3g} |")
        except Exception as error:  # noqa: BLE001 - the report names every refusal
            print(f"| {path.name} | | | | failed: {first_line(error)} | | | |")
        finally:
            modified.unlink(missing_ok=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--repeats", type=int, default=5)
    parser.add_argument("--models", type=Path, default=None, help="a folder of MJCF files to try")
    parser.add_argument("--skip-sweep", action="store_true")
    parser.add_argument("--skip-cost", action="store_true")
    parser.add_argument("--published", type=Path, nargs="*", default=[],
                        help="MJCF files (a quadruped, a humanoid) to time with their own integrator, contacts off")
    parser.add_argument("--with-contacts", action="store_true",
                        help="time the --published files as published, their contacts on")
    args = parser.parse_args()
    header()
    if not args.skip_sweep:
        sweep()
    if not args.skip_cost:
        cost(args.repeats)
    if args.models is not None:
        published(args.models)
    if args.published:
        published_cost(args.published, args.repeats, contacts=args.with_contacts)


if __name__ == "__main__":
    main()
