"""MJCF's contacts as rbody Contacts: MuJoCo's combination rules for a geom pair, and rbody's restitution numerics.

The broad phase's filter (which pairs can collide) is rbody.mjcf.parse (check_contacts: welds, parent-child,
<exclude>, contype/conaffinity, the contact flag), and every explicit <pair> (which replaces the dynamic pair of
the same geoms, as MuJoCo's does, with its own friction (sliding, torsional, rolling: the first, third and fourth of
its five, default 1 1 0.005 0.0001 0.0001) and condim (default 3), whatever the filters). For each dynamic pair
kept, as MuJoCo's mj_contactParam combines them:

- friction: a geom's `friction` is (sliding, torsional [m], rolling [m]), default 1 0.005 0.0001 for what it does
  not give; the pair's is the geom's with the higher `priority`, or, at equal priority, the larger of each;
- condim: the higher-priority geom's, or the larger; rbody models 1 (frictionless), 3 (Coulomb's circular cone,
  exact, rigid), 4 (and torsional friction) and 6 (and rolling friction), each friction its own Coulomb law sharing
  the normal force (rbody.engine.constraints.cone; MuJoCo bounds them in one cone, pyramidal or elliptic);
- restitution (rbody's own, MuJoCo's contacts have none but their softness): Newton's coefficient, from
  ``<custom><numeric name="rbody.contact_restitution.GEOM" data="e"/>`` on either geom (the larger of the two when
  both have one), else ``<numeric name="rbody.contact_restitution" data="e"/>`` for every pair, else 0 (plastic:
  the rigid limit of MuJoCo's critically damped default);
- margin: the two geoms' margins summed (a <pair>'s own, default 0; <option o_margin> for every pair under
  <flag override="enable">), MuJoCo's inflation of the surfaces since 3.9: a contact holds the geoms that far apart
  (Contact.margin), where MuJoCo's soft contact pushes towards it;
- gap (since MuJoCo 3.9 a band beyond the margin where contacts are reported but push nothing), solref, solimp,
  solmix (MuJoCo's softness) have no counterpart in the rigid limit: a contact holds at its margin to round-off.
  (Before MuJoCo 3.9 a contact pushed from margin - gap: a file written for it that sets gap > 0 needs its margins
  lowered by its gaps, as MuJoCo's changelog for 3.9.0 says.)

Geom kinds rbody computes: plane, sphere, capsule, ellipsoid, cylinder, box and mesh (by its convex hull, as MuJoCo
collides it), the pairs of rbody.engine.contacts.geometry.SLOTS.
"""

from __future__ import annotations

from rbody.layout import Contact
from rbody.mjcf.document import MJCFError, integer, number, numbers

CONTACT_RESTITUTION = "rbody.contact_restitution"


def _kind_code(geom) -> int | None:
    from rbody.engine.contacts.geometry import TYPE_CODES

    return TYPE_CODES.get(geom.kind)


def _combined(g1, g2, key: str, read):
    p1, p2 = (integer(g.element, "priority", g.attrib, 0) for g in (g1, g2))
    v1, v2 = read(g1), read(g2)
    if p1 != p2:
        return v1 if p1 > p2 else v2
    return max(v1, v2)


GEOM_FRICTION = (1.0, 0.005, 0.0001)  # MuJoCo's default (sliding, torsional [m], rolling [m])
PAIR_FRICTION = (1.0, 1.0, 0.005, 0.0001, 0.0001)  # a <pair>'s (tangent 1, tangent 2, torsional, rolling 1, 2)


def _friction(geom) -> tuple[float, float, float]:
    """A geom's (sliding, torsional, rolling) friction: what its `friction` gives, MuJoCo's default for the rest."""
    given = [float(x) for x in numbers(geom.element, "friction", geom.attrib)] if "friction" in geom.attrib else []
    return tuple(given + list(GEOM_FRICTION[len(given):]))


def _combined_friction(g1, g2) -> tuple[float, float, float]:
    """The pair's friction: the higher-priority geom's, or each component's larger (mj_contactParam)."""
    p1, p2 = (integer(g.element, "priority", g.attrib, 0) for g in (g1, g2))
    f1, f2 = _friction(g1), _friction(g2)
    if p1 != p2:
        return f1 if p1 > p2 else f2
    return tuple(max(a, b) for a, b in zip(f1, f2))


def _margin(element, attrib) -> float:
    """An element's margin [m] (default 0). Raises MJCFError for a negative one (rbody's contacts hold the
    surfaces at least that far apart: a negative margin would let them overlap)."""
    margin = number(element, "margin", attrib, 0.0)
    if margin < 0:
        raise element.error(f"margin={attrib['margin']!r}: rbody needs a contact margin >= 0 [m] (the distance at "
                            "which a contact holds the surfaces)")
    return margin


def _condim(geom) -> int:
    return integer(geom.element, "condim", geom.attrib, 3)


