"""Issue 23: an MJCF mutation fuzzer. Mutants of small models of our own (a fixed seed) are loaded by MuJoCo
(mujoco.MjModel.from_xml_path) and by rbody.from_mjcf: rbody must accept no file MuJoCo refuses, raise nothing but
its own error classes (ValueError and its subclasses such as MJCFError, NotImplementedError), and, where both
accept, read the same model (degrees of freedom and total mass).

    python tests/rbody/test_mjcf_fuzz.py [COUNT] [SEED]    # prints the counts of a sweep

The default test runs FAST_MUTANTS mutants (well under 30 s); the slow one SLOW_MUTANTS.
"""

from __future__ import annotations

import copy
import random
import sys
import tempfile
import xml.etree.ElementTree as ET
from collections import Counter
from pathlib import Path

import pytest

mujoco = pytest.importorskip("mujoco") if __name__ != "__main__" else __import__("mujoco")

OWN_ERRORS: tuple = ()
FAST_MUTANTS = 300
SLOW_MUTANTS = 3000

# ----- the models mutated (our own) ----------------------------------------------------------------------------

MODELS = {
    "double pendulum": """<mujoco model="arm">
  <compiler angle="radian" inertiafromgeom="auto"/>
  <option timestep="0.002" integrator="RK4" gravity="0 0 -9.81">
    <flag contact="enable"/>
  </option>
  <default>
    <joint damping="0.01" armature="0.001"/>
    <geom contype="0" conaffinity="0" density="800" rgba="0.8 0.2 0.2 1"/>
    <default class="thin">
      <geom size="0.02"/>
    </default>
  </default>
  <worldbody>
    <light pos="0 0 3" dir="0 0 -1"/>
    <camera name="side" pos="0 -3 0" xyaxes="1 0 0 0 0 1"/>
    <body name="upper" pos="0 0 1">
      <joint name="shoulder" type="hinge" axis="0 1 0" range="-3 3" limited="false"/>
      <geom name="upper_rod" class="thin" type="capsule" fromto="0 0 0 0 0 -0.5"/>
      <site name="elbow_site" pos="0 0 -0.5" size="0.01"/>
      <body name="lower" pos="0 0 -0.5">
        <joint name="elbow" type="hinge" axis="0 1 0" stiffness="2" springref="0.1"/>
        <geom name="lower_rod" type="cylinder" size="0.03 0.2" pos="0 0 -0.2" mass="0.7"/>
      </body>
    </body>
  </worldbody>
  <keyframe>
    <key name="bent" qpos="0.3 -0.2" qvel="0 0.1"/>
  </keyframe>
</mujoco>
""",
    "free and ball": """<mujoco model="flyer">
  <option timestep="0.001">
    <flag contact="disable"/>
  </option>
  <worldbody>
    <body name="hull" pos="0 0 2" euler="0.1 0.2 0.3">
      <freejoint name="float"/>
      <inertial pos="0 0 0.05" mass="2.5" diaginertia="0.1 0.12 0.15"/>
      <geom type="box" size="0.2 0.1 0.05" contype="1" conaffinity="1"/>
      <body name="pod" pos="0.3 0 0" quat="1 0 0 0">
        <joint name="socket" type="ball" damping="0.02"/>
        <inertial pos="0.05 0 0" mass="0.4" fullinertia="0.002 0.003 0.004 0.0001 0 0"/>
        <geom type="sphere" size="0.05" group="3"/>
      </body>
    </body>
  </worldbody>
</mujoco>
""",
    "slide and hinge": """<mujoco model="cart">
  <compiler angle="degree" autolimits="true" inertiagrouprange="0 4"/>
  <option timestep="0.005"/>
  <default>
    <geom contype="0" conaffinity="0"/>
    <default class="heavy">
      <geom density="7800"/>
      <joint armature="0.01"/>
    </default>
  </default>
  <worldbody>
    <geom name="floor" type="plane" size="2 2 0.1"/>
    <body name="cart" pos="0 0 0.2" childclass="heavy">
      <joint name="rail" type="slide" axis="1 0 0" range="-1 1" damping="0.5"/>
      <geom type="box" size="0.1 0.05 0.05"/>
      <body name="pole" pos="0 0 0.05" axisangle="0 0 1 30">
        <joint name="hinge" axis="0 1 0" ref="10" springref="5"/>
        <geom type="capsule" size="0.01" fromto="0 0 0 0 0 0.6"/>
        <geom type="ellipsoid" size="0.03 0.04 0.05" pos="0 0 0.7"/>
      </body>
    </body>
  </worldbody>
</mujoco>
""",
}

