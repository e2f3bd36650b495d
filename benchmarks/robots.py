"""MJCF models written for the engine-core speed benchmarks (our own numbers; no published model is copied).

- humanoid(): 27 degrees of freedom in the manner of the control suite's humanoid: a free torso, an abdomen of
  three hinges on two bodies, hips of three hinges, knees, ankles of two, shoulders of two, elbows; capsules,
  joint damping, stiffness and armature, contacts off.
- arm(dof): a serial arm of `dof` hinges (7 for an arm like a Panda's), axes alternating about z and y of
  each link, link offsets along the arm, capsule links.
- hand(fingers, arm_dof): an arm of `arm_dof` hinges ending in a palm with `fingers` fingers of four
  hinges each (spread, then three flexions), the thumb's base turned.
- arms_with_hands(): two 7-dof arms on one fixed base, each carrying a five-fingered hand: 2 (7 + 3 + 20) = 60
  degrees of freedom.
- random_chain(links, seed): a serial chain of `links` bodies, each a hinge about a random axis through a
  random anchor, random offsets, masses and inertia tensors (the 3-D path: no common plane).

Every model disables contacts and constraints (<flag contact="disable" constraint="disable"/>), so MuJoCo,
Pinocchio and rbody integrate the same unconstrained tree.
"""

from __future__ import annotations

import numpy as np

HEADER = """<mujoco model="{name}">
  <compiler angle="radian"/>
  <option timestep="0.001" integrator="RK4" gravity="0 0 -9.81">
    <flag contact="disable" constraint="disable"/>
  </option>
  <default>
    <joint damping="{damping}" armature="{armature}"/>
    <geom type="capsule" density="1000"/>
  </default>
  <worldbody>
"""
FOOTER = """  </worldbody>
</mujoco>
"""


def _f(values) -> str:
    return " ".join(f"{float(v):.6g}" for v in np.ravel(values))


def humanoid() -> str:
    """27 dof (nq 28): free torso; abdomen z, y (lower waist) and x (pelvis); per leg hip x, z, y, knee, ankle y, x;
    per arm shoulder 1, 2 and elbow."""
    def leg(side: str, sign: float) -> str:
        return f"""
        <body name="{side}_thigh" pos="0 {sign * 0.1:.3g} -0.04">
          <joint name="{side}_hip_x" type="hinge" axis="1 0 0" pos="0 0 0" stiffness="10"/>
          <joint name="{side}_hip_z" type="hinge" axis="0 0 1" pos="0 0 0" stiffness="10"/>
          <joint name="{side}_hip_y" type="hinge" axis="0 1 0" pos="0 0 0" stiffness="20" armature="0.01"/>
          <geom name="{side}_thigh" fromto="0 0 0 0 {sign * 0.01:.3g} -0.34" size="0.06"/>
          <body name="{side}_shin" pos="0 {sign * 0.01:.3g} -0.403">
            <joint name="{side}_knee" type="hinge" axis="0 -1 0" pos="0 0 0.02" stiffness="5"/>
            <geom name="{side}_shin" fromto="0 0 0 0 0 -0.3" size="0.049"/>
            <body name="{side}_foot" pos="0 0 -0.39">
              <joint name="{side}_ankle_y" type="hinge" axis="0 1 0" pos="0 0 0.08" stiffness="4"/>
              <joint name="{side}_ankle_x" type="hinge" axis="1 0 0.5" pos="0 0 0.04" stiffness="1"/>
              <geom name="{side}_foot" fromto="-0.07 {-sign * 0.02:.3g} 0 0.14 {sign * 0.02:.3g} 0" size="0.027"/>
            </body>
          </body>
        </body>"""

    def arm(side: str, sign: float) -> str:
        return f"""
      <body name="{side}_upper_arm" pos="0 {sign * 0.17:.3g} 0.06">
        <joint name="{side}_shoulder1" type="hinge" axis="2 {sign:.3g} 1" pos="0 0 0" stiffness="3"/>
        <joint name="{side}_shoulder2" type="hinge" axis="0 {-sign:.3g} 1" pos="0 0 0" stiffness="3"/>
        <geom name="{side}_upper_arm" fromto="0 0 0 0.16 {sign * 0.16:.3g} -0.16" size="0.04 0.16"/>
        <body name="{side}_lower_arm" pos="0.18 {sign * 0.18:.3g} -0.18">
          <joint name="{side}_elbow" type="hinge" axis="0 {-sign:.3g} 1" pos="0 0 0" stiffness="2"/>
          <geom name="{side}_lower_arm" fromto="0.01 {sign * 0.01:.3g} 0.01 0.17 {sign * 0.17:.3g} 0.17"
                size="0.031"/>
        </body>
      </body>"""

    return (HEADER.format(name="humanoid", damping=0.2, armature=0.02) + """    <body name="torso" pos="0 0 1.4">
      <freejoint name="root"/>
      <geom name="torso" fromto="0 -0.07 0 0 0.07 0" size="0.07"/>
      <body name="lower_waist" pos="-0.01 0 -0.26" quat="1 0 -0.002 0">
        <joint name="abdomen_z" type="hinge" axis="0 0 1" pos="0 0 0.065" stiffness="20"/>
        <joint name="abdomen_y" type="hinge" axis="0 1 0" pos="0 0 0.065" stiffness="10"/>
        <geom name="lower_waist" fromto="0 -0.06 0 0 0.06 0" size="0.06"/>
        <body name="pelvis" pos="0 0 -0.165" quat="1 0 -0.002 0">
          <joint name="abdomen_x" type="hinge" axis="1 0 0" pos="0 0 0.1" stiffness="10"/>
          <geom name="butt" fromto="-0.02 -0.07 0 -0.02 0.07 0" size="0.09"/>"""
            + leg("right", -1.0) + leg("left", 1.0) + """
        </body>
      </body>""" + arm("right", -1.0) + arm("left", 1.0) + """
    </body>
""" + FOOTER)


