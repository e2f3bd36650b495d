"""Which published MJCF models rbody loads, which it refuses, and why: every MJCF file of the collections given, tried
as a user would (rbody.from_mjcf(path)), twice: as published, and with <flag contact="disable"/> injected (a copy
beside the original, so that its includes and assets resolve), because rbody's contacts are young (primitive pairs
only). For each:

- rbody: loads / refused (the first refusal's message, shortened) / an exception that is not rbody's own (a bug);
- for a file that loads: nq, nv, nu, contact pairs, constraint units, the file's integrator;
- MuJoCo's compile of the same file (mujoco.MjModel.from_xml_path);
- a 0.2 s run of both from the reference pose (or the file's first keyframe, its ctrl held), at the file's own
  timestep, rbody with the file's integrator (scene.file_method) where it offers it, else the constraint layer's
  method (moreau for contacts, rk4 for limits and friction alone); the largest |qpos difference| rbody vs MuJoCo
  over the run, and whether either failed (an exception, a warning of MuJoCo's, a non-finite state).

Each file runs in a child process (forked from a parent that compiled rbody's loops once) stopped after
--time-limit seconds, so that one model cannot stall the survey.

    python benchmarks/mjcf_survey.py --collection NAME=FOLDER[:GLOB] [--collection ...] [--exclude GLOB ...]
        [--stand-ins] [--qvel0 V] [--time-limit S] [--note TEXT ...] [--out docs/mjcf_survey.md]
        [--rows ROWS.json] [--redraw ROWS.json]

GLOB (default *.xml) is matched below FOLDER; --exclude drops files whose name matches. --stand-ins: a mesh or
texture file a model names that is missing (a published snapshot whose binary assets were not stored) is replaced
by a stand-in at its path (a tetrahedron, STL or OBJ as the name says; a 2x2 PNG), and the table says which model
ran on stand-ins: its load/refusal status stays meaningful and rbody and MuJoCo run the same stand-in geometry.
No published file is copied into rbody; the survey writes only beside the files it reads (the contacts-off copies,
the stand-ins) and the page given by --out.
"""

from __future__ import annotations

import argparse
import contextlib
import fnmatch
import json
import multiprocessing
import os
import re
import shlex
import struct
import sys
import time
import traceback
import warnings
import xml.etree.ElementTree as ET
import zlib
from pathlib import Path

import numpy as np

# Each file runs in a child forked from this process: GNU OpenMP (numba's default threading layer where it is
# installed) refuses to run in a forked child, numba's own workqueue layer does not.
os.environ.setdefault("NUMBA_THREADING_LAYER", "workqueue")

RUN_T_END = 0.2       # [s] the run of both engines
TIME_LIMIT = 120.0    # [s] wall time of one file's child process (both variants are separate children)
STAND_IN_MARK = b"rbody mjcf survey stand-in"
NOCONTACT_TAG = ".nocontact"


@contextlib.contextmanager
def quiet():
    """The process's stdout and stderr (file descriptors 1 and 2: MuJoCo's C and Bullet's C++ print there) muted
    (benchmarks/urdf_survey.py uses it too)."""
    sys.stdout.flush()
    sys.stderr.flush()
    saved = [os.dup(1), os.dup(2)]
    null = os.open(os.devnull, os.O_WRONLY)
    os.dup2(null, 1)
    os.dup2(null, 2)
    try:
        yield
    finally:
        os.dup2(saved[0], 1)
        os.dup2(saved[1], 2)
        for fd in saved + [null]:
            os.close(fd)


def first_line(error: BaseException | str, limit: int = 220) -> str:
    text = str(error).strip()
    text = text.splitlines()[0] if text else type(error).__name__
    text = text.replace("|", "/")
    return text if len(text) <= limit else text[:limit] + "..."


def why(error: BaseException, path: Path) -> str:
    """rbody's message without the file's path (the table names the file)."""
    text = first_line(error, 400)
    for form in (str(path), path.name):
        text = text.replace(form + ", ", "").replace(form, "<file>")
    return text.replace(NOCONTACT_TAG, "")