# ----- the mutations -------------------------------------------------------------------------------------------

NUMBERS = ["1_0", "\u0661", "\uff11", "0x1p1", "0X1.8P1", "1e400", "-1e400", "1e-400", "nan", "inf", "-inf",
           "infinity", "", " ", "1,0", "0.9", "1.5", "-1", "0", "-0", "+.5", ".e1", "1e", "0x", "1f", "1d", "--1",
           "\u00a01", "1e-320", "3.5e38", "2147483648", "08", "1 2", "00.5", "1e5", "0.", "x", "1.0.0", "\t2"]
KEYWORDS = ["Hinge", "hinge2", "", "true ", "TRUE", "1", "auto", "false", "slide", "ball", "free", "Euler", "rk4",
            "degree", "radian", "capsule", "sdf", "hfield", "enable", "disable", "none"]
EXTRA_ATTRIBUTES = [("foo", "1"), ("mass", "1"), ("damping", "0.1"), ("mocap", "true"), ("mocap", "yes"),
                    ("contype", "1"), ("conaffinity", "1"), ("condim", "2"), ("condim", "4"), ("group", "9"),
                    ("priority", "1.5"), ("gravcomp", "1"), ("density", "-5"), ("euler", "0 0 1"), ("quat", "0 0 0 0"),
                    ("frictionloss", "0.1"), ("springdamper", "1 1"), ("stiffness", "1 2"), ("margin", "0.01"),
                    ("user", "1 2 x"), ("rgba", "1e39 0 0 1"), ("size", "0.1 0.2 0.3 0.4"), ("fluidshape", "ellipsoid"),
                    ("limited", "true"), ("range", "1 -1"), ("axis", "0 0 0"), ("sleep", "never"), ("align", "true")]
CHILDREN = ["foo", "geom", "joint", "inertial", "site", "plugin", "body", "camera", "frame", "include"]
TAGS = {"joint": ["Joint", "joints", "site"], "geom": ["Geom", "site", "body"], "body": ["Body", "bodies", "frame"],
        "inertial": ["Inertial", "geom"], "site": ["Site", "geom"], "default": ["defaults"], "option": ["options"]}


def _numeric(value: str) -> bool:
    try:
        return bool(value.split()) and all(float(token) == float(token) for token in value.split())
    except ValueError:
        return False


def _elements(root: ET.Element) -> list[tuple[ET.Element, ET.Element | None]]:
    out, stack = [], [(root, None)]
    while stack:
        element, parent = stack.pop()
        out.append((element, parent))
        stack.extend((child, element) for child in element)
    return out


