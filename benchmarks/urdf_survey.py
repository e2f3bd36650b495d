"""Which published URDF robots rbody loads, which it does not, and why: every URDF of the collections given, tried
as a user would (rbody.from_urdf(path, package_dirs=...), its limits, friction and mimics held), then

- its dynamics against Pinocchio's own parse of the same file (pin.buildModelFromUrdf: the mass matrix, bias forces
  and forward dynamics at three random states, the largest difference relative to the largest entry),
- a short run (0.1 s at dt = 1 ms, rbody's default method; a run over 30 s of wall time is stopped and said so),
- MuJoCo's own URDF loader (mujoco.MjModel.from_xml_path) and Bullet's (pybullet.loadURDF, DIRECT), each loads or
  its first line of error.

    python benchmarks/urdf_survey.py --collection NAME=FOLDER [--collection ...] [--package-dir DIR ...]
        [--moving-only] [--out docs/urdf_survey.md]

NAME=FOLDER: a collection and the folder searched for *.urdf; --package-dir: folders holding the packages that
package:// paths name (each collection's parent is added); --moving-only: skip files with no moving joint (pybullet's
data holds hundreds of static objects). Writes a Markdown page (to a temporary name, then renamed) with the
machine, the versions, a summary per collection and one row per file. No published file is copied anywhere.
"""

from __future__ import annotations

import argparse
import signal
import sys
import time
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path

import numpy as np

sys.path.insert(0, str(Path(__file__).resolve().parent))  # the sibling survey's helpers
from mjcf_survey import quiet  # noqa: E402

RUN_SECONDS = 30    # wall-time limit of the short run [s]
RUN_T_END = 0.1     # [s]
STATES = 3          # random states at which the dynamics are compared with Pinocchio's


class Timeout(Exception):
    pass


def _alarm(signum, frame):
    raise Timeout()


def moving_joints(path: Path) -> int | None:
    """The number of joints that are not fixed, or None for a file that is not XML."""
    try:
        root = ET.parse(path).getroot()
    except ET.ParseError:
        return None
    return sum(1 for j in root.iter("joint") if j.get("type") not in (None, "fixed"))


def first_line(error: BaseException, limit: int = 220) -> str:
    text = str(error).strip().splitlines()[0] if str(error).strip() else type(error).__name__
    text = text.replace("|", "/")
    return text if len(text) <= limit else text[:limit] + "..."


def why(error: BaseException, path: Path) -> str:
    """rbody's message without the file's path (the table names the file)."""
    text = first_line(error, 400)
    return text.replace(str(path) + ", ", "").replace(str(path), "<file>")


def random_states(model, rng):
    for _ in range(STATES):
        q, v = rng.normal(size=model.nq), rng.normal(size=model.nv)
        for kind, address in zip(model.arrays.joint_kinds, model.arrays.qposadr):
            if kind in ("free", "ball"):
                at = address + 3 if kind == "free" else address
                q[at:at + 4] /= np.linalg.norm(q[at:at + 4])
        yield q, v


def try_rbody(path: Path, package_dirs: list[str]) -> dict:
    import rbody
    from rbody.urdf import URDFError

    out: dict = {}
    try:
        scene = rbody.from_urdf(path, package_dirs=package_dirs, t_end=RUN_T_END)
    except (URDFError, ValueError) as error:
        out["rbody"] = "refused: " + why(error, path)
        return out
    tree = scene.tree
    out["scene"] = scene
    out["rbody"] = "loads"
    out["size"] = f"{scene.multibody.nq}/{scene.multibody.nv}"
    held = [f"{sum(j.range is not None for j in tree.joints)} limits"] if any(j.range is not None for j in tree.joints) else []
    held += [f"{sum(j.frictionloss > 0 for j in tree.joints)} friction"] if any(j.frictionloss > 0 for j in tree.joints) else []
    held += [f"{len(tree.equalities)} mimic"] if tree.equalities else []
    out["held"] = ", ".join(held) or "-"
    violations = [n for n in scene.import_notes if "triangle inequality" in n or "negative principal" in n]
    out["inertia"] = f"{len(violations)} non-physical" if violations else "-"
    return out