def reason_of(message: str) -> str:
    """A refusal's reason with names and numbers taken out, so that refusals of one kind count together: the text
    after the element ("line N, <body name='x'>: ..."), quoted names as '…', numbers as #, cut at the first '.' or
    ';' or '('."""
    text = re.sub(r"^.*?line \d+, <[^>]*>: ", "", message)
    text = re.sub(r"^.*?line \d+: ", "", text)
    text = re.sub(r" \(line \d+\)", "", text)
    text = re.sub(r"'[^']*'", "'…'", text)
    text = re.sub(r"\"[^\"]*\"", "'…'", text)
    text = re.sub(r"[-+]?\d+(\.\d+)?(e[-+]?\d+)?", "#", text)
    return re.split(r"[.;(]", text, maxsplit=1)[0].strip()


# ----- the files -------------------------------------------------------------------------------------------------

def includes_and_assets(path: Path, seen: set[Path] | None = None) -> tuple[list[Path], list[Path]]:
    """The files a model includes (recursively) and the mesh and texture files it names, resolved as MuJoCo
    resolves them (includes relative to the including file; meshdir/texturedir/assetdir relative to the main
    file's folder)."""
    seen = set() if seen is None else seen
    main = path
    root = ET.parse(path).getroot()
    files, elements = [path], []

    def walk(file: Path, node: ET.Element) -> None:
        for child in node:
            if child.tag == "include" and child.get("file"):
                inc = (file.parent / child.get("file")).resolve()
                if inc in seen or not inc.exists():
                    continue
                seen.add(inc)
                files.append(inc)
                walk(inc, ET.parse(inc).getroot())
            else:
                elements.append(child)
                walk(file, child)

    walk(path, root)
    compiler = [e for e in elements if e.tag == "compiler"]
    dirs = {"mesh": "", "texture": ""}
    for c in compiler:
        if c.get("assetdir"):
            dirs = {"mesh": c.get("assetdir"), "texture": c.get("assetdir")}
        if c.get("meshdir"):
            dirs["mesh"] = c.get("meshdir")
        if c.get("texturedir"):
            dirs["texture"] = c.get("texturedir")
    assets = []
    for e in elements:
        if e.tag in ("mesh", "texture", "hfield", "skin") and e.get("file"):
            kind = "mesh" if e.tag in ("mesh", "skin") else "texture"
            assets.append(main.parent / dirs[kind if e.tag != "hfield" else "texture"] / e.get("file"))
        for attr in ("fileright", "fileleft", "fileup", "filedown", "filefront", "fileback"):
            if e.tag == "texture" and e.get(attr):
                assets.append(main.parent / dirs["texture"] / e.get(attr))
    return files, assets


def stand_in_stl(path: Path) -> None:
    """A binary STL tetrahedron of 5 cm edges (outward faces)."""
    v = np.array([[0, 0, 0], [0.05, 0, 0], [0, 0.05, 0], [0, 0, 0.05]], dtype=np.float32)
    faces = [(0, 2, 1), (0, 1, 3), (0, 3, 2), (1, 2, 3)]
    data = bytearray(STAND_IN_MARK.ljust(80, b" ") + struct.pack("<I", len(faces)))
    for a, b, c in faces:
        n = np.cross(v[b] - v[a], v[c] - v[a])
        n = n / np.linalg.norm(n)
        data += struct.pack("<12fH", *n, *v[a], *v[b], *v[c], 0)
    path.write_bytes(bytes(data))


def stand_in_obj(path: Path) -> None:
    path.write_text("# rbody mjcf survey stand-in\nv 0 0 0\nv 0.05 0 0\nv 0 0.05 0\nv 0 0 0.05\n"
                    "f 1 3 2\nf 1 2 4\nf 1 4 3\nf 2 3 4\n")


def stand_in_png(path: Path) -> None:
    """A 2x2 grey RGB PNG."""
    def chunk(kind: bytes, body: bytes) -> bytes:
        return struct.pack(">I", len(body)) + kind + body + struct.pack(">I", zlib.crc32(kind + body) & 0xFFFFFFFF)
    raw = b"".join(b"\x00" + b"\x80\x80\x80" * 2 for _ in range(2))
    path.write_bytes(b"\x89PNG\r\n\x1a\n" + chunk(b"IHDR", struct.pack(">IIBBBBB", 2, 2, 8, 2, 0, 0, 0))
                     + chunk(b"tEXt", b"Comment\x00" + STAND_IN_MARK)
                     + chunk(b"IDAT", zlib.compress(raw)) + chunk(b"IEND", b""))