def mutate(text: str, rng: random.Random) -> tuple[bytes, str]:
    """One mutant of `text` (bytes to write) and a short description of what was changed."""
    root = ET.fromstring(text)
    done = []
    for _ in range(rng.choice((1, 1, 2))):
        nodes = _elements(root)
        element, parent = rng.choice(nodes)
        numeric = [k for k, v in element.attrib.items() if _numeric(v)]
        keywords = [k for k, v in element.attrib.items() if not _numeric(v) and k not in ("name", "class")]
        kind = rng.choice(["number", "number", "number", "count", "keyword", "drop", "add", "add", "delete",
                           "duplicate", "child", "mocap", "tag", "bytes", "bytes"] + ["deep"] * (rng.random() < 0.03))
        if kind == "number" and numeric:
            key = rng.choice(numeric)
            tokens = element.attrib[key].split()
            tokens[rng.randrange(len(tokens))] = rng.choice(NUMBERS)
            element.attrib[key] = " ".join(tokens)
            done.append(f"<{element.tag} {key}={element.attrib[key]!r}>")
        elif kind == "count" and numeric:
            key = rng.choice(numeric)
            tokens = element.attrib[key].split()
            tokens = tokens[:-1] if rng.random() < 0.5 else tokens + ["0.5"]
            element.attrib[key] = " ".join(tokens)
            done.append(f"<{element.tag} {key}={element.attrib[key]!r}>")
        elif kind == "keyword" and keywords:
            key = rng.choice(keywords)
            element.attrib[key] = rng.choice(KEYWORDS)
            done.append(f"<{element.tag} {key}={element.attrib[key]!r}>")
        elif kind == "drop" and element.attrib:
            key = rng.choice(sorted(element.attrib))
            del element.attrib[key]
            done.append(f"<{element.tag}> without {key}")
        elif kind == "add":
            key, value = rng.choice(EXTRA_ATTRIBUTES)
            element.attrib[key] = value
            done.append(f"<{element.tag} {key}={value!r}>")
        elif kind == "delete" and parent is not None:
            parent.remove(element)
            done.append(f"<{element.tag}> deleted")
        elif kind == "duplicate" and parent is not None:
            parent.insert(list(parent).index(element), copy.deepcopy(element))
            done.append(f"<{element.tag}> twice")
        elif kind == "child":
            tag = rng.choice(CHILDREN)
            child = ET.SubElement(element, tag)
            if tag == "geom":
                child.attrib.update(size="0.05", contype="0", conaffinity="0")
            elif tag == "inertial":
                child.attrib.update(pos="0 0 0", mass="1", diaginertia="0.1 0.1 0.1")
            elif tag == "include":
                child.attrib["file"] = "missing.xml"
            done.append(f"<{tag}> in <{element.tag}>")
        elif kind == "mocap":
            bodies = [e for e, _ in nodes if e.tag == "body"]
            if bodies:
                rng.choice(bodies).attrib["mocap"] = "true"
                done.append("a mocap body")
        elif kind == "deep":  # a chain of bodies around one body, near MuJoCo's nesting limit (496 bodies)
            bodies = [(e, p) for e, p in nodes if e.tag == "body" and p is not None]
            if bodies:
                body, holder = rng.choice(bodies)
                depth = rng.randrange(470, 500)
                outer = inner = ET.Element("body", {"pos": "0 0 -0.01"})
                for _ in range(depth - 1):
                    ET.SubElement(inner, "joint", {"axis": "0 1 0"})
                    ET.SubElement(inner, "geom", {"size": "0.005", "contype": "0", "conaffinity": "0"})
                    inner = ET.SubElement(inner, "body", {"pos": "0 0 -0.01"})
                holder.insert(list(holder).index(body), outer)
                holder.remove(body)
                inner.append(body)
                done.append(f"a body {depth} bodies deep")
        elif kind == "tag" and element.tag in TAGS:
            old = element.tag
            element.tag = rng.choice(TAGS[old])
            done.append(f"<{old}> as <{element.tag}>")
    data = ET.tostring(root, encoding="unicode").encode("utf-8")
    if any("bytes" in d for d in done) or rng.random() < 0.15:
        data, what = _byte_mutation(data, rng)
        done.append(what)
    return data, "; ".join(done) or "unchanged"


def _byte_mutation(data: bytes, rng: random.Random) -> tuple[bytes, str]:
    byte = rng.choice([b"\xe9", b"\xff", b"\xc3", b"\x01", b"\x0b", b"\x00", b"\xa0"])
    where = rng.choice(["comment", "name", "number", "anywhere"])
    if where == "comment":
        at = data.index(b">") + 1
        return data[:at] + b"<!-- caf" + byte + b" -->" + data[at:], f"byte {byte!r} in a comment"
    if where == "name" and b'name="' in data:
        at = data.index(b'name="') + 6
        return data[:at] + byte + data[at:], f"byte {byte!r} in a name"
    quote = [i for i in range(len(data)) if data[i:i + 2] == b'="' and data[i + 2:i + 3].isdigit()]
    if where == "number" and quote:
        at = rng.choice(quote) + 3
        return data[:at] + byte + data[at:], f"byte {byte!r} in a number"
    at = rng.randrange(len(data))
    return data[:at] + byte + data[at:], f"byte {byte!r} at {at}"