def try_pinocchio(out: dict) -> None:
    from validation.backends import pinocchio as pin_backend

    scene = out["scene"]
    try:
        model = pin_backend.build(scene)
        worst = 0.0
        for q, v in random_states(scene.multibody, np.random.default_rng(1)):
            theirs = model.dynamics(q, v)
            ours = {"mass_matrix": scene.multibody.mass_matrix(q), "bias": scene.multibody.bias_forces(q, v),
                    "qacc": scene.multibody.forward_dynamics(q, v)}
            floor = {"mass_matrix": 1e-300, "qacc": 1.0, "bias": float(np.max(np.abs(theirs["mass_matrix"])))}
            for key, value in ours.items():
                # relative to the largest entry, or where every entry is below that, to 1 m/s^2 (rad/s^2) for qacc
                # and to the force of that acceleration (the largest entry of M) for bias: a robot whose joints feel
                # no force at a state (wheels spinning about symmetric axes) has bias and qacc ~ 1e-38 in both
                scale = max(float(np.max(np.abs(theirs[key]))), floor[key])
                worst = max(worst, float(np.max(np.abs(value - theirs[key]))) / scale)
        out["pinocchio"] = f"{worst:.1e}"
    except Exception as error:  # Pinocchio's parse or the map between the models: said, not hidden
        out["pinocchio"] = "no: " + first_line(error, 120)


def try_run(out: dict) -> None:
    import rbody

    scene = out["scene"]
    previous = signal.signal(signal.SIGALRM, _alarm)
    signal.alarm(RUN_SECONDS)
    start = time.perf_counter()
    try:
        with warnings.catch_warnings():
            warnings.simplefilter("ignore")
            run = rbody.simulate(scene, dt=1e-3)
        finite = bool(np.all(np.isfinite(run["qpos"])))
        out["run"] = f"{time.perf_counter() - start:.2g} s" + ("" if finite else " (non-finite)")
    except Timeout:
        out["run"] = f"stopped after {RUN_SECONDS} s"
    except Exception as error:
        out["run"] = f"{type(error).__name__}: " + first_line(error, 160)
    finally:
        signal.alarm(0)
        signal.signal(signal.SIGALRM, previous)


def try_mujoco(path: Path) -> str:
    import mujoco

    try:
        with quiet():
            mujoco.MjModel.from_xml_path(str(path))
        return "compiles"
    except Exception as error:
        return "no: " + first_line(error, 140)


def try_bullet(path: Path) -> str:
    try:
        import pybullet as pb
    except ImportError:
        return "not installed"
    client = pb.connect(pb.DIRECT)
    try:
        with quiet():
            pb.loadURDF(str(path), useFixedBase=True, flags=pb.URDF_USE_INERTIA_FROM_FILE, physicsClientId=client)
        return "loads"
    except Exception as error:
        return "no: " + first_line(error, 100)
    finally:
        pb.disconnect(client)


WARM_UP = ('<robot name="w"><link name="a"/><link name="b"><inertial><mass value="1"/><inertia ixx="1" iyy="1" '
           'izz="1" ixy="0" ixz="0" iyz="0"/></inertial></link><joint name="j" type="revolute"><parent link="a"/>'
           '<child link="b"/><limit lower="-1" upper="1" effort="1" velocity="1"/></joint></robot>')


def survey(collections: list[tuple[str, Path]], package_dirs: list[str], moving_only: bool, log) -> list[dict]:
    import rbody

    rbody.simulate(rbody.from_urdf(WARM_UP, t_end=0.01), dt=1e-3)  # compiles the engine once: runs below are runs
    rows = []
    for name, folder in collections:
        dirs = package_dirs + [str(folder.parent), str(folder)]
        for path in sorted(folder.rglob("*.urdf")):
            joints = moving_joints(path)
            if moving_only and not joints:
                continue
            row = {"collection": name, "file": str(path.relative_to(folder)), "joints": joints}
            started = time.perf_counter()
            row.update(try_rbody(path, dirs))
            if "scene" in row:
                try_pinocchio(row)
                try_run(row)
                del row["scene"]
            row["mujoco"] = try_mujoco(path)
            row["bullet"] = try_bullet(path)
            print(f"[survey] {name}/{row['file']}: {row['rbody'][:80]} ({time.perf_counter() - started:.1f} s)",
                  file=log, flush=True)
            rows.append(row)
    return rows


