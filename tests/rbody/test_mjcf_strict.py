"""Issue 23: MJCF read as strictly as MuJoCo reads it. Each case is checked against MuJoCo itself (loaded from the
same text), so that the test says what MuJoCo does, not what we think it does."""

from __future__ import annotations

import sys

import numpy as np
import pytest

from rbody import from_mjcf
from rbody.mjcf import MJCFError

mujoco = pytest.importorskip("mujoco")

BODY = ('<mujoco>{pre}<worldbody><body name="b" {body}><joint name="j" axis="0 1 0" {joint}>{joint_children}</joint>'
        '<geom size="0.1" mass="{mass}" contype="{contype}" conaffinity="{conaffinity}" {geom}>{geom_children}</geom>'
        '{more}</body></worldbody></mujoco>')


def model(pre="", body="", joint="", joint_children="", geom="", geom_children="", more="", mass="1", contype="0",
          conaffinity="0") -> str:
    return BODY.format(pre=pre, body=body, joint=joint, joint_children=joint_children, geom=geom,
                       geom_children=geom_children, more=more, mass=mass, contype=contype, conaffinity=conaffinity)


def mujoco_refuses(xml: str | None = None, path=None) -> bool:
    try:
        mujoco.MjModel.from_xml_path(str(path)) if path else mujoco.MjModel.from_xml_string(xml)
    except Exception:  # noqa: BLE001
        return True
    return False


REFUSED = {
    "mass 1_0 (Python's float reads 10)": model(mass="1_0"),
    "an Arabic-Indic digit": model(mass="\u0661"),
    "a fullwidth digit": model(mass="\uff11"),
    "a non-breaking space between numbers": model(geom='pos="0\u00a00 0"'),
    "a number too large for a double": model(geom='pos="1e400 0 0"'),
    "a number too large for a float (rgba)": model(geom='rgba="3.5e38 0 0 1"'),
    "a fractional contype (read as 0 before: contacts off)": model(contype="0.9"),
    "an exponent in an int": model(conaffinity="1e0"),
    "hex in an int": model(geom='group="0x1"'),
    "an int beyond 32 bits": model(geom='priority="2147483648"'),
    "a condim MuJoCo does not have": model(geom='condim="2"'),
    "a fractional inertiagrouprange": model(pre='<compiler inertiagrouprange="0 4.5"/>'),
    "four frictions": model(geom='friction="1 0.1 0.01 0.5"'),
    "an unknown child of a joint": model(joint_children="<foo/>"),
    "a geom inside a joint": model(joint_children='<geom size="1"/>'),
    "an unknown child of a geom": model(geom_children="<bar/>"),
    "an unknown child of an inertial": model(
        mass="0", more='<inertial pos="0 0 0" mass="1" diaginertia="1 1 1"><x/></inertial>'),
    "two joints in one default class (the last won before)": model(
        pre='<default><joint damping="1"/><joint damping="2"/></default>'),
    "a mocap body with a joint": model(body='mocap="true"'),
    "mocap='yes'": model(body='mocap="yes"'),
    "a site with a bad size": model(more='<site size="a"/>'),
    "a camera with two orientations": model(more='<camera quat="1 0 0 0" euler="0 0 1"/>'),
    "two flags in one option": model(pre='<option><flag contact="disable"/><flag energy="enable"/></option>'),
}


@pytest.mark.parametrize("case", list(REFUSED))
def test_what_mujoco_refuses_is_refused(case):
    xml = REFUSED[case]
    assert mujoco_refuses(xml), "the case must be one MuJoCo refuses"
    with pytest.raises(MJCFError):
        from_mjcf(xml)


ACCEPTED = {
    "hex": (model(mass="0x1.8p1"), 3.0),
    "a leading plus and a bare point": (model(mass="+.5"), 0.5),
    "an exponent with a capital E": (model(mass="2E0"), 2.0),
    "a blank mass: no attribute (the density decides)": (model(mass=" "), 1000 * 4 / 3 * np.pi * 0.1**3),
}


@pytest.mark.parametrize("case", list(ACCEPTED))
def test_what_mujoco_reads_is_read_as_it_reads_it(case):
    xml, mass = ACCEPTED[case]
    compiled = mujoco.MjModel.from_xml_string(xml)
    assert float(compiled.body_mass[1]) == pytest.approx(mass, rel=1e-12)
    assert from_mjcf(xml).tree.bodies[0].inertia.mass == pytest.approx(mass, rel=1e-12)


