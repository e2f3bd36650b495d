"""MJCF's constraints read into rbody's description: joint limits, dry friction, restitution, equalities.

rbody holds every constraint rigidly (rbody.engine.constraints), so MuJoCo's softness settings (solref, solimp,
solreflimit, solimplimit, solreffriction, solimpfriction, torquescale, margin's soft band) have no counterpart;
the reader notes them where a model sets them. What is read, as MuJoCo's compiler reads it:

- a joint's ``range`` when it is limited: ``limited="true"``, or ``limited="auto"`` (the default) with
  ``<compiler autolimits="true"/>`` (the default) and a range given. The limit sits at range less the joint's
  ``margin`` (MuJoCo's limit force holds the joint at distance margin from its range). Ball joints: range
  "0 theta_max" bounds the rotation angle. ``<flag limit="disable"/>`` (or constraint) drops every limit.
- a joint's ``frictionloss`` [N m or N] per degree of freedom; ``<flag frictionloss="disable"/>`` drops it.
- restitution, rbody's own (MuJoCo's limits have none: their rebound follows from solref): Newton's coefficient
  of a joint's limit impacts, from ``<custom><numeric name="rbody.restitution.JOINT" data="e"/></custom>`` for
  one joint, or ``name="rbody.restitution"`` for every joint without its own; default 0 (the joint stays at its
  stop, the rigid limit of MuJoCo's default critically damped limit). MuJoCo ignores these numerics.
- ``<equality>``: ``connect`` (body1, body2, anchor, or site1 and site2), ``weld`` (body1, body2, anchor, relpose,
  or site1 and site2), ``joint`` (joint1, joint2, polycoef), each with ``active`` (default true; an inactive
  equality is kept, inactive, as MuJoCo starts it) and defaults from ``<default><equality>``. Where MuJoCo
  completes an equality from the model's reference configuration qpos0 (a connect's point on body2; a weld's
  relative pose when relpose is not given), the reader does the same from the bodies' frames, so that the
  Equality it returns is explicit. ``<flag equality="disable"/>`` drops every equality (noted).
  ``tendon`` (tendon1, tendon2, polycoef: L1 - L1_0 = P(L2 - L2_0), L_0 the lengths at qpos0, MuJoCo's
  convention; rbody.layout.Equality) is read too; its tendons must be tendons of the model.
- a tendon's limit restitution: ``name="rbody.restitution.TENDON"`` as for a joint (tendon and joint names share
  the numerics' namespace; the model-wide ``rbody.restitution`` applies to tendon limits too).
"""

from __future__ import annotations

import numpy as np

from rbody.layout import WORLD, Equality
from rbody.mjcf.document import Element, MJCFError, boolean, numbers
from rbody.mjcf.frames import quat_matrix, quat_product

RESTITUTION_NUMERIC = "rbody.restitution"   # <custom><numeric name=...>: every limit; + ".JOINT": one joint's
SOFTNESS_ATTRS = ("solref", "solimp")       # MuJoCo's soft-constraint settings, replaced by the rigid limit
_COMMON = {"name", "class", "active", "solref", "solimp"}
EQUALITY_ATTRS = {
    "connect": _COMMON | {"body1", "body2", "anchor", "site1", "site2"},
    "weld": _COMMON | {"body1", "body2", "anchor", "relpose", "torquescale", "site1", "site2"},
    "joint": _COMMON | {"joint1", "joint2", "polycoef"},
    "tendon": _COMMON | {"tendon1", "tendon2", "polycoef"},
}


def read_numerics(elements: list[Element]) -> dict[str, np.ndarray]:
    """name -> data of every <custom><numeric> (other custom entries are left to the caller's note)."""
    found: dict[str, np.ndarray] = {}
    for custom in elements:
        for child in custom.children:
            if child.tag != "numeric":
                continue
            name = child.attrib.get("name")
            if name is None:
                raise child.error("a <numeric> needs a name")
            data = numbers(child, "data", child.attrib) if "data" in child.attrib else np.zeros(1)
            found[name] = data
            if name.startswith(RESTITUTION_NUMERIC):
                if data.size != 1 or not 0.0 <= data[0] <= 1.0:
                    raise child.error(f"data={child.attrib.get('data')!r}: a restitution is one number in [0, 1]")
    return found


def restitution_of(numerics: dict[str, np.ndarray], joint: str) -> float:
    """Newton's coefficient of joint `joint`'s limit impacts: its own numeric, else the model's, else 0."""
    for key in (f"{RESTITUTION_NUMERIC}.{joint}", RESTITUTION_NUMERIC):
        if key in numerics:
            return float(numerics[key][0])
    return 0.0


