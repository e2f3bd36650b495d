"""MJCF values read as MuJoCo reads them: numbers by C's strtod and strtol, attribute types and counts per element.

Numbers (MuJoCo's StringToVector, src/user/user_util.cc, through mjXUtil::ReadAttrVec): tokens separated by C's
isspace (space, tab, newline, vertical tab, form feed, carriage return: not a non-breaking space); a double is
what strtod reads in the "C" locale and nothing after it:

    decimal   [+-]? (digits [. digits?] | . digits) ([eE] [+-]? digits)?      ASCII digits only: no '1_0', no
    hex       [+-]? 0[xX] (hexdigits [. hexdigits?] | . hexdigits) ([pP] [+-]? digits)?   Arabic-Indic digits
    special   [+-]? (inf | infinity | nan | nan(chars)), any case

a value beyond the type's range is an error ("number is too large": 1e400 for a double, 3.5e38 for a float);
an int is what strtol reads in base 10 ([+-]? digits: '0.9', '1e0' and '0x1' are refused), within 32 bits. An
empty attribute is no attribute. MuJoCo accepts inf and nan; rbody then refuses them where it reads a value
(its numbers must be finite), so it accepts no number MuJoCo refuses.

Attributes (MuJoCo's schema, src/xml/mjcf.schema, read for this table): for the elements rbody reads or ignores,
each numeric attribute's type and count (double[3]: exactly 3; double[1..3]: 1 to 3; double[]: any), each keyword
attribute's choices, so that a value MuJoCo refuses ('friction="1 2 3 4"', 'rgba="1e39 0 0 1"', 'mocap="yes"')
is refused here too even where rbody does not use it. check_values(element) checks every attribute of the element
found in the table (rbody.mjcf.parse calls it on every element it reads).
"""

from __future__ import annotations

import math
import re

import numpy as np

_SPACE = " \t\n\v\f\r"  # C's isspace in the "C" locale
_SPLIT = re.compile(f"[{re.escape(_SPACE)}]+")
# (each part matched one way only: no backtracking, whatever the length of a token)
_DOUBLE = re.compile(r"[+-]?(?:0[xX](?:[0-9a-fA-F]+(?:\.[0-9a-fA-F]*)?|\.[0-9a-fA-F]+)(?:[pP][+-]?[0-9]+)?"
                     r"|(?:[0-9]+(?:\.[0-9]*)?|\.[0-9]+)(?:[eE][+-]?[0-9]+)?"
                     r"|(?i:inf(?:inity)?|nan(?:\([0-9A-Za-z_]*\))?))")
_INT = re.compile(r"[+-]?[0-9]+")
_HEX = re.compile(r"[+-]?0[xX]")
FLOAT32_MAX = float(np.finfo(np.float32).max)
NUMERIC = ("double", "float", "int")  # the kinds of ATTRIBUTES' numeric entries
INT_RANGE = (-(2**31), 2**31 - 1)


class GrammarError(ValueError):
    """A value MuJoCo's reader refuses: the message says why, as MuJoCo would ("bad format", "too large", ...)."""


def tokens(text: str) -> list[str]:
    """The tokens of an attribute value, separated as C's isspace separates them."""
    stripped = text.strip(_SPACE)
    return _SPLIT.split(stripped) if stripped else []


def parse_double(token: str, float32: bool = False) -> float:
    """One token as strtod (strtof for float32) reads it: GrammarError for a bad format or a value too large."""
    if not _DOUBLE.fullmatch(token):
        raise GrammarError(f"{shorten(token)!r} is not a number as MuJoCo reads it (C's strtod: ASCII digits, an "
                           "optional sign, point and exponent, or hex 0x...p...)")
    body = token.lstrip("+-")
    negative = token.startswith("-")
    if body[:1] in "iInN":
        value = math.inf if body[0] in "iI" else math.nan
        return -value if negative else value
    try:
        value = float.fromhex(token) if _HEX.match(token) else float(token)
    except OverflowError:
        value = math.inf
    if float32 and abs(value) > FLOAT32_MAX:
        with np.errstate(over="ignore"):
            value = float(np.float32(value))  # strtof: beyond FLT_MAX after rounding is an overflow
    if math.isinf(value):
        raise GrammarError(f"{shorten(token)!r} is too large for a {'float' if float32 else 'double'} "
                           "(MuJoCo: number is too large)")
    return value


def parse_int(token: str) -> int:
    """One token as strtol reads it in base 10, within a C int: GrammarError otherwise."""
    if not _INT.fullmatch(token):
        raise GrammarError(f"{shorten(token)!r} is not a whole number as MuJoCo reads it (C's strtol in base 10: "
                           "ASCII digits and an optional sign, no point, exponent or 0x)")
    value = int(token)
    if not INT_RANGE[0] <= value <= INT_RANGE[1]:
        raise GrammarError(f"{shorten(token)!r} is too large for an int (MuJoCo: number is too large)")
    return value


def parse_values(text: str, kind: str = "double") -> list:
    """Every token of `text` as a double, float or int (kind), as MuJoCo reads an attribute of that type."""
    if kind == "int":
        return [parse_int(token) for token in tokens(text)]
    return [parse_double(token, float32=kind == "float") for token in tokens(text)]


