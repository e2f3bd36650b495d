"""MJCF actuators and tendons -> rbody.layout.Actuator and Tendon, as MuJoCo's XML reader and compiler form them.

Actuators. MuJoCo keeps one actuator default per <default> class, whatever the element that set it: every
actuator element of a class (<general>, <motor>, <position>, ...) writes into the same default, in document
order, and an actuator starts from its class's default, then applies its own element (xml_native_reader.cc
OneActuator, user_api.cc mjs_setTo*). Shortcuts, as general actuators:
- motor:       gain fixed 1; bias none; dynamics none
- position:    gain fixed kp; bias affine (0, -kp, -kv); timeconst > 0: dynamics filterexact, dynprm timeconst;
               dampratio: kv = dampratio 2 sqrt(kp m), m = 1 / (moment M^-1 moment^T) the mass reflected through
               the transmission at the model's reference pose (mujoco 4.0's compiler, measured)
- velocity:    gain fixed kv; bias affine (0, 0, -kv)
- intvelocity: as position, dynamics integrator (act = the integrated velocity command)
- damper:      gain affine (0, 0, -kv); bias none; ctrllimited
- general:     gaintype, biastype, dyntype, gainprm, biasprm, dynprm as given
ctrllimited, forcelimited, actlimited "auto": limited where the range is given (compiler autolimits, MJCF's
default; without autolimits a range with "auto" is MuJoCo's error). inheritrange r > 0 (position, intvelocity):
the control (intvelocity: activation) range is the target joint's or tendon's range scaled by r about its middle.
Transmission through joint (hinge, slide, ball, free), jointinparent (hinge, slide), tendon.
Refused, naming the file, line and reason: site, body and slider-crank transmissions, muscle, cylinder,
adhesion, pid, dcmotor and orientation actuators, plugins, user (callback) dynamics, gains and biases, actuator
damping and armature, delays.

Tendons: <fixed> (joints with coef) and <spatial> through <site>s only; a <geom> wrap or a <pulley> is refused,
and so is a tendon's armature. Its limits (range, when limited="true", or "auto" with compiler autolimits and a
range; at range less margin, as joints') and its frictionloss are rows of the constraint layer, held rigidly
(rbody.engine.constraints); <flag limit="disable"/> and <flag frictionloss="disable"/> drop them (noted), and
solreflimit, solimplimit, solreffriction, solimpfriction are noted as ignored. Restitution of a tendon's limit:
<custom><numeric name="rbody.restitution.TENDON" data="e"/> (rbody.mjcf.constraints), else the model's.
springlength: one value a is (a, a); absent ("-1 -1") the length at the reference pose (rbody.layout.Tendon).
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field, replace

import numpy as np

from rbody.layout import Actuator, Tendon
from rbody.mjcf.document import Element, boolean, choice, number, numbers

SUPPORTED = ("general", "motor", "position", "velocity", "intvelocity", "damper")
REFUSED = {
    "muscle": "muscle actuators (their force-length-velocity curves and activation dynamics) are not modelled",
    "cylinder": "cylinder actuators are not modelled (write it as <general> with its gain and filter)",
    "adhesion": "adhesion actuators act through contacts, which rbody does not model here",
    "pid": "pid actuators (their integral and slew states) are not modelled",
    "dcmotor": "dcmotor actuators (electrical, thermal and friction states) are not modelled",
    "orientation": "orientation actuators (geodesic servos on a rotation) are not modelled",
    "plugin": "actuator plugins are not modelled (their physics is unknown to rbody)",
}
TRANSMISSION_KEYS = ("joint", "jointinparent", "tendon", "site", "body", "cranksite")
COMMON = {"name", "class", "group", "ctrllimited", "forcelimited", "actlimited", "ctrlrange", "forcerange",
          "actrange", "lengthrange", "gear", "cranklength", "joint", "jointinparent", "tendon", "cranksite",
          "slidersite", "site", "refsite", "body", "user", "actearly", "nsample", "interp", "delay", "damping",
          "armature", "actdim"}
EXTRA = {"general": {"dyntype", "gaintype", "biastype", "dynprm", "gainprm", "biasprm", "input"},
         "motor": set(), "position": {"kp", "kv", "dampratio", "timeconst", "inheritrange"},
         "velocity": {"kv"}, "intvelocity": {"kp", "kv", "dampratio", "inheritrange"}, "damper": {"kv"}}
DYNTYPES = ("none", "integrator", "filter", "filterexact", "muscle", "user", "pid", "dcmotor")
GAINTYPES = ("fixed", "affine", "muscle", "user", "pid", "dcmotor", "so3")
BIASTYPES = ("none", "affine", "muscle", "user", "dcmotor", "so3")
LIMITED = ("false", "true", "auto")
TENDON_ATTRS = {"name", "class", "group", "limited", "actuatorfrclimited", "range", "actuatorfrcrange", "solreflimit",
                "solimplimit", "solreffriction", "solimpfriction", "frictionloss", "springlength", "width",
                "material", "margin", "stiffness", "damping", "armature", "rgba", "user"}
MJ_MINVAL = 1e-15


@dataclass
class ActuatorSpec:
    """MuJoCo's mjsActuator, the fields rbody reads (its defaults are MuJoCo's)."""

    gaintype: str = "fixed"
    gainprm: list = field(default_factory=lambda: [1.0] + [0.0] * 9)
    biastype: str = "none"
    biasprm: list = field(default_factory=lambda: [0.0] * 10)
    dyntype: str = "none"
    dynprm: list = field(default_factory=lambda: [1.0] + [0.0] * 9)
    gear: list = field(default_factory=lambda: [1.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    ctrlrange: list = field(default_factory=lambda: [0.0, 0.0])
    forcerange: list = field(default_factory=lambda: [0.0, 0.0])
    actrange: list = field(default_factory=lambda: [0.0, 0.0])
    ctrllimited: str = "auto"
    forcelimited: str = "auto"
    actlimited: str = "auto"
    actearly: bool = False
    group: int = 0
    inheritrange: float = 0.0
    damping: list = field(default_factory=lambda: [0.0])
    armature: float = 0.0
    delay: float = 0.0
    actdim: int = -1
    trntype: str = ""
    target: str = ""
    kind: str = "general"       # the element that made it (for messages and notes)
    element: Element | None = None

    def copy(self) -> "ActuatorSpec":
        return replace(self, gainprm=list(self.gainprm), biasprm=list(self.biasprm), dynprm=list(self.dynprm),
                       gear=list(self.gear), ctrlrange=list(self.ctrlrange), forcerange=list(self.forcerange),
                       actrange=list(self.actrange), damping=list(self.damping))


def _read_into(element: Element, attrib: dict, key: str, target: list, most: int) -> bool:
    """The first values of `target` from attribute `key` (up to `most`, MuJoCo's partial read); False if absent."""
    if key not in attrib:
        return False
    values = numbers(element, key, attrib)
    if not 1 <= len(values) <= most:
        raise element.error(f"{key}={attrib[key]!r}: expected 1 to {most} numbers, got {len(values)}")
    target[:len(values)] = values.tolist()
    return True


def apply_actuator(spec: ActuatorSpec, element: Element, attrib: dict) -> None:
    """Apply one actuator element (or a default's) to `spec`, as MuJoCo's OneActuator does."""
    tag = element.tag
    if tag in REFUSED:
        raise element.error(REFUSED[tag])
    if tag not in SUPPORTED:
        raise element.error(f"unknown actuator <{tag}> (rbody reads {SUPPORTED})")
    known = COMMON | EXTRA[tag]
    unknown = sorted(set(attrib) - known)
    if unknown:
        raise element.error(f"unknown attribute {unknown[0]!r} (MJCF's <{tag}> has {sorted(known)})")
    spec.kind, spec.element = tag, element
    if "group" in attrib:
        spec.group = int(number(element, "group", attrib, 0))
    for key in ("ctrlrange", "forcerange", "actrange"):
        if key in attrib:
            getattr(spec, key)[:] = numbers(element, key, attrib, 2).tolist()
    for key in ("ctrllimited", "forcelimited", "actlimited"):
        if key in attrib:
            setattr(spec, key, choice(element, key, attrib, LIMITED, "auto"))
    _read_into(element, attrib, "gear", spec.gear, 6)
    _read_into(element, attrib, "damping", spec.damping, 4)
    if "armature" in attrib:
        spec.armature = number(element, "armature", attrib, 0.0)
    if "delay" in attrib:
        spec.delay = number(element, "delay", attrib, 0.0)
    if "actdim" in attrib:
        spec.actdim = int(number(element, "actdim", attrib, -1))
    if "actearly" in attrib:
        spec.actearly = boolean(element, "actearly", attrib, False)
    for key, name in (("dyntype", "dyntype"), ("gaintype", "gaintype"), ("biastype", "biastype")):
        if key in attrib:
            setattr(spec, name, choice(element, key, attrib, {"dyntype": DYNTYPES, "gaintype": GAINTYPES,
                                                              "biastype": BIASTYPES}[key], "none"))
    for key in ("dynprm", "gainprm", "biasprm"):
        _read_into(element, attrib, key, getattr(spec, key), 10)
    for key in TRANSMISSION_KEYS:
        if key in attrib:
            spec.trntype, spec.target = key, attrib[key]
    if "input" in attrib:
        raise element.error("input= (servo input subsets, SO3 charts) is not modelled")
    if tag == "motor":
        spec.gainprm[0] = 1.0
        spec.dyntype, spec.gaintype, spec.biastype = "none", "fixed", "none"
    elif tag in ("position", "intvelocity"):
        kp = number(element, "kp", attrib, spec.gainprm[0])
        kv = number(element, "kv", attrib, 0.0) if "kv" in attrib else None
        dampratio = number(element, "dampratio", attrib, 0.0) if "dampratio" in attrib else None
        timeconst = number(element, "timeconst", attrib, 0.0) if "timeconst" in attrib else None
        spec.inheritrange = number(element, "inheritrange", attrib, spec.inheritrange)
        spec.gainprm[0], spec.biasprm[1] = kp, -kp
        if kv is not None and dampratio is not None:
            raise element.error("kv and dampratio cannot both be defined")
        if kv is not None:
            if kv < 0:
                raise element.error("kv cannot be negative")
            spec.biasprm[2] = -kv
        if dampratio is not None:
            if dampratio < 0:
                raise element.error("dampratio cannot be negative")
            spec.biasprm[2] = dampratio  # > 0: a damping ratio, resolved against the reflected mass (compile)
        if timeconst is not None:
            if timeconst < 0:
                raise element.error("timeconst cannot be negative")
            spec.dynprm[0] = timeconst
            spec.dyntype = "none" if timeconst == 0 else "filterexact"
        if spec.inheritrange > 0 and (spec.ctrlrange[0] or spec.ctrlrange[1]) and tag == "position":
            raise element.error("ctrlrange and inheritrange cannot both be defined")
        spec.gaintype, spec.biastype = "fixed", "affine"
        if tag == "intvelocity":
            spec.dyntype = "integrator"
            if spec.inheritrange > 0 and (spec.actrange[0] or spec.actrange[1]):
                raise element.error("actrange and inheritrange cannot both be defined")
    elif tag == "velocity":
        kv = number(element, "kv", attrib, spec.gainprm[0])
        spec.biasprm = [0.0] * 10
        spec.gainprm[0], spec.biasprm[2] = kv, -kv
        spec.dyntype, spec.gaintype, spec.biastype = "none", "fixed", "affine"
    elif tag == "damper":
        kv = number(element, "kv", attrib, -spec.gainprm[2] if spec.gaintype == "affine" else 0.0)
        spec.gainprm = [0.0] * 10
        spec.gainprm[2] = -kv
        spec.ctrllimited = "true"
        spec.dyntype, spec.gaintype, spec.biastype = "none", "affine", "none"
        if kv < 0:
            raise element.error("damping coefficient cannot be negative")
        if spec.ctrlrange[0] < 0 or spec.ctrlrange[1] < 0:
            raise element.error("damper control range cannot be negative")


@dataclass
class TendonSpec:
    """One MJCF tendon as read: its element, attributes over its class's defaults, and its path."""

    element: Element
    attrib: dict
    kind: str
    joints: list = field(default_factory=list)   # (joint name, coef, element)
    sites: list = field(default_factory=list)    # (site name, element)


def read_tendon(element: Element, attrib: dict) -> TendonSpec:
    """The path of one <fixed> or <spatial> tendon (MuJoCo's OneTendon and its children)."""
    unknown = sorted(set(attrib) - TENDON_ATTRS)
    if unknown:
        raise element.error(f"unknown attribute {unknown[0]!r} (MJCF's <{element.tag}> has {sorted(TENDON_ATTRS)})")
    spec = TendonSpec(element, attrib, "fixed" if element.tag == "fixed" else "spatial")
    for child in element.children:
        if spec.kind == "fixed":
            if child.tag != "joint":
                raise child.error("a fixed tendon holds <joint> elements only")
            if set(child.attrib) - {"joint", "coef"} or "joint" not in child.attrib:
                raise child.error("a fixed tendon's <joint> takes joint= and coef=")
            spec.joints.append((child.attrib["joint"], number(child, "coef", child.attrib, 0.0), child))
        elif child.tag == "site":
            if set(child.attrib) != {"site"}:
                raise child.error("a spatial tendon's <site> takes site= only")
            spec.sites.append((child.attrib["site"], child))
        elif child.tag in ("geom", "pulley"):
            raise child.error(f"a spatial tendon's <{child.tag}> (wrapping around a geom, or a pulley) is not "
                              "modelled: rbody's spatial tendons are straight paths through sites")
        else:
            raise child.error(f"unknown element <{child.tag}> in a spatial tendon")
    if spec.kind == "fixed" and not spec.joints:
        raise element.error("a fixed tendon needs at least one <joint>")
    if spec.kind == "spatial" and len(spec.sites) < 2:
        raise element.error("a spatial tendon needs at least two <site>s")
    return spec


def tendon_of(spec: TendonSpec, name: str, sites: dict, spring_on: bool, damper_on: bool,
              limits_on: bool, frictionloss_on: bool, autolimits: bool, notes, restitution: float = 0.0) -> Tendon:
    """The rbody Tendon of a read tendon; sites: site name -> (body name or "world", point in that body's frame);
    restitution: Newton's coefficient of its limit's impacts. Its range (when limited) and frictionloss as the
    flags allow (module docstring); refuses what rbody does not model (armature, polynomial springs)."""
    element, attrib = spec.element, spec.attrib
    for key in ("stiffness", "damping"):
        if key in attrib and np.any(numbers(element, key, attrib)[1:] != 0):
            raise element.error(f"{key}={attrib[key]!r}: polynomial tendon springs and dampers are not modelled "
                                "(give one coefficient)")
    stiffness = float(numbers(element, "stiffness", attrib)[0]) if "stiffness" in attrib else 0.0
    damping = float(numbers(element, "damping", attrib)[0]) if "damping" in attrib else 0.0
    for key, value in (("stiffness", stiffness), ("damping", damping)):
        if value < 0:
            raise element.error(f"{key}={value!r}: must be >= 0")
    if number(element, "armature", attrib, 0.0) != 0:
        raise element.error("tendon armature (inertia added along the tendon) is not modelled")
    frictionloss = number(element, "frictionloss", attrib, 0.0)
    if frictionloss < 0:
        raise element.error(f"frictionloss={frictionloss!r}: must be >= 0 (a dry friction force)")
    if frictionloss and not frictionloss_on:
        notes("tendon frictionloss", "tendon frictionloss ignored (<flag frictionloss=\"disable\"/>)")
        frictionloss = 0.0
    limited = choice(element, "limited", attrib, LIMITED, "auto")
    tendon_range = None
    if limited == "true" or (limited == "auto" and autolimits and "range" in attrib):
        if "range" not in attrib:
            raise element.error("limited=\"true\" needs a range")
        low, high = numbers(element, "range", attrib, 2)
        if not low < high:
            raise element.error(f"range={attrib['range']!r}: a tendon's range needs lower < upper")
        margin = number(element, "margin", attrib, 0.0)
        if not low + margin < high - margin:
            raise element.error(f"range={attrib['range']!r} less margin={margin!r} leaves no room")
        if limits_on:
            tendon_range = (float(low + margin), float(high - margin))
        else:
            notes("tendon limit", "tendon limits ignored (<flag limit=\"disable\"/>)")
    elif limited == "auto" and "range" in attrib and not autolimits:
        raise element.error("range given but limited is \"auto\" without compiler autolimits: set limited=\"true\" "
                            "or autolimits=\"true\" (MuJoCo's rule)")
    soft = sorted(key for key in attrib if key.startswith(("solref", "solimp")))
    if soft and (tendon_range is not None or frictionloss):
        notes("tendon soft", f"tendon {', '.join(soft)} ignored: rbody's tendon limits and dry friction are rigid")
    if not spring_on and stiffness:
        notes("tendon spring", "tendon stiffness ignored (<flag spring=\"disable\"/>)")
        stiffness = 0.0
    if not damper_on and damping:
        notes("tendon damper", "tendon damping ignored (<flag damper=\"disable\"/>)")
        damping = 0.0
    springlength = None
    if "springlength" in attrib:
        values = numbers(element, "springlength", attrib, (1, 2))
        low, high = (values[0], values[0]) if len(values) == 1 else (values[0], values[1])
        if low > high:
            raise element.error("invalid springlength in tendon (low > high)")
        if not (low == -1 and high == -1):
            springlength = (float(low), float(high))
    constraints = dict(range=tendon_range, frictionloss=frictionloss,
                       restitution=restitution if tendon_range is not None else 0.0)
    if spec.kind == "fixed":
        return Tendon(name, "fixed", joints=tuple((joint, coef) for joint, coef, _child in spec.joints),
                      stiffness=stiffness, damping=damping, springlength=springlength, **constraints)
    path = []
    for site, child in spec.sites:
        if site not in sites:
            raise child.error(f"site={site!r} is not a <site> of the model")
        path.append(sites[site])
    return Tendon(name, "spatial", sites=tuple(path), stiffness=stiffness, damping=damping, springlength=springlength,
                  **constraints)


def _limited(spec: ActuatorSpec, key: str, autolimits: bool) -> bool:
    element = spec.element
    limited = getattr(spec, f"{key}limited")
    values = getattr(spec, f"{key}range")
    has_range = not (values[0] == 0 and values[1] == 0)
    if limited == "auto":
        if has_range and not autolimits:
            raise element.error(f"{key}range given but {key}limited is \"auto\" without compiler autolimits: set "
                                f"{key}limited=\"true\" or autolimits=\"true\" (MuJoCo's rule)")
        limited = "true" if has_range else "false"
    if limited == "true" and not values[0] < values[1]:
        raise element.error(f"invalid {key}range {values} (needs low < high)")
    return limited == "true"


def actuator_of(spec: ActuatorSpec, name: str, joint_kinds: dict, ranges: dict, tendon_names: set,
                autolimits: bool, disabled_groups: set, actuation_on: bool, clampctrl_on: bool,
                sites: dict | None = None) -> Actuator:
    """The rbody Actuator of a resolved spec (a dampratio still pending stays positive in biasprm[2]: resolve
    it with resolve_dampratio once the model's mass matrix is known). joint_kinds: joint name -> kind; ranges:
    joint or tendon name -> (lo, hi) declared range (for inheritrange); sites: site name -> (body, pos, quat) in
    the body's frame (site transmissions)."""
    element = spec.element
    if spec.trntype in ("body", "cranksite"):
        raise element.error(f"a {spec.trntype} transmission is not modelled (rbody drives joints, tendons and sites)")
    if spec.trntype == "site" and "refsite" in element.attrib:
        raise element.error("a site transmission with refsite (a length relative to another site) is not modelled")
    if not spec.trntype:
        raise element.error("the actuator names no transmission (joint=, jointinparent= or tendon=)")
    for key, value, choices in (("dyntype", spec.dyntype, ("none", "integrator", "filter", "filterexact")),
                                ("gaintype", spec.gaintype, ("fixed", "affine")),
                                ("biastype", spec.biastype, ("none", "affine"))):
        if value not in choices:
            raise element.error(f"{key}=\"{value}\" is not modelled (rbody reads {', '.join(choices)})")
    if any(spec.damping) or spec.armature:
        raise element.error("actuator damping and armature (added to the joint or tendon) are not modelled")
    if spec.delay:
        raise element.error("actuator delay (a history of controls) is not modelled")
    if spec.actdim not in (-1, int(spec.dyntype != "none")):
        raise element.error(f"actdim={spec.actdim} is not modelled (one activation with dynamics, none without)")
    site = None
    if spec.trntype == "site":
        if sites is None or spec.target not in sites:
            raise element.error(f"site={spec.target!r} is not a <site> of the model")
        body, pos, quat = sites[spec.target]
        kind, transmission, site = "site", "site", (pos, quat)
        target = body
    elif spec.trntype in ("joint", "jointinparent"):
        if spec.target not in joint_kinds:
            raise element.error(f"{spec.trntype}={spec.target!r} is not a joint of the model")
        kind = joint_kinds[spec.target]
        if spec.trntype == "jointinparent" and kind in ("ball", "free"):
            raise element.error("jointinparent on a ball or free joint (torques in the parent frame) is not "
                                "modelled")
        transmission = "joint"
    else:
        if spec.target not in tendon_names:
            raise element.error(f"tendon={spec.target!r} is not a tendon of the model")
        kind, transmission = "tendon", "tendon"
    if spec.trntype != "site":
        target = spec.target
    if spec.inheritrange > 0:
        position_like = spec.gaintype == "fixed" and spec.gainprm[0] == -spec.biasprm[1] and spec.biastype == "affine"
        if not position_like:
            raise element.error("inheritrange is for position and intvelocity actuators")
        if kind not in ("hinge", "slide", "tendon"):
            raise element.error("inheritrange can only be used with hinge and slide joints and tendons")
        if spec.target not in ranges:
            raise element.error(f"inheritrange used but target {spec.target!r} has no range")
        low, high = ranges[spec.target]
        middle, radius = 0.5 * (high + low), 0.5 * (high - low) * spec.inheritrange
        if spec.dyntype in ("none", "filterexact"):
            spec.ctrlrange[:] = [middle - radius, middle + radius]
        elif spec.dyntype == "integrator":
            spec.actrange[:] = [middle - radius, middle + radius]
        else:
            raise element.error("inheritrange only available for position and intvelocity actuators")
    ctrllimited = _limited(spec, "ctrl", autolimits)
    forcelimited = _limited(spec, "force", autolimits)
    actlimited = _limited(spec, "act", autolimits)
    gear = list(spec.gear)
    used = {"ball": 3, "free": 6, "site": 6}.get(kind, 1)
    if any(gear[used:]):
        raise element.error(f"gear={gear}: a {kind} transmission takes {used} gear component(s)")
    disabled = not actuation_on or (0 <= spec.group <= 30 and spec.group in disabled_groups)
    return Actuator(name, target, transmission=transmission, gear=tuple(gear[:used]), dynamics=spec.dyntype,
                    dynprm=spec.dynprm[0], gain=spec.gaintype, gainprm=tuple(spec.gainprm[:3]), bias=spec.biastype,
                    biasprm=tuple(spec.biasprm[:3]),
                    ctrlrange=tuple(spec.ctrlrange) if ctrllimited and clampctrl_on else None,
                    forcerange=tuple(spec.forcerange) if forcelimited else None,
                    actrange=tuple(spec.actrange) if actlimited else None, actearly=spec.actearly, disabled=disabled,
                    site=site)


def dampratio_pending(actuator: Actuator) -> bool:
    """Whether biasprm[2] > 0 on a position-like actuator: MuJoCo reads it as a damping ratio (engine_setconst.c)."""
    return actuator.gain == "fixed" and actuator.gainprm[0] == -actuator.biasprm[1] and actuator.biasprm[2] > 0


def resolve_dampratio(actuators: tuple[Actuator, ...], model, qpos0: np.ndarray) -> tuple[Actuator, ...]:
    """The actuators with every pending damping ratio turned into kv (biasprm[2] = -kv), as MuJoCo 4's compiler
    does it (measured against mujoco 4.0.0: its source's older rule, a sum of M_dd / moment_d^2, differs beyond
    one degree of freedom): kv = dampratio 2 sqrt(kp m), with m = 1 / (moment M^-1 moment^T) the mass reflected
    through the transmission, M the mass matrix at the model's reference pose qpos0 (armature included). model:
    the rbody.Multibody of the layout."""
    if not any(dampratio_pending(a) for a in actuators):
        return actuators
    inverse = np.linalg.inv(model.mass_matrix(qpos0))
    moment = model.actuation(qpos0, np.zeros(model.nv))["moment"]
    out = []
    for i, actuator in enumerate(actuators):
        if not dampratio_pending(actuator):
            out.append(actuator)
            continue
        mobility = float(moment[i] @ inverse @ moment[i])
        mass = 1.0 / mobility if mobility > MJ_MINVAL else 0.0
        kp = actuator.gainprm[0]
        kv = actuator.biasprm[2] * 2 * math.sqrt(kp * mass)
        out.append(replace(actuator, biasprm=(actuator.biasprm[0], actuator.biasprm[1], -kv)))
    return tuple(out)


# ----- writing ---------------------------------------------------------------------------------------------

DISABLED_GROUP = 30  # to_mjcf puts disabled actuators in this group and disables it (MuJoCo's highest)


def site_name(tendon: Tendon, k: int) -> str:
    """The name to_mjcf gives the k-th site of a spatial tendon."""
    return f"{tendon.name}_site{k}"


def tendon_sites(tendons, body: str, actuators=()) -> list[tuple[str, tuple, tuple]]:
    """(site name, point, quat) of every spatial tendon site and actuator site on `body` (or "world"), for
    to_mjcf."""
    out = [(site_name(t, k), point, (1.0, 0.0, 0.0, 0.0)) for t in tendons if t.kind == "spatial"
           for k, (owner, point) in enumerate(t.sites) if owner == body]
    return out + [(f"{a.name}_site", a.site[0], a.site[1]) for a in actuators
                  if a.transmission == "site" and a.target == body]


def tendon_xml(tendon: Tendon, springlength, attrs, vec, num, indent: str) -> list[str]:
    """MJCF lines of one tendon; springlength (low, high) as resolved by the engine (written explicitly)."""
    head = {"name": tendon.name}
    if tendon.stiffness:
        head["stiffness"] = num(tendon.stiffness)
    if tendon.damping:
        head["damping"] = num(tendon.damping)
    if springlength is not None:
        head["springlength"] = vec(springlength)
    if tendon.range is not None:
        head["limited"] = "true"
        head["range"] = f"{num(tendon.range[0])} {num(tendon.range[1])}"
    if tendon.frictionloss:
        head["frictionloss"] = num(tendon.frictionloss)
    lines = [f"{indent}<{tendon.kind} {attrs(**head)}>"]
    if tendon.kind == "fixed":
        lines += [f"{indent}  <joint {attrs(joint=name, coef=num(coef))}/>" for name, coef in tendon.joints]
    else:
        lines += [f"{indent}  <site {attrs(site=site_name(tendon, k))}/>" for k in range(len(tendon.sites))]
    lines.append(f"{indent}</{tendon.kind}>")
    return lines


def actuator_xml(actuator: Actuator, attrs, vec, num, indent: str) -> str:
    """One <general> element holding every parameter of the actuator (MuJoCo's general actuator is its model)."""
    target = f"{actuator.name}_site" if actuator.transmission == "site" else actuator.target
    values = {"name": actuator.name, actuator.transmission: target, "gear": vec(actuator.gear),
              "dyntype": actuator.dynamics, "gaintype": actuator.gain, "biastype": actuator.bias,
              "dynprm": num(actuator.dynprm), "gainprm": vec(actuator.gainprm), "biasprm": vec(actuator.biasprm)}
    for key in ("ctrl", "force", "act"):
        value = getattr(actuator, f"{key}range")
        values[f"{key}limited"] = "false" if value is None else "true"
        if value is not None:
            values[f"{key}range"] = vec(value)
    if actuator.actearly:
        values["actearly"] = "true"
    if actuator.disabled:
        values["group"] = str(DISABLED_GROUP)
    return f"{indent}<general {attrs(**values)}/>"


__all__ = ["ActuatorSpec", "TendonSpec", "apply_actuator", "read_tendon", "tendon_of", "actuator_of",
           "resolve_dampratio", "dampratio_pending", "SUPPORTED", "REFUSED", "tendon_xml", "actuator_xml",
           "tendon_sites", "site_name", "DISABLED_GROUP"]