# ----- the sweep -------------------------------------------------------------------------------------------------

def _own_errors() -> tuple:
    """rbody's own error classes: MJCFError (a ValueError) and rbody.errors' (plain ValueError and
    NotImplementedError are accepted by their exact type: a UnicodeDecodeError is a ValueError, not rbody's)."""
    import rbody.errors
    from rbody.mjcf import MJCFError

    return (MJCFError,) + tuple(v for v in vars(rbody.errors).values() if isinstance(v, type) and
                                issubclass(v, Exception) and v.__module__ == "rbody.errors")


def mujoco_reads(path: Path):
    """MuJoCo's model of the file, or None when it refuses it."""
    try:
        return mujoco.MjModel.from_xml_path(str(path))
    except Exception:  # noqa: BLE001 - MuJoCo's refusal of any kind
        return None


def sweep(count: int, seed: int = 23) -> tuple[Counter, list[str]]:
    """Counts of (MuJoCo, rbody) outcomes over `count` mutants, and the problems: a mutant rbody accepts and
    MuJoCo refuses, an error of a class other than rbody's, or a model read differently (nv, total mass)."""
    from rbody import from_mjcf

    global OWN_ERRORS
    OWN_ERRORS = _own_errors()
    rng = random.Random(seed)
    counts: Counter = Counter()
    problems: list[str] = []
    names = sorted(MODELS)
    with tempfile.TemporaryDirectory() as folder:
        for k in range(count):
            name = names[k % len(names)]
            data, what = mutate(MODELS[name], rng)
            path = Path(folder) / f"mutant{k}.xml"
            path.write_bytes(data)
            model = mujoco_reads(path)
            try:
                scene = from_mjcf(path)
                rbody = "accepts"
            except Exception as error:  # noqa: BLE001 - what the test looks for
                scene = None
                if type(error) in (ValueError, NotImplementedError) or isinstance(error, OWN_ERRORS):
                    rbody = "refuses"
                else:  # RecursionError, UnicodeDecodeError (a ValueError, not rbody's), TypeError, ...
                    rbody = "crashes"
                    problems.append(f"mutant {k} of {name} ({what}): {type(error).__name__}: {str(error)[:200]}")
            counts[("mujoco accepts" if model is not None else "mujoco refuses", rbody)] += 1
            if model is None and rbody == "accepts":
                problems.append(f"mutant {k} of {name} ({what}): MuJoCo refuses it, rbody accepts it")
            if model is not None and scene is not None:
                nv, mass = scene.multibody.nv, sum(b.inertia.mass for b in scene.tree.bodies)
                if nv != model.nv or abs(mass - float(model.body_mass.sum())) > 1e-9 * max(1.0, mass):
                    problems.append(f"mutant {k} of {name} ({what}): read differently: rbody nv={nv}, mass={mass!r}; "
                                    f"MuJoCo nv={model.nv}, mass={float(model.body_mass.sum())!r}")
    return counts, problems


def _report(counts: Counter, problems: list[str]) -> str:
    lines = [f"{m}, rbody {r}: {n}" for (m, r), n in sorted(counts.items())]
    return "\n".join(lines + [f"{len(problems)} problems"] + problems[:40])


def test_rbody_accepts_no_mutant_mujoco_refuses_and_raises_only_its_own_errors():
    counts, problems = sweep(FAST_MUTANTS)
    assert sum(counts.values()) == FAST_MUTANTS
    assert counts[("mujoco accepts", "accepts")] > 0 and counts[("mujoco refuses", "refuses")] > 0  # both kinds met
    assert not problems, _report(counts, problems)


@pytest.mark.slow
def test_a_bigger_sweep():
    counts, problems = sweep(SLOW_MUTANTS, seed=2023)
    assert not problems, _report(counts, problems)


if __name__ == "__main__":
    found = sweep(int(sys.argv[1]) if len(sys.argv) > 1 else FAST_MUTANTS, int(sys.argv[2]) if len(sys.argv) > 2 else 23)
    print(_report(*found))