def unknown_restitutions(numerics: dict[str, np.ndarray], joints: set[str]) -> list[str]:
    """Restitution numerics that name no joint (nor tendon) of the model (a typo would otherwise pass unseen)."""
    prefix = RESTITUTION_NUMERIC + "."
    return sorted(name for name in numerics if name.startswith(prefix) and name[len(prefix):] not in joints)


# ----- frames ----------------------------------------------------------------------------------------------

def _inverse(quat: np.ndarray) -> np.ndarray:
    return np.array([quat[0], -quat[1], -quat[2], -quat[3]])


class Frames:
    """Where every MJCF body sits at the reference configuration (MuJoCo's qpos0: every body at its own pos/quat
    in its parent), and which rbody body carries it (a folded body's frame inside its carrier).

    world: MJCF body index -> (pos (3,), quat (4,)) in the world; carrier: index -> (rbody body name, pos, quat
    of the MJCF body's frame in the carrier's); index: MJCF body name -> index (the world: 0)."""

    def __init__(self, bodies, carriers: dict) -> None:
        self.world = {0: (np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))}
        self.index = {WORLD: 0}
        for body in bodies:  # parents come before children
            ppos, pquat = self.world[body.parent.index]
            self.world[body.index] = (ppos + quat_matrix(pquat) @ body.pos, quat_product(pquat, body.quat))
            self.index[body.name] = body.index
        self.carrier = carriers

    def point_in_carrier(self, index: int, point) -> tuple[str, np.ndarray]:
        """(carrier name, the point given in MJCF body `index`'s frame, in the carrier's frame)."""
        name, pos, quat = self.carrier[index]
        return name, pos + quat_matrix(quat) @ np.asarray(point, dtype=float)

    def quat_in_carrier(self, index: int, quat) -> np.ndarray:
        """An orientation given in MJCF body `index`'s frame, in its carrier's frame."""
        return quat_product(self.carrier[index][2], np.asarray(quat, dtype=float))

    def to_world(self, index: int, point) -> np.ndarray:
        pos, quat = self.world[index]
        return pos + quat_matrix(quat) @ np.asarray(point, dtype=float)

    def from_world(self, index: int, point) -> np.ndarray:
        pos, quat = self.world[index]
        return quat_matrix(quat).T @ (np.asarray(point, dtype=float) - pos)


# ----- equalities ------------------------------------------------------------------------------------------

def equality_kind_error(element: Element) -> MJCFError | None:
    """The error for an equality element rbody cannot hold, or None."""
    if element.tag == "flex":
        return element.error("flex equality constraints are not supported (rbody models no deformable bodies)")
    if element.tag not in EQUALITY_ATTRS:
        return element.error(f"unknown element <{element.tag}> in <equality>")
    return None