def make_stand_ins(path: Path) -> list[str]:
    """Stand-ins for the model's missing meshes and textures; the names of those written (relative to the model's
    folder)."""
    _files, assets = includes_and_assets(path)
    written = []
    for asset in assets:
        if asset.exists():
            with open(asset, "rb") as file:
                head = file.read(200)
            if STAND_IN_MARK in head:  # written by an earlier survey
                written.append(os.path.relpath(asset, path.parent))
            continue
        asset.parent.mkdir(parents=True, exist_ok=True)
        suffix = asset.suffix.lower()
        if suffix == ".stl":
            stand_in_stl(asset)
        elif suffix == ".obj":
            stand_in_obj(asset)
        elif suffix == ".png":
            stand_in_png(asset)
        else:
            continue
        written.append(os.path.relpath(asset, path.parent))
    return written


def has_key(path: Path) -> bool:
    """Whether the model (its includes too) has a <key> element. MuJoCo also makes keys at qpos0 from
    <size nkey="n">, which rbody ignores: such a model starts at its reference pose in both engines."""
    files, _assets = includes_and_assets(path)
    return any(ET.parse(f).getroot().find(".//keyframe/key") is not None for f in files)


def contacts_off_copy(path: Path) -> Path:
    """A copy of the file beside it with <option><flag contact="disable"/></option> (the option's own flag made to
    say so where it has one). Comments are not kept."""
    tree = ET.parse(path)
    root = tree.getroot()
    option = root.find("option")
    if option is None:
        option = ET.Element("option")
        root.insert(0, option)
    flag = option.find("flag")
    if flag is None:
        flag = ET.SubElement(option, "flag")
    flag.set("contact", "disable")
    copy = path.with_name(path.stem + NOCONTACT_TAG + path.suffix)
    tree.write(copy, encoding="unicode")
    return copy


# ----- one file, in a child process -------------------------------------------------------------------------------

def method_for(scene) -> str:
    """The file's integrator where rbody offers it for the scene; else the constraint layer's: moreau for contacts
    (time-stepping only), rk4 (event-driven) for limits and friction alone."""
    methods = scene.methods
    if scene.file_method in methods:
        return scene.file_method
    if scene.tree.contacts and "moreau" in methods:
        return "moreau"
    return "rk4" if "rk4" in methods else methods[0]


def mujoco_run(path: Path, steps: int, qvel0: float, key: bool) -> dict:
    import mujoco

    out: dict = {}
    try:
        with quiet():
            model = mujoco.MjModel.from_xml_path(str(path))
    except Exception as error:
        out["mujoco"] = "no: " + first_line(error, 160)
        return out
    out["mujoco"] = "compiles"
    out["mj_sizes"] = (model.nq, model.nv, model.nu)
    out["nkey"] = model.nkey
    data = mujoco.MjData(model)
    if key and model.nkey:
        mujoco.mj_resetDataKeyframe(model, data, 0)
    data.qvel[:] = qvel0
    qpos = np.empty((steps + 1, model.nq))
    qpos[0] = data.qpos
    started = time.perf_counter()
    with quiet():
        for k in range(steps):
            mujoco.mj_step(model, data)
            qpos[k + 1] = data.qpos
    out["mj_seconds"] = time.perf_counter() - started
    warned = [mujoco.mjtWarning(i).name.removeprefix("mjWARN_") for i in range(len(data.warning))
              if data.warning[i].number]
    out["mj_failed"] = ", ".join(warned) + ("" if np.all(np.isfinite(qpos)) else " non-finite")
    out["mj_qpos"] = qpos
    out["moved"] = float(np.max(np.abs(qpos - qpos[0]), initial=0.0)) if np.all(np.isfinite(qpos)) else float("nan")
    out["mj_contacts"] = int(data.ncon)
    return out