def _arm_bodies(dof: int, prefix: str, indent: str, tail: str = "", base_pos=(0, 0, 0.3)) -> str:
    """Nested bodies of a serial arm of `dof` hinges (axes z, y, z, y, ...), `tail` inside the last link."""
    opening, closing = [], []
    for k in range(dof):
        axis = "0 0 1" if k % 2 == 0 else "0 1 0"
        pos = _f(base_pos) if k == 0 else ("0 0 0.25" if k % 2 == 0 else "0.02 0 0.12")
        radius = 0.06 - 0.004 * min(k, 10)
        pad = indent + "  " * k
        opening.append(f'{pad}<body name="{prefix}link{k}" pos="{pos}">\n'
                       f'{pad}  <joint name="{prefix}j{k}" type="hinge" axis="{axis}"/>\n'
                       f'{pad}  <geom fromto="0 0 0 0.01 0 {0.2 if k % 2 == 0 else 0.1}" size="{radius:.3g}"/>\n')
        closing.append(f"{pad}</body>\n")
    inner = indent + "  " * dof
    return "".join(opening) + tail.replace("\n", "\n" + inner).rstrip(" ") + "".join(reversed(closing))


def _hand(prefix: str, fingers: int, wrist: int = 3) -> str:
    """A palm on `wrist` hinges with `fingers` fingers of four hinges each (spread, three flexions)."""
    axes = ("1 0 0", "0 1 0", "0 0 1")
    wrist_joints = "".join(f'  <joint name="{prefix}wrist{k}" type="hinge" axis="{axes[k % 3]}"/>\n' for k in range(wrist))
    parts = [f'<body name="{prefix}palm" pos="0 0 0.22">\n{wrist_joints}'
             f'  <geom type="box" size="0.045 0.015 0.05" pos="0 0 0.05"/>\n']
    for f in range(fingers):
        thumb = f == 0
        x = -0.04 + 0.08 * f / max(fingers - 1, 1)
        base = f'pos="{-0.05:.3g} 0 0.03" quat="0.924 0 0.383 0"' if thumb else f'pos="{x:.3g} 0 0.1"'
        lengths = (0.045, 0.03, 0.025)
        segment = f'  <body name="{prefix}f{f}_0" {base}>\n'
        segment += f'    <joint name="{prefix}f{f}_spread" type="hinge" axis="0 1 0"/>\n'
        segment += f'    <joint name="{prefix}f{f}_flex0" type="hinge" axis="1 0 0"/>\n'
        segment += f'    <geom fromto="0 0 0 0 0 {lengths[0]}" size="0.009"/>\n'
        z = lengths[0]
        closing = "  </body>\n"
        for s in (1, 2):
            pad = "  " * (s + 1)
            segment += f'{pad}<body name="{prefix}f{f}_{s}" pos="0 0 {z:.3g}">\n'
            segment += f'{pad}  <joint name="{prefix}f{f}_flex{s}" type="hinge" axis="1 0.1 0"/>\n'
            segment += f'{pad}  <geom fromto="0 0 0 0 0 {lengths[s]}" size="0.008"/>\n'
            closing = f"{pad}</body>\n" + closing
            z = lengths[s]
        parts.append(segment + closing)
    parts.append("</body>\n")
    return "".join(parts)