def shorten(text: str, limit: int = 60) -> str:
    """`text` cut to `limit` characters with the length said, for messages (a 5 MB value is never echoed whole)."""
    return text if len(text) <= limit else f"{text[:limit]}... ({len(text)} characters)"


# ----- the attributes MuJoCo's schema gives the elements rbody reads or ignores ----------------------------------

def _spec(text: str):
    """'double[3]' -> ('double', 3, 3); 'double[1..3]' -> ('double', 1, 3); 'double[]' -> ('double', 0, inf);
    'int' -> ('int', 1, 1); 'enum:a|b' -> ('enum', ('a', 'b')); 'bool' -> ('enum', ('false', 'true'))."""
    if text == "bool":
        return ("enum", ("false", "true"))
    if text.startswith("enum:"):
        return ("enum", tuple(text[5:].split("|")))
    if text.startswith("flags:"):
        return ("flags", tuple(text[6:].split("|")))
    match = re.fullmatch(r"(double|float|int)(?:\[(\d*)(?:\.\.(\d+))?\])?", text)
    kind, low, high = match.groups()
    if "[" not in text:
        return (kind, 1, 1)
    if low == "":
        return (kind, 0, math.inf)
    return (kind, int(low), int(high) if high else int(low))


_ORIENTATION = {"quat": "double[4]", "axisangle": "double[4]", "xyaxes": "double[6]", "zaxis": "double[3]",
                "euler": "double[3]"}
_FTA = "enum:false|true|auto"
_GEOMTYPE = "enum:plane|hfield|sphere|capsule|ellipsoid|cylinder|box|mesh|sdf"
_CAMLIGHT = "enum:fixed|track|trackcom|targetbody|targetbodycom"
_ENABLE = "enum:disable|enable"

_TABLE_TEXT = {
    "compiler": {"autolimits": "bool", "boundmass": "double", "boundinertia": "double", "settotalmass": "double",
                 "balanceinertia": "bool", "strippath": "bool", "coordinate": "enum:local|global",
                 "angle": "enum:radian|degree", "fitaabb": "bool", "discardvisual": "bool", "usethread": "bool",
                 "fusestatic": "bool", "inertiafromgeom": _FTA, "inertiagrouprange": "int[2]", "saveinertial": "bool",
                 "alignfree": "bool", "conflict": "enum:warning|merge|error"},
    "lengthrange": {"mode": "enum:none|muscle|muscleuser|all", "useexisting": "bool", "uselimit": "bool",
                    "accel": "double", "maxforce": "double", "timeconst": "double", "timestep": "double",
                    "inttotal": "double", "interval": "double", "tolrange": "double"},
    "option": {"timestep": "double", "impratio": "double", "tolerance": "double", "ls_tolerance": "double",
               "noslip_tolerance": "double", "ccd_tolerance": "double", "sleep_tolerance": "double",
               "gravity": "double[3]", "wind": "double[3]", "magnetic": "double[3]", "density": "double",
               "viscosity": "double", "o_margin": "double", "o_solref": "double[1..2]", "o_solimp": "double[1..5]",
               "o_friction": "double[1..5]", "integrator": "enum:Euler|RK4|implicit|implicitfast",
               "cone": "enum:pyramidal|elliptic", "jacobian": "enum:dense|sparse|auto",
               "solver": "enum:PGS|CG|Newton", "iterations": "int", "ls_iterations": "int",
               "noslip_iterations": "int", "ccd_iterations": "int", "sdf_iterations": "int",
               "sdf_initpoints": "int", "actuatorgroupdisable": "int[]"},
    "flag": {name: _ENABLE for name in (
        "constraint", "equality", "frictionloss", "limit", "contact", "spring", "damper", "gravity", "clampctrl",
        "warmstart", "filterparent", "actuation", "refsafe", "sensor", "midphase", "eulerdamp", "autoreset",
        "nativeccd", "island", "multiccd", "override", "energy", "fwdinv", "invdiscrete", "sleep", "diagexact")},
    "statistic": {"meaninertia": "double", "meanmass": "double", "meansize": "double", "extent": "double",
                  "center": "double[3]"},
    "body": {"pos": "double[3]", **_ORIENTATION, "mocap": "bool", "gravcomp": "double",
             "sleep": "enum:auto|never|allowed|init", "simple": "enum:false|auto", "user": "double[]"},
    "inertial": {"pos": "double[3]", **_ORIENTATION, "mass": "double", "diaginertia": "double[3]",
                 "fullinertia": "double[6]"},
    "joint": {"type": "enum:free|ball|slide|hinge", "group": "int", "pos": "double[3]", "axis": "double[3]",
              "springdamper": "double[2]", "limited": _FTA, "actuatorfrclimited": _FTA,
              "solreflimit": "double[1..2]", "solimplimit": "double[1..5]", "solreffriction": "double[1..2]",
              "solimpfriction": "double[1..5]", "stiffness": "double[1..3]", "range": "double[2]",
              "actuatorfrcrange": "double[2]", "actuatorgravcomp": "bool", "margin": "double", "ref": "double",
              "springref": "double", "armature": "double", "damping": "double[1..3]", "frictionloss": "double",
              "user": "double[]"},
    "freejoint": {"group": "int", "align": _FTA},
    "geom": {"type": _GEOMTYPE, "contype": "int", "conaffinity": "int", "condim": "int", "group": "int",
             "priority": "int", "size": "double[1..3]", "friction": "double[1..3]", "mass": "double",
             "density": "double", "shellinertia": "bool", "solmix": "double", "solref": "double[1..2]",
             "solimp": "double[1..5]", "margin": "double", "gap": "double", "surfacevel": "double[1..6]",
             "adhesion": "double", "fromto": "double[6]", "pos": "double[3]", **_ORIENTATION, "fitscale": "double",
             "rgba": "float[4]", "fluidshape": "enum:none|ellipsoid", "fluidcoef": "double[1..5]",
             "user": "double[]"},
    "site": {"type": _GEOMTYPE, "group": "int", "pos": "double[3]", **_ORIENTATION, "size": "double[1..3]",
             "fromto": "double[6]", "rgba": "float[4]", "user": "double[]"},
    "camera": {"projection": "enum:perspective|orthographic", "fovy": "double", "ipd": "double",
               "resolution": "int[2]", "output": "flags:rgb|depth|distance|normal|segmentation",
               "pos": "double[3]", **_ORIENTATION, "mode": _CAMLIGHT, "focal": "float[2]", "focalpixel": "float[2]",
               "principal": "float[2]", "principalpixel": "float[2]", "sensorsize": "float[2]", "user": "double[]"},
    "light": {"directional": "bool", "type": "enum:spot|directional|point|image", "castshadow": "bool",
              "active": "bool", "pos": "double[3]", "dir": "double[3]", "bulbradius": "float", "intensity": "float",
              "range": "float", "attenuation": "float[3]", "cutoff": "float", "softness": "float",
              "exponent": "float", "ambient": "float[3]", "diffuse": "float[3]", "specular": "float[3]",
              "mode": _CAMLIGHT},
    "mesh": {"vertex": "float[]", "normal": "float[]", "texcoord": "float[]", "face": "int[]",
             "refpos": "double[3]", "refquat": "double[4]", "scale": "double[3]", "smoothnormal": "bool",
             "maxhullvert": "int", "inertia": "enum:convex|legacy|exact|shell", "params": "double[]",
             "builtin": "enum:none|sphere|hemisphere|cone|supertorus|supersphere|wedge|plate"},
    "key": {"time": "double", "qpos": "double[]", "qvel": "double[]", "act": "double[]", "mpos": "double[]",
            "mquat": "double[]", "ctrl": "double[]"},
    "pair": {"condim": "int", "friction": "double[1..5]", "solref": "double[1..2]", "solreffriction": "double[1..2]",
             "solimp": "double[1..5]", "gap": "double", "margin": "double", "adhesion": "double"},
}
ATTRIBUTES: dict[str, dict[str, tuple]] = {tag: {name: _spec(spec) for name, spec in attrs.items()}
                                           for tag, attrs in _TABLE_TEXT.items()}