def rbody_variant(path: Path, qvel0: float, overlap: str, queue) -> None:
    """Everything of one file (one variant), put on the queue as a dict."""
    import rbody
    from rbody.errors import SimulationError
    from rbody.mjcf.document import MJCFError

    out: dict = {}
    try:
        try:
            started = time.perf_counter()
            with warnings.catch_warnings():
                warnings.simplefilter("ignore")
                scene = rbody.from_mjcf(path, overlapping_geoms=overlap)
            out["load_seconds"] = time.perf_counter() - started
        except (MJCFError, ValueError) as error:
            out["rbody"] = "refused"
            out["why"] = why(error, path)
        except Exception as error:  # not rbody's own error class: a bug
            out["rbody"] = "bug"
            out["why"] = f"{type(error).__name__}: {why(error, path)}"
            out["trace"] = "".join(traceback.format_exception(error)[-3:])[-600:]
        else:
            model = scene.multibody
            out["rbody"] = "loads"
            out["sizes"] = (model.nq, model.nv, model.nu)
            out["contacts"] = len(scene.tree.contacts)
            table = scene.constraint_table
            out["units"] = len(table.units) if table is not None else 0
            out["integrator"] = scene.integrator or "Euler"
            out["timestep"] = scene.timestep
        steps = int(round(RUN_T_END / (out.get("timestep") or 0.002)))
        key = has_key(path)
        mj = mujoco_run(path, steps, qvel0, key)
        out.update({k: v for k, v in mj.items() if k != "mj_qpos"})
        if out["rbody"] == "loads":
            try:
                with warnings.catch_warnings(record=True) as caught:
                    warnings.simplefilter("always")
                    if key or qvel0:
                        scene = rbody.from_mjcf(path, keyframe=0 if key else None, overlapping_geoms=overlap,
                                                qvel0=np.full(scene.multibody.nv, qvel0) if qvel0 else None)
                    out["start"] = "key 0" if key else "qpos0"
                    out["method"] = method = method_for(scene)
                    started = time.perf_counter()
                    run = rbody.simulate(scene, dt=scene.timestep, method=method, t_end=steps * scene.timestep,
                                         progress=False)
                    out["rb_seconds"] = time.perf_counter() - started
                out["rb_warned"] = "; ".join(sorted({type(w.message).__name__ for w in caught}))
                qpos = np.asarray(run["qpos"])
                finite = bool(np.all(np.isfinite(qpos)))
                out["rb_failed"] = "" if finite else "non-finite"
                theirs = mj.get("mj_qpos")
                if theirs is not None and theirs.shape[1] == qpos.shape[-1]:
                    n = min(len(theirs), len(qpos))
                    out["dq"] = float(np.max(np.abs(qpos[:n] - theirs[:n]), initial=0.0)) if n else float("nan")
                    out["dq_rows"] = n
                elif theirs is not None:
                    out["dq"] = None
                    out["dq_note"] = f"nq {qpos.shape[-1]} vs MuJoCo's {theirs.shape[1]}"
            except (SimulationError, ValueError) as error:
                out["rb_failed"] = f"{type(error).__name__}: {why(error, path)}"
            except Exception as error:
                out["rb_failed"] = f"bug: {type(error).__name__}: {why(error, path)}"
                out["trace"] = "".join(traceback.format_exception(error)[-3:])[-600:]
    except Exception as error:  # the survey's own failure: said, never hidden
        out.setdefault("rbody", "bug")
        out["survey_error"] = f"{type(error).__name__}: {first_line(error)}"
    queue.put(out)


def in_child(path: Path, limit: float, qvel0: float, overlap: str = "refuse") -> dict:
    context = multiprocessing.get_context("fork")
    queue = context.Queue()
    child = context.Process(target=rbody_variant, args=(path, qvel0, overlap, queue))
    started = time.perf_counter()
    child.start()
    out = None
    try:
        out = queue.get(timeout=limit)
    except Exception:
        pass
    child.join(timeout=5)
    if child.is_alive():
        child.kill()
        child.join()
    if out is None:
        out = {"rbody": "stopped", "why": f"no answer within {limit:g} s (exit code {child.exitcode})"}
    out["wall"] = time.perf_counter() - started
    return out


WARM_UP = """<mujoco><option timestep="0.002" integrator="{integrator}"><flag contact="{contact}"/></option>
<worldbody><geom type="plane" size="1 1 0.1"/>
<body pos="0 0 1"><joint name="j" type="hinge" axis="0 1 0" range="-1 1" limited="{limited}" damping="0.1"/>
<geom type="capsule" fromto="0 0 0 0 0 -0.5" size="0.05" contype="0" conaffinity="0"/>
<body pos="0 0 -0.5"><joint type="hinge" axis="0 1 0" damping="0.1"/><geom type="sphere" size="0.05" pos="0 0 -0.3"/></body>
</body></worldbody><actuator><position joint="j" kp="10"/></actuator></mujoco>"""