def explicit_pairs(pairs, named: dict, body_of: dict) -> list:
    """(g1, g2, spec) of every <pair> (element, attributes with its class's defaults): the geoms it names (by the
    names the file gives them) and spec = {"friction": (sliding, torsional, rolling), the first, third and fourth
    of its five (default 1 1 0.005 0.0001 0.0001), "condim": its condim (default 3)}, MuJoCo's defaults for a pair
    (its own, not its geoms'). body_of: geom name -> (the rbody body that carries it, its own body's name). Raises
    MJCFError for a missing or unknown geom, a pair of one geom with itself, or of two geoms carried by one body
    (fixed to each other: nothing to collide)."""
    out = []
    for element, attrib in pairs:
        geoms = []
        for key in ("geom1", "geom2"):
            if key not in attrib:
                raise element.error(f"a <pair> needs {key}")
            if attrib[key] not in named:
                raise element.error(f"{key}={attrib[key]!r} is not a geom of the model")
            geoms.append(named[attrib[key]])
        if geoms[0] is geoms[1]:
            raise element.error(f"geom1 and geom2 are both {attrib['geom1']!r}")
        (carrier1, own1), (carrier2, own2) = (body_of[attrib[k]] for k in ("geom1", "geom2"))
        if carrier1 == carrier2:
            folded = [own for own in dict.fromkeys((own1, own2)) if own != carrier1]
            why = (f" (body {folded[0]!r} has neither mass nor joints: it is part of {carrier1!r})" if folded else "")
            raise element.error(f"geom1={attrib['geom1']!r} and geom2={attrib['geom2']!r} are both on body "
                                f"{carrier1!r}{why}: a contact needs geoms of two bodies (or of a body and the world)")
        given = [float(x) for x in numbers(element, "friction", attrib)] if "friction" in attrib else []
        five = given + list(PAIR_FRICTION[len(given):])
        friction = (five[0], five[2], five[3])
        condim = integer(element, "condim", attrib, 3)
        if condim not in (1, 3, 4, 6):
            raise element.error(f"condim={attrib['condim']!r}: MuJoCo allows 1, 3, 4 or 6 (invalid condim)")
        out.append((geoms[0], geoms[1], {"friction": friction, "condim": condim, "margin": _margin(element, attrib)}))
    return out


def unsupported_pair(g1, g2, spec: dict | None = None) -> str:
    """Why rbody cannot run contacts between geoms g1 and g2 (parse's _Geom; spec: an explicit <pair>'s friction
    and condim, which rbody models whatever they are), or "" when it can."""
    from rbody.engine.contacts.geometry import SLOTS, pairs_text

    if "hfield" in (g1.kind, g2.kind):
        other = g2 if g1.kind == "hfield" else g1
        if other.kind in ("plane", "hfield"):
            return f"rbody does not compute hfield-{other.kind} contacts (MuJoCo has none)"
        return ""
    codes = [_kind_code(g) for g in (g1, g2)]
    if None in codes:
        kind = g1.kind if codes[0] is None else g2.kind
        return (f"rbody computes contacts of plane, sphere, capsule, ellipsoid, cylinder, box, mesh and hfield "
                f"geoms, not {kind}")
    if tuple(sorted(codes)) not in SLOTS:
        return f"rbody does not compute {g1.kind}-{g2.kind} contacts yet (it computes {pairs_text()})"
    return ""


def contacts_of(pairs, numerics: dict, source: str, override_margin: float | None = None) -> tuple[Contact, ...]:
    """The rbody Contact of every geom pair (g1, g2, spec) kept by the broad phase or listed (spec: explicit_pairs),
    with MuJoCo's friction, condim and margin (override_margin [m]: <option o_margin> under <flag override>, for
    every pair) and rbody's restitution (module docstring). Raises MJCFError for a restitution numeric naming no
    geom, or a negative margin."""
    names = {g.name for g1, g2, _spec in pairs for g in (g1, g2)}
    prefix = CONTACT_RESTITUTION + "."
    stray = sorted(n for n in numerics if n.startswith(prefix) and n[len(prefix):] not in names)
    if stray:
        raise MJCFError(f"{source}: <custom><numeric name={stray[0]!r}> names no geom that can collide")
    for key, data in numerics.items():
        if (key == CONTACT_RESTITUTION or key.startswith(prefix)) and (data.size != 1 or not 0 <= data[0] <= 1):
            raise MJCFError(f"{source}: <custom><numeric name={key!r}>: a restitution is one number in [0, 1], "
                            f"not {data.tolist()}")
    out = []
    for g1, g2, spec in pairs:
        own = [float(numerics[prefix + g.name][0]) for g in (g1, g2) if prefix + g.name in numerics]
        if own:
            restitution = max(own)
        elif CONTACT_RESTITUTION in numerics:
            restitution = float(numerics[CONTACT_RESTITUTION][0])
        else:
            restitution = 0.0
        if spec:
            friction, condim, margin = spec["friction"], spec["condim"], spec["margin"]
        else:
            friction, condim = _combined_friction(g1, g2), _combined(g1, g2, "condim", _condim)
            margin = _margin(g1.element, g1.attrib) + _margin(g2.element, g2.attrib)
        if override_margin is not None:
            if override_margin < 0:
                raise MJCFError(f"{source}: <option o_margin={override_margin!r}>: rbody needs a contact margin >= 0 "
                                "[m] (the distance at which a contact holds the surfaces)")
            margin = override_margin
        slide, torsion, rolling = friction
        out.append(Contact(g1.name, g2.name, friction=slide, restitution=restitution, condim=condim,
                           torsion=torsion if condim >= 4 else 0.0, rolling=rolling if condim == 6 else 0.0,
                           margin=margin))
    return tuple(out)


__all__ = ["contacts_of", "unsupported_pair", "CONTACT_RESTITUTION"]