def markdown(rows: list[dict], collections: list[tuple[str, Path]], command: str, notes: list[str]) -> str:
    import mujoco
    import pinocchio

    import rbody
    from validation.machine import describe_machine

    try:
        from importlib.metadata import version
        bullet = version("pybullet")
    except Exception:
        bullet = "not installed"
    lines = ["# Published URDF robots in rbody", "",
             "Every URDF of the collections below tried as a user would: `rbody.from_urdf(path, package_dirs=...)` "
             "(limits, dry friction and mimics held by the constraint layer, the root link welded to the world), "
             "its mass matrix, bias forces and forward dynamics against Pinocchio's own parse of the same file "
             f"(largest difference relative to the largest entry; the forward dynamics relative to at least 1 m/s^2 or rad/s^2 and the bias forces to at least the force of that acceleration, at {STATES} random states), a {RUN_T_END:g} s run "
             f"at dt = 1 ms (wall time; stopped after {RUN_SECONDS} s), and the same file through MuJoCo's URDF "
             "loader and Bullet's (`pybullet.loadURDF`). No published file is copied into rbody.", "",
             f"- command: `{command}`",
             f"- machine: {describe_machine()}",
             f"- versions: rbody {getattr(rbody, '__version__', '(this checkout)')}, pin {pinocchio.__version__}, "
             f"mujoco {mujoco.__version__}, pybullet {bullet}", ""]
    lines += [f"- {note}" for note in notes]
    lines += ["", "## Summary", "", "| collection | files | rbody loads | equal to Pinocchio (<= 1e-10) | runs 0.1 s | "
              "MuJoCo's loader compiles | Bullet loads |", "|---|---|---|---|---|---|---|"]
    for name, _ in collections:
        mine = [r for r in rows if r["collection"] == name]
        loads = [r for r in mine if r["rbody"] == "loads"]
        equal = [r for r in loads if not r.get("pinocchio", "no").startswith("no") and float(r["pinocchio"]) <= 1e-10]
        ran = [r for r in loads if r.get("run", "").endswith(" s") and "stopped" not in r["run"]
               and "Error" not in r["run"]]
        lines.append(f"| {name} | {len(mine)} | {len(loads)} | {len(equal)} | {len(ran)} | "
                     f"{sum(r['mujoco'] == 'compiles' for r in mine)} | {sum(r['bullet'] == 'loads' for r in mine)} |")
    refusals: dict[str, list[str]] = {}
    for r in rows:
        if r["rbody"].startswith("refused"):
            refusals.setdefault(r["collection"], []).append(f"`{r['file']}`: {r['rbody'].removeprefix('refused: ')}")
    if refusals:
        lines += ["", "## Refused by rbody, and why", ""]
        for name, items in refusals.items():
            lines += [f"{name}:", ""] + [f"- {item}" for item in items] + [""]
    for name, _ in collections:
        lines += ["", f"## {name}", "", "| file | moving joints | rbody | nq/nv | held | inertia | vs Pinocchio | "
                  "0.1 s run | MuJoCo's loader | Bullet |", "|---|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if r["collection"] != name:
                continue
            status = "loads" if r["rbody"] == "loads" else "refused (below)"
            lines.append(f"| {r['file']} | {r['joints']} | {status} | {r.get('size', '-')} | {r.get('held', '-')} | "
                         f"{r.get('inertia', '-')} | {r.get('pinocchio', '-')} | {r.get('run', '-')} | "
                         f"{r['mujoco']} | {r['bullet']} |")
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--collection", action="append", required=True, metavar="NAME=FOLDER")
    parser.add_argument("--package-dir", action="append", default=[], metavar="DIR")
    parser.add_argument("--moving-only", action="store_true")
    parser.add_argument("--note", action="append", default=[], help="a line for the page's header")
    parser.add_argument("--out", type=Path, default=Path("docs/urdf_survey.md"))
    args = parser.parse_args(argv)
    collections = []
    for item in args.collection:
        name, _, folder = item.partition("=")
        if not name or not Path(folder).is_dir():
            parser.error(f"--collection {item!r}: expected NAME=FOLDER with an existing folder")
        collections.append((name, Path(folder).resolve()))
    rows = survey(collections, args.package_dir, args.moving_only, sys.stderr)
    from rbody.files import write_atomic

    command = "python benchmarks/urdf_survey.py " + " ".join(sys.argv[1:] if argv is None else argv)
    write_atomic(args.out, markdown(rows, collections, command, args.note))
    print(f"[survey] {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