def warm_up() -> None:
    """rbody's compiled loops made once in the parent, so that every forked child runs rather than compiles."""
    import rbody

    with warnings.catch_warnings():
        warnings.simplefilter("ignore")
        for integrator in ("Euler", "implicitfast", "implicit", "RK4"):
            for limited in ("false", "true"):
                for contact in ("enable", "disable"):
                    try:
                        scene = rbody.from_mjcf(WARM_UP.format(integrator=integrator, limited=limited,
                                                               contact=contact))
                        rbody.simulate(scene, dt=scene.timestep, method=method_for(scene), t_end=0.01, progress=False)
                    except Exception as error:
                        print(f"[survey] warm-up {integrator} {limited} {contact}: {first_line(error)}",
                              file=sys.stderr)


def survey(collections: list[tuple[str, Path, str]], excludes: list[str], stand_ins: bool, limit: float,
           qvel0: float, log) -> list[dict]:
    warm_up()
    rows = []
    for name, folder, pattern in collections:
        for path in sorted(folder.glob(pattern)):
            if NOCONTACT_TAG in path.name or any(fnmatch.fnmatch(path.name, g) for g in excludes):
                continue
            row = {"collection": name, "file": str(path.relative_to(folder))}
            try:
                row["stand_ins"] = make_stand_ins(path) if stand_ins else []
                copy = contacts_off_copy(path)
            except (ET.ParseError, OSError) as error:
                row["as_is"] = {"rbody": "not read", "why": first_line(error)}
                rows.append(row)
                continue
            row["as_is"] = in_child(path, limit, qvel0)
            row["no_contact"] = in_child(copy, limit, qvel0)
            if "overlap" in row["no_contact"].get("why", ""):
                row["summed"] = in_child(copy, limit, qvel0, "sum")
            print(f"[survey] {name}/{row['file']}: {row['as_is']['rbody']} / {row['no_contact']['rbody']} "
                  f"({row['as_is']['wall'] + row['no_contact']['wall']:.1f} s) "
                  f"{row['as_is'].get('why', '')[:100]}", file=log, flush=True)
            rows.append(row)
    return rows


# ----- the page ---------------------------------------------------------------------------------------------------

def status(v: dict) -> str:
    if v["rbody"] == "loads":
        return "loads"
    return {"refused": "refused", "bug": "**bug**", "stopped": "stopped"}.get(v["rbody"], v["rbody"])


def run_cell(v: dict) -> str:
    if v["rbody"] != "loads":
        return "-"
    if "rb_seconds" not in v or v.get("rb_failed"):
        return "fails: " + first_line(v.get("rb_failed", "no run"), 160)
    text = f"{v['method']}, {v['rb_seconds']:.2g} s"
    if v.get("rb_warned"):
        text += f" ({v['rb_warned']})"
    return text


def dq_cell(v: dict) -> str:
    if v.get("mujoco", "").startswith("no"):
        return "MuJoCo " + v["mujoco"][:80]
    if v.get("dq") is not None:
        text = f"{v['dq']:.1e}"
    elif v.get("dq_note"):
        text = v["dq_note"]
    else:
        return "-"
    if v.get("moved") is not None:
        text += f" (moved {v['moved']:.1e})"
    if v.get("mj_failed"):
        text += f" (MuJoCo: {v['mj_failed'].strip()})"
    return text


def sizes_cell(v: dict) -> str:
    if "sizes" not in v:
        return "-"
    nq, nv, nu = v["sizes"]
    return f"{nq}/{nv}/{nu} (loads in {v['load_seconds']:.2g} s)"


def variants(row: dict) -> list[tuple[str, dict]]:
    """The variants a file was tried in, named: as is, contacts off, contacts off + summed."""
    return [(label, row[key]) for label, key in (("as is", "as_is"), ("contacts off", "no_contact"),
                                                 ("off + summed", "summed")) if key in row]


def best_variant(row: dict) -> tuple[str, dict | None]:
    """The first variant that loads, or ("", None)."""
    for label, v in variants(row):
        if v.get("rbody") == "loads":
            return label, v
    return "", None