def arm(dof: int = 7) -> str:
    """A serial arm of `dof` hinges on a fixed base."""
    return HEADER.format(name=f"arm{dof}", damping=0.5, armature=0.05) + _arm_bodies(dof, "", "    ") + FOOTER


def hand(fingers: int = 5, arm_dof: int = 0) -> str:
    """A hand of `fingers` four-hinge fingers on three wrist hinges, on an arm of `arm_dof` hinges (fixed base):
    arm_dof + 3 + 4 fingers degrees of freedom."""
    tail = _hand("", fingers)
    if arm_dof == 0:
        body = '    <body name="base" pos="0 0 0.3">\n      ' + tail.replace("\n", "\n      ").rstrip(" ") + "    </body>\n"
    else:
        body = _arm_bodies(arm_dof, "", "    ", tail)
    return HEADER.format(name=f"hand{fingers}", damping=0.05, armature=0.002) + body + FOOTER


def arms_with_hands() -> str:
    """Two 7-dof arms, each with a five-fingered hand on a 3-hinge wrist: 60 degrees of freedom."""
    bodies = '    <body name="base" pos="0 0 0.5">\n      <geom type="box" size="0.1 0.4 0.1"/>\n'
    for side, y in (("r_", -0.3), ("l_", 0.3)):
        bodies += _arm_bodies(7, side, "      ", _hand(side, 5), base_pos=(0, y, 0.1))
    bodies += "    </body>\n"
    return HEADER.format(name="arms_with_hands", damping=0.1, armature=0.01) + bodies + FOOTER


def random_chain(links: int, seed: int = 0) -> str:
    """A serial chain of `links` bodies, hinges about random axes through random anchors (3-D: no common plane)."""
    rng = np.random.default_rng(seed)
    opening, closing = [], []
    for k in range(links):
        pad = "    " + "  " * k
        pos = (0, 0, 1.0) if k == 0 else rng.uniform(-0.15, 0.15, 3) + (0, 0, -0.25)
        axis = rng.normal(size=3)
        anchor = rng.uniform(-0.05, 0.05, 3)
        moments = np.sort(rng.uniform(0.002, 0.01, 3))
        moments[2] = min(moments[2], 0.99 * (moments[0] + moments[1]))
        quat = rng.normal(size=4)
        quat /= np.linalg.norm(quat)
        opening.append(
            f'{pad}<body name="link{k}" pos="{_f(pos)}">\n'
            f'{pad}  <joint name="j{k}" type="hinge" axis="{_f(axis)}" pos="{_f(anchor)}"/>\n'
            f'{pad}  <inertial pos="{_f(rng.uniform(-0.05, 0.05, 3) + (0, 0, -0.12))}" mass="{rng.uniform(0.5, 2):.4g}"'
            f' diaginertia="{_f(moments)}" quat="{_f(quat)}"/>\n')
        closing.append(f"{pad}</body>\n")
    return (HEADER.format(name=f"chain{links}", damping=0.0, armature=0.0) + "".join(opening)
            + "".join(reversed(closing)) + FOOTER)


MODELS = {
    "humanoid (27 dof)": humanoid,
    "random chain, 8 links": lambda: random_chain(8, 8),
    "random chain, 32 links": lambda: random_chain(32, 32),
    "arm, 7 dof": lambda: arm(7),
    "hand on an arm, 30 dof": lambda: hand(5, 7),
    "two arms with hands, 60 dof": arms_with_hands,
}