# Children an element holds at most once in MuJoCo's schema ("child x ?"); a <default>'s children are all so.
UNIQUE_CHILDREN = {"option": ("flag",), "compiler": ("lengthrange",), "body": ("inertial",)}
# Elements with no child elements in MuJoCo's schema (a child is "Schema violation: unrecognized element");
# a geom's <plugin> child is refused by rbody anyway (plugins are not supported).
CHILDLESS = ("joint", "freejoint", "inertial", "site", "camera", "light", "flag", "key", "exclude", "pair")


def check_value(tag: str, name: str, text: str) -> str | None:
    """Why attribute `name`="`text`" of <`tag`> is refused by MuJoCo's reader (str), or None (also when the table
    does not know the attribute: the caller's list of known attributes decides that)."""
    spec = ATTRIBUTES.get(tag, {}).get(name)
    if spec is None:
        return None
    kind = spec[0]
    if kind == "enum":
        return None if text in spec[1] else f"{name}={shorten(text)!r}: expected one of {', '.join(spec[1])}"
    if kind == "flags":
        words = tokens(text)
        bad = [w for w in words if w not in spec[1]]
        return None if words and not bad else f"{name}={shorten(text)!r}: expected keywords among {', '.join(spec[1])}"
    low, high = spec[1], spec[2]
    try:
        values = parse_values(text, kind)
    except GrammarError as error:
        return f"{name}={shorten(text)!r}: {error}"
    if not values:
        return None  # MuJoCo: an empty attribute is no attribute
    if len(values) > high:
        return f"{name}={shorten(text)!r}: at most {high} {'number' if high == 1 else 'numbers'}, got {len(values)}"
    if len(values) < low:
        return f"{name}={shorten(text)!r}: {low} numbers expected, got {len(values)}"
    return None


__all__ = ["GrammarError", "parse_double", "parse_int", "parse_values", "tokens", "shorten", "check_value",
           "ATTRIBUTES", "CHILDLESS", "UNIQUE_CHILDREN", "NUMERIC"]