def markdown(rows: list[dict], collections, command: str, notes: list[str], limit: float, qvel0: float) -> str:
    import mujoco

    import rbody
    from validation.machine import describe_machine

    lines = ["# Published MJCF models in rbody", "",
             "Every MJCF file of the collections below tried as a user would, `rbody.from_mjcf(path)`, twice: as "
             "published, and with `<flag contact=\"disable\"/>` injected (contacts off: rbody computes contacts "
             "between planes, height fields, spheres, capsules, ellipsoids, cylinders, boxes and meshes). For a file "
             "that loads: its sizes, contact pairs and constraint units, "
             "and a "
             f"{RUN_T_END:g} s run of rbody and of MuJoCo on the same file, at the file's own timestep, from its "
             f"reference pose or its first keyframe (with the key's ctrl held; else ctrl = 0), every velocity "
             f"{qvel0:g} (rad/s or m/s) at the start, rbody with the file's "
             "integrator where it offers it (`simulate(scene, dt=scene.timestep, method=scene.file_method)`), else "
             "the constraint layer's method (moreau for contacts, event-driven rk4 for limits and friction): "
             "then the two differ by construction (rigid constraints in rbody, MuJoCo's soft ones, and a different "
             "scheme), and max |dq| measures that, not an import error. Each variant ran in a child process stopped "
             f"after {limit:g} s. Beside max |dq|, (moved X) is how far MuJoCo's own qpos moved over the run (a model "
             "that starts at an equilibrium and stays there compares nothing). No published file is copied into rbody.", "",
             f"- command: `{command}`",
             f"- machine: {describe_machine()}",
             f"- versions: rbody {getattr(rbody, '__version__', '(this checkout)')}, mujoco {mujoco.__version__}, "
             f"numpy {np.__version__}, Python {sys.version.split()[0]}", ""]
    lines += [f"- {note}" for note in notes]
    lines += ["", "## Summary", "",
              "Contacts off + summed: the contacts-off copy loaded with `from_mjcf(path, overlapping_geoms=\"sum\")`, "
              "tried only where the contacts-off copy was refused for overlapping geoms of one moving body (MuJoCo "
              "sums their masses; rbody refuses by default).", "",
              "| collection | files | load as is | load with contacts off | contacts off + summed | bugs (not rbody's "
              "error) | MuJoCo compiles | rbody runs 0.2 s (best variant) | max \\|dq\\| <= 1e-9 vs MuJoCo (best "
              "variant) |", "|---|---|---|---|---|---|---|---|---|"]
    for name, _, _ in collections:
        mine = [r for r in rows if r["collection"] == name and "no_contact" in r]
        best = [best_variant(r)[1] for r in mine]
        ran = [v for v in best if v and "rb_seconds" in v and not v.get("rb_failed")]
        close = [v for v in ran if v.get("dq") is not None and v["dq"] <= 1e-9]
        bugs = sum(v["rbody"] == "bug" or "bug:" in v.get("rb_failed", "") for r in mine for _, v in variants(r))
        summed = sum(r["no_contact"]["rbody"] == "loads" or r.get("summed", {}).get("rbody") == "loads" for r in mine)
        lines.append(f"| {name} | {len(mine)} | {sum(r['as_is']['rbody'] == 'loads' for r in mine)} | "
                     f"{sum(r['no_contact']['rbody'] == 'loads' for r in mine)} | {summed} | {bugs} | "
                     f"{sum(r['as_is'].get('mujoco') == 'compiles' for r in mine)} | {len(ran)} | {len(close)} |")
    counts: dict[str, list[str]] = {}
    for r in rows:
        for variant, v in variants(r):
            if v.get("rbody") in ("refused", "bug", "stopped", "not read"):
                counts.setdefault(reason_of(v.get("why", "")), []).append(f"{r['file']} ({variant})")
    lines += ["", "## Refusals by reason", "",
              "Each refusal's message with its names and numbers taken out; a model counts once per variant it was "
              "tried in.", "", "| reason | refusals | models |", "|---|---|---|"]
    for reason, items in sorted(counts.items(), key=lambda kv: (-len(kv[1]), kv[0])):
        models = sorted({i.rsplit(" (", 1)[0] for i in items})
        lines.append(f"| {reason.replace('|', '/')} | {len(items)} | {', '.join(models)} |")
    for name, _, _ in collections:
        lines += ["", f"## {name}", "",
                  "The sizes, run and difference are those of the first variant that loads (as is, else contacts off, "
                  "else contacts off + summed), named in the run's cell.", "",
                  "| file | as is | contacts off | off + summed | MuJoCo | nq/nv/nu | contact pairs / constraint units | "
                  "integrator, timestep | start | rbody 0.2 s | max \\|dq\\| vs MuJoCo | why refused (first refusal) "
                  "| stand-ins |", "|---|---|---|---|---|---|---|---|---|---|---|---|---|"]
        for r in rows:
            if r["collection"] != name:
                continue
            a, n, m = r["as_is"], r.get("no_contact", {"rbody": "-"}), r.get("summed")
            label, loaded = best_variant(r)
            pairs = f"{loaded['contacts']} / {loaded['units']}" if loaded else "-"
            timing = f"{loaded['integrator']}, {loaded['timestep']:g}" if loaded else "-"
            reasons, said = [], set()
            for variant, v in variants(r):
                if v.get("rbody") not in ("loads", "-") and v.get("why") not in said:
                    said.add(v.get("why"))
                    reasons.append(f"{variant}: {v.get('why', '')}")
            stand = (f"{len(r['stand_ins'])}: " + ", ".join(r["stand_ins"][:3]) + (" ..." if len(r["stand_ins"]) > 3
                                                                                   else "")) if r.get("stand_ins") else "-"
            lines.append(f"| {r['file']} | {status(a)} | {status(n)} | {status(m) if m else '-'} | "
                         f"{a.get('mujoco', '-')[:120].replace('|', '/')} | "
                         f"{sizes_cell(loaded) if loaded else '-'} | {pairs} | {timing} | "
                         f"{loaded.get('start', '-') if loaded else '-'} | "
                         f"{(label + ': ' + run_cell(loaded)) if loaded else '-'} | {dq_cell(loaded) if loaded else '-'} | "
                         f"{'<br>'.join(x.replace('|', '/') for x in reasons) or '-'} | {stand} |")
    traces = [(r["file"], variant, v) for r in rows for variant, v in variants(r) if v.get("trace")]
    if traces:
        lines += ["", "## Exceptions that are not rbody's own (bugs)", ""]
        for file, variant, v in traces:
            lines += [f"- {file} ({variant}): {v.get('why') or v.get('rb_failed')}", "", "```", v["trace"].strip(),
                      "```", ""]
    return "\n".join(lines) + "\n"


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--collection", action="append", required=True, metavar="NAME=FOLDER[:GLOB]")
    parser.add_argument("--exclude", action="append", default=[], metavar="GLOB")
    parser.add_argument("--stand-ins", action="store_true")
    parser.add_argument("--time-limit", type=float, default=TIME_LIMIT)
    parser.add_argument("--qvel0", type=float, default=0.0,
                        help="initial velocity of every degree of freedom [rad/s | m/s] in both engines (default 0: at "
                             "rest; a model at an equilibrium then compares nothing)")
    parser.add_argument("--note", action="append", default=[], help="a line for the page's header")
    parser.add_argument("--out", type=Path, default=Path("docs/mjcf_survey.md"))
    parser.add_argument("--rows", type=Path, help="also write the rows as JSON here (to redraw the page with --redraw)")
    parser.add_argument("--redraw", type=Path, help="draw the page from rows written by --rows; run nothing")
    args = parser.parse_args(argv)
    collections = []
    for item in args.collection:
        name, _, rest = item.partition("=")
        folder, _, pattern = rest.partition(":")
        if not name or not Path(folder).is_dir():
            parser.error(f"--collection {item!r}: expected NAME=FOLDER[:GLOB] with an existing folder")
        collections.append((name, Path(folder).resolve(), pattern or "*.xml"))
    if not args.time_limit > 0:
        parser.error(f"--time-limit {args.time_limit!r}: expected seconds > 0")
    import mujoco

    from validation.machine import describe_machine

    print(f"[survey] machine: {describe_machine()}; mujoco {mujoco.__version__}, numpy {np.__version__}, "
          f"Python {sys.version.split()[0]}", file=sys.stderr, flush=True)
    from rbody.files import write_atomic

    # quoted as a shell reads it: a note's spaces and parentheses, a glob, pasted back into bash
    command = "python benchmarks/mjcf_survey.py " + shlex.join(sys.argv[1:] if argv is None else argv)
    if args.redraw:
        saved = json.loads(args.redraw.read_text())
        rows, command = saved["rows"], saved["command"]
    else:
        rows = survey(collections, args.exclude, args.stand_ins, args.time_limit, args.qvel0, sys.stderr)
        if args.rows:
            write_atomic(args.rows, json.dumps({"rows": rows, "command": command}, default=float))
    write_atomic(args.out, markdown(rows, collections, command, args.note, args.time_limit, args.qvel0))
    print(f"[survey] {args.out}", file=sys.stderr)
    return 0


if __name__ == "__main__":
    raise SystemExit(main())