def equality_from(element: Element, attrib: dict, name: str, frames: Frames, sites: dict,
                  joints: dict, tendons=frozenset()) -> Equality:
    """The rbody Equality of one MJCF equality element (attrib: its attributes over its class's defaults).

    frames: Frames of the model; sites: site name -> (MJCF body index, pos (3,), quat (4,)) in that body's frame;
    joints: joint name -> rbody Joint (for a joint equality's kinds); tendons: the model's tendon names."""
    active = boolean(element, "active", attrib, True)
    tag = element.tag
    if tag == "tendon":
        first, second = attrib.get("tendon1"), attrib.get("tendon2")
        if first is None:
            raise element.error("a tendon equality needs tendon1")
        for tendon in (first, second):
            if tendon is not None and tendon not in tendons:
                raise element.error(f"tendon {tendon!r} is not a tendon of the model (tendons: {sorted(tendons)})")
        coefficients = numbers(element, "polycoef", attrib, 5) if "polycoef" in attrib else np.array(
            [0.0, 1.0, 0.0, 0.0, 0.0])
        return Equality(name, "tendon", tendon1=first, tendon2=second, polycoef=tuple(coefficients.tolist()),
                        active=active)
    if tag == "joint":
        first, second = attrib.get("joint1"), attrib.get("joint2")
        if first is None:
            raise element.error("a joint equality needs joint1")
        for joint in (first, second):
            if joint is None:
                continue
            if joint not in joints:
                raise element.error(f"joint {joint!r} is not a joint of the model")
            if joints[joint].kind not in ("hinge", "slide"):
                raise element.error(f"joint {joint!r} is a {joints[joint].kind} joint: a joint equality couples "
                                    "hinge and slide joints (MuJoCo's rule)")
        coefficients = numbers(element, "polycoef", attrib, 5) if "polycoef" in attrib else np.array(
            [0.0, 1.0, 0.0, 0.0, 0.0])
        return Equality(name, "joint", joint1=first, joint2=second, polycoef=tuple(coefficients.tolist()),
                        active=active)

    bodies = (attrib.get("body1"), attrib.get("body2"))
    site_names = (attrib.get("site1"), attrib.get("site2"))
    if any(site_names):
        if not all(site_names) or any(bodies):
            raise element.error("give site1 and site2, or body1 (and body2), not a mixture")
        for site in site_names:
            if site not in sites:
                raise element.error(f"site {site!r} is not a named site of the model")
        (i1, p1, q1), (i2, p2, q2) = sites[site_names[0]], sites[site_names[1]]
        body1, anchor1 = frames.point_in_carrier(i1, p1)
        body2, anchor2 = frames.point_in_carrier(i2, p2)
        if body1 == body2:
            raise element.error(f"sites {site_names[0]!r} and {site_names[1]!r} are on one rigid body ({body1!r})")
        if tag == "connect":
            return Equality(name, "connect", body1=body1, body2=body2, anchor=tuple(anchor1.tolist()),
                            anchor2=tuple(anchor2.tolist()), active=active)
        # weld: body1's site frame on body2's: q_c1 qs1 = q_c2 qs2, so q_c1 relquat = q_c2 with relquat = qs1 qs2^-1
        qs1, qs2 = frames.quat_in_carrier(i1, q1), frames.quat_in_carrier(i2, q2)
        relquat = quat_product(qs1, _inverse(qs2))
        return Equality(name, "weld", body1=body1, body2=body2, anchor=tuple(anchor2.tolist()),
                        relpose=tuple(anchor1.tolist() + relquat.tolist()), active=active)

    if bodies[0] is None:
        raise element.error(f"a {tag} equality needs body1 (or site1 and site2)")
    indices = []
    for body in (bodies[0], bodies[1] or WORLD):
        if body not in frames.index:
            raise element.error(f"body {body!r} is not a body of the model")
        indices.append(frames.index[body])
    i1, i2 = indices
    body1, body2 = frames.carrier[i1][0], frames.carrier[i2][0]
    if body1 == body2:
        raise element.error(f"bodies {bodies[0]!r} and {bodies[1] or WORLD!r} are one rigid body ({body1!r}): "
                            "nothing to constrain")
    anchor = numbers(element, "anchor", attrib, 3) if "anchor" in attrib else np.zeros(3)
    if tag == "connect":  # anchor in body1; body2's point is where the anchor sits at qpos0
        point = frames.to_world(i1, anchor)
        _, anchor1 = frames.point_in_carrier(i1, anchor)
        _, anchor2 = frames.point_in_carrier(i2, frames.from_world(i2, point))
        return Equality(name, "connect", body1=body1, body2=body2, anchor=tuple(anchor1.tolist()),
                        anchor2=tuple(anchor2.tolist()), active=active)
    # weld: anchor in body2; relpose (pos in body1, quat of body2 relative to body1), or both at qpos0
    relpose = numbers(element, "relpose", attrib, 7) if "relpose" in attrib else np.zeros(7)
    _, anchor2 = frames.point_in_carrier(i2, anchor)
    if np.any(relpose[3:] != 0):
        relquat = relpose[3:] / np.linalg.norm(relpose[3:])
        relpos = relpose[:3]
    else:
        relpos = frames.from_world(i1, frames.to_world(i2, anchor))
        relquat = quat_product(_inverse(frames.world[i1][1]), frames.world[i2][1])
    _, relpos_c = frames.point_in_carrier(i1, relpos)
    # q_b1 relquat = q_b2, q_b = q_c qo: q_c1 (qo1 relquat qo2^-1) = q_c2
    relquat_c = quat_product(quat_product(frames.carrier[i1][2], relquat), _inverse(frames.carrier[i2][2]))
    return Equality(name, "weld", body1=body1, body2=body2, anchor=tuple(anchor2.tolist()),
                    relpose=tuple(relpos_c.tolist() + (relquat_c / np.linalg.norm(relquat_c)).tolist()),
                    active=active)


def softness_note(attrib: dict) -> str:
    """A note when an equality or joint sets MuJoCo's soft-constraint parameters, else ""."""
    keys = [key for key in attrib if key in SOFTNESS_ATTRS or key.startswith(("solref", "solimp"))
            or key == "torquescale"]
    return ", ".join(sorted(keys))


__all__ = ["RESTITUTION_NUMERIC", "EQUALITY_ATTRS", "Frames", "read_numerics", "restitution_of",
           "unknown_restitutions", "equality_from", "equality_kind_error", "softness_note"]