def test_the_number_grammar_is_strtods():
    from rbody.mjcf.grammar import parse_double, parse_values

    assert parse_values("1 -2.5e-3\t0x10 0X1P-1 .5 5. 1e-320", "double") == [1.0, -0.0025, 16.0, 0.5, 0.5, 5.0, 1e-320]
    assert parse_values("08 -3 +4", "int") == [8, -3, 4]
    assert parse_double("nan") != parse_double("nan") and parse_double("-INF") == -np.inf  # MuJoCo reads them
    for bad in ("1_0", "1,5", "0x", "1e", ".e1", "--1", "1.0.0", "1f", "infinit", "\u0663"):
        with pytest.raises(ValueError):
            parse_values(bad)
    assert parse_double("3.4028235e38", float32=True) == pytest.approx(3.4028234663852886e38)


def test_non_finite_numbers_mujoco_accepts_are_refused_by_rbody():
    """MuJoCo reads inf and nan (with a warning); rbody's numbers must be finite: stricter, never looser."""
    with pytest.raises(MJCFError, match="finite"):
        from_mjcf(model(mass="inf"))


def test_a_file_included_twice_is_refused(tmp_path):
    (tmp_path / "part.xml").write_text('<mujoco><option timestep="0.01"/></mujoco>')
    main = tmp_path / "main.xml"
    main.write_text(model(pre='<include file="part.xml"/><include file="part.xml"/>'))
    assert mujoco_refuses(path=main)
    with pytest.raises(MJCFError, match="already included"):
        from_mjcf(main)
    main.write_text(model(pre='<include file="part.xml"/>'))
    assert from_mjcf(main).timestep == 0.01


def chain(bodies: int) -> str:
    geom = '<geom size="0.01" contype="0" conaffinity="0"/>'
    return ("<mujoco><worldbody>" + f'<body pos="0 0 -0.01"><joint axis="0 1 0"/>{geom}' * bodies
            + "</body>" * bodies + "</worldbody></mujoco>")


def deep_call(depth: int, function):
    """function() called `depth` Python frames down (as from deep inside a user's program)."""
    return function() if depth == 0 else deep_call(depth - 1, function)


def test_495_nested_bodies_load_also_from_deep_in_a_stack_and_mujocos_limit_is_kept():
    """Before: RecursionError on 495 nested bodies (MuJoCo loads them), or on fewer from deep in a stack."""
    assert not mujoco_refuses(chain(495))
    depth = sys.getrecursionlimit() - 150
    scene = deep_call(depth, lambda: from_mjcf(chain(495)))
    assert scene.multibody.nv == 495
    assert mujoco_refuses(chain(497))  # tinyxml2's depth limit: rbody stops where MuJoCo stops
    with pytest.raises(MJCFError, match="levels MuJoCo's XML parser reads"):
        from_mjcf(chain(497))


def test_bytes_are_decoded_as_mujoco_decodes_them(tmp_path):
    """MuJoCo hands the bytes to its parser as they are: a Latin-1 comment or name loads, a Latin-1 byte in a
    number is a bad number. Before: UnicodeDecodeError naming no file."""
    cases = {
        "comment": (b'<mujoco><!-- caf\xe9 --><worldbody><body><joint/><geom size="0.1" contype="0" conaffinity="0"/>'
                    b"</body></worldbody></mujoco>", False),
        "name": (b'<mujoco><worldbody><body name="caf\xe9"><joint/><geom size="0.1" contype="0" conaffinity="0"/>'
                 b"</body></worldbody></mujoco>", False),
        "declared": (b'<?xml version="1.0" encoding="ISO-8859-1"?><mujoco><worldbody><body name="\xe9"><joint/>'
                     b'<geom size="0.1" contype="0" conaffinity="0"/></body></worldbody></mujoco>', False),
        "number": (b'<mujoco><worldbody><body><joint/><geom size="0.1" mass="1\xe9" contype="0" conaffinity="0"/>'
                   b"</body></worldbody></mujoco>", True),
        "nul": (b'<mujoco><!-- \x00 --><worldbody/></mujoco>', True),
    }
    for name, (data, refused) in cases.items():
        path = tmp_path / f"{name}.xml"
        path.write_bytes(data)
        assert mujoco_refuses(path=path) == refused, name
        if refused:
            with pytest.raises(MJCFError, match=str(path)):
                from_mjcf(path)
        else:
            assert from_mjcf(path).multibody.nv == 1, name


def test_a_huge_attribute_is_not_echoed_whole():
    with pytest.raises(MJCFError) as error:
        from_mjcf(model(mass="1" * 5_000_000 + "x"))
    assert len(str(error.value)) < 1000 and "5000001 characters" in str(error.value)
