"""MJCF's contacts as rbody Contacts: MuJoCo's combination rules for a geom pair, and rbody's restitution numerics.

The broad phase's filter (which pairs can collide) is rbody.mjcf.parse (check_contacts: welds, parent-child,
<exclude>, contype/conaffinity, the contact flag). For each pair kept, as MuJoCo's mj_contactParam combines them:

- friction: the sliding coefficient (the first of a geom's `friction`, default 1) of the geom with the higher
  `priority`, or, at equal priority, the larger of the two (MuJoCo takes the maximum of each component);
- condim: the higher-priority geom's, or the larger; rbody models 1 (frictionless) and 3 (Coulomb's circular cone,
  exact, rigid); 4 and 6 (torsional and rolling friction) are refused;
- restitution (rbody's own, MuJoCo's contacts have none but their softness): Newton's coefficient, from
  ``<custom><numeric name="rbody.contact_restitution.GEOM" data="e"/>`` on either geom (the larger of the two when
  both have one), else ``<numeric name="rbody.contact_restitution" data="e"/>`` for every pair, else 0 (plastic:
  the rigid limit of MuJoCo's critically damped default);
- solref, solimp, margin, gap, solmix (MuJoCo's softness and activation distance) have no counterpart in the rigid
  limit: a contact acts at distance 0 and holds to round-off.

Geom kinds rbody computes: plane, sphere, capsule, box, the pairs of rbody.engine.contacts.geometry.SLOTS.
"""

from __future__ import annotations

from rbody.layout import Contact
from rbody.mjcf.document import MJCFError, integer, numbers

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


def _friction(geom) -> float:
    if "friction" not in geom.attrib:
        return 1.0
    return float(numbers(geom.element, "friction", geom.attrib)[0])


def _condim(geom) -> int:
    return integer(geom.element, "condim", geom.attrib, 3)


def unsupported_pair(g1, g2) -> str:
    """Why rbody cannot run contacts between geoms g1 and g2 (parse's _Geom), or "" when it can."""
    from rbody.engine.contacts.geometry import SLOTS

    codes = [_kind_code(g) for g in (g1, g2)]
    if None in codes:
        kind = g1.kind if codes[0] is None else g2.kind
        return (f"rbody computes contacts of plane, sphere, capsule and box geoms, not {kind} (cylinder, ellipsoid, "
                "mesh and height-field contacts are to come)")
    if tuple(sorted(codes)) not in SLOTS:
        return (f"rbody does not compute {g1.kind}-{g2.kind} contacts yet (it computes plane with sphere, capsule and "
                "box; sphere with sphere, capsule and box; capsule with capsule; box with box)")
    condim = _combined(g1, g2, "condim", _condim)
    if condim not in (1, 3):
        return (f"their contact has condim {condim}: rbody models condim 1 (frictionless) and 3 (Coulomb's cone), "
                "not torsional (4) or rolling (6) friction")
    return ""


def contacts_of(pairs, numerics: dict, source: str) -> tuple[Contact, ...]:
    """The rbody Contact of every geom pair (g1, g2) kept by the broad phase, with MuJoCo's friction and condim and
    rbody's restitution (module docstring). Raises MJCFError for a restitution numeric naming no geom."""
    names = {g.name for pair in pairs for g in pair}
    prefix = CONTACT_RESTITUTION + "."
    stray = sorted(n for n in numerics if n.startswith(prefix) and n[len(prefix):] not in names)
    if stray:
        raise MJCFError(f"{source}: <custom><numeric name={stray[0]!r}> names no geom that can collide")
    for key, data in numerics.items():
        if (key == CONTACT_RESTITUTION or key.startswith(prefix)) and (data.size != 1 or not 0 <= data[0] <= 1):
            raise MJCFError(f"{source}: <custom><numeric name={key!r}>: a restitution is one number in [0, 1], "
                            f"not {data.tolist()}")
    out = []
    for g1, g2 in pairs:
        own = [float(numerics[prefix + g.name][0]) for g in (g1, g2) if prefix + g.name in numerics]
        if own:
            restitution = max(own)
        elif CONTACT_RESTITUTION in numerics:
            restitution = float(numerics[CONTACT_RESTITUTION][0])
        else:
            restitution = 0.0
        out.append(Contact(g1.name, g2.name, friction=_combined(g1, g2, "friction", _friction),
                           restitution=restitution, condim=_combined(g1, g2, "condim", _condim)))
    return tuple(out)


__all__ = ["contacts_of", "unsupported_pair", "CONTACT_RESTITUTION"]
