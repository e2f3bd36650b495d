"""MJCF -> rbody: ``from_mjcf(source)`` reads a MuJoCo model into a Scene that rbody runs natively.

``layout_from_mjcf(source)`` does the reading and returns an MJCFModel (the Layout, gravity, time step,
integrator, initial state in MuJoCo's qpos/qvel layout, keyframes, declared joint limits, notes);
``from_mjcf`` hands it to ``Scene.from_layout`` (the general engine). `source` is a path or an XML string.
Every error is an MJCFError (a ValueError) naming the file, the line and the element, raised before any run.
The package: document.py reads the XML (lines kept, includes expanded), frames.py forms MuJoCo's frames,
geoms.py its mass properties, overlap.py decides whether geoms of one body overlap; this module assembles.

Supported (read as MuJoCo's compiler reads them; the compiled masses, centres of mass and inertia tensors
equal MuJoCo's body_mass, body_ipos and body_inertia/body_iquat to round-off):

- ``<include file>`` (relative to the including file), ``<default>`` classes (nested, inherited), ``class``
  and ``childclass``;
- ``<compiler>``: angle (degree, MJCF's default, or radian), eulerseq, inertiafromgeom (true, false,
  auto), inertiagrouprange, autolimits, meshdir, assetdir, strippath, fitaabb; balanceinertia only where no
  body needs it;
- frames: pos and every orientation (quat, axisangle, euler, xyaxes, zaxis; at most one per element),
  geom ``fromto``;
- ``<inertial>``: pos, orientation, mass, diaginertia or fullinertia;
- mass and inertia from geoms: sphere, capsule, cylinder, box, ellipsoid, mesh; mass or density;
  shellinertia; several geoms summed about the body's centre of mass, as MuJoCo does;
- ``<mesh file>`` assets (STL, OBJ, any format trimesh reads) with scale, refpos, refquat and inertia
  legacy (MuJoCo's default), exact, convex or shell; vertices are rounded to float32 as MuJoCo does;
  meshdir/assetdir relative to the model file's folder (the working folder for an XML string); the Shape
  holds the mesh file's absolute path (a scale applies to the mass properties only, noted);
- a primitive given a mesh (type sphere, capsule, cylinder, ellipsoid or box with mesh=): fitted to the mesh as
  MuJoCo fits it (geoms.fitted_size: the equivalent inertia box, or with fitaabb the vertices' box; fitscale),
  placed in the mesh's principal frame; from then on it is that primitive (mass, contacts);
- principal axes as MuJoCo's compiler finds them (its Jacobi solver, geoms.mujoco_principal): for a body
  of several geoms, a fullinertia or a mesh, MuJoCo's compiled tensor can differ from the exact one by
  more than round-off (a small rotation left undone); rbody takes MuJoCo's, noting any difference
  beyond 1e-12, so that both engines run the same bodies;
- joints hinge, slide, ball, free and ``<freejoint>``, with pos, axis, ref, damping, stiffness,
  springref, armature, range, limited, margin and frictionloss, and ``<equality>`` connect, weld, joint and tendon,
  held rigidly (rbody.mjcf.constraints: MuJoCo's defaults, active flags, what replaces solref and solimp, and
  the ``<custom>`` numeric that gives a limit its restitution); springdamper (MuJoCo's stiffness and damping from
  a time constant and damping ratio at the reference pose, hinge and slide); actuatorgravcomp,
  actuatorfrcrange/actuatorfrclimited;
- body gravcomp (a force against gravity on a fraction of the body's weight, passive or through the joints'
  actuators); compiler settotalmass (every mass and inertia scaled as MuJoCo's mj_setTotalmass);
- ``<frame>``: nested, with pos/orientation and childclass, around bodies, geoms, sites, joints' bodies;
- actuators (rbody.mjcf.actuators): <general>, <motor>, <position> (kp, kv, dampratio, timeconst, inheritrange),
  <velocity>, <intvelocity>, <damper>, with their one-default-per-class rule, ctrl/force/act ranges, actearly,
  gear, through a joint, a tendon or a site (no refsite); <fixed> and <spatial> tendons (through sites, no
  wrapping) with stiffness, damping and springlength, range (limited) and frictionloss held rigidly;
- ``<option>``: timestep, gravity (along -z: rbody's scenes have gravity -g z), integrator (the scene's
  file_method: Euler -> "mujoco_euler", implicitfast, implicit, RK4 -> "rk4"), density, viscosity and wind
  (fluid forces: MuJoCo's inertia-box model, or its ellipsoid model on geoms with fluidshape="ellipsoid",
  rbody.mjcf.fluid), actuatorgroupdisable; flags contact, constraint, equality, limit, frictionloss, gravity
  (disable: g = 0), spring and damper (disable: the joints' and tendons' stiffness or damping become 0),
  actuation (disable: actuators apply no force), clampctrl (disable: controls are not clamped), each noted;
- ``<keyframe>``: qpos, qvel, act and ctrl of a key chosen by name or index (``keyframe=``);
- a world-fixed height field (<hfield> with nrow, ncol, size and elevation, or from a PNG or binary file read by
  MuJoCo's compiler), as a "hfield" Shape
  that collides (rbody.engine.contacts.terrain);
- one rbody Body per MJCF body, with its name (an unnamed body is called ``body<id>``, id as MuJoCo's;
  unnamed joints ``<body>_joint<i>``, geoms ``<body>_geom<i>``), except that a body with neither mass
  nor joints (a pure frame) is folded into its parent, its children and shapes moved there (noted).

Cheap loading: a mesh's mass properties are computed only where they count (a body with an explicit <inertial>
under inertiafromgeom="auto" keeps only the mesh's path).

Ignored, and named in ``MJCFModel.notes`` (``scene.import_notes``): light, camera, site (but a tendon's or
actuator's site is read), material, texture, skin, skybox, visual, statistic, size, custom, geoms' appearance
(rgba, material, group), sensors, contact parameters of geoms that cannot collide, solver settings (only
constraints use them); overlapping geoms of a body welded to the world (it never moves: their mass is unused).

Contacts: the geom pairs MuJoCo's broad phase keeps (different bodies, not welded together nor parent
and child, no <exclude>, contype/conaffinity matching, the contact flag on) become rbody Contacts with
MuJoCo's friction and condim combination and rbody's restitution numerics (rbody.mjcf.contacts), held
rigidly by the constraint layer (condim 4 and 6: torsional and rolling friction, each its own Coulomb law). Explicit
<pair>s too, with their own friction and condim, in place of the dynamic pair of their geoms.

Refused (MJCFError, naming the element, its file and line): contacts rbody does not compute (an sdf geom; a
height field on a body) while the contact flag is on (set
contype="0" conaffinity="0" on the geoms, or <flag contact="disable"/>); flex equalities; tendon armature, wrapping
tendons (geoms, pulleys); actuators that rbody does not model (muscle, cylinder, adhesion, pid, dcmotor,
orientation; user dynamics, gains or biases; actuator damping or armature; body, slider-crank or refsite
transmissions; see rbody.mjcf.actuators); springdamper on a ball or free joint; fluidshape="ellipsoid" on a mesh
or plane geom; a height field on a moving body or from a file, flexes, composites, plugins, <replicate>, <attach>; gravity not
along -z; stiffness on a ball joint; boundmass, boundinertia, fusestatic, alignfree; a body with a joint but no
mass; an orientation given twice; unknown elements or attributes; geoms of one moving body that overlap, which
MuJoCo would count twice (``overlapping_geoms="sum"`` sums them as MuJoCo does).

Read as strictly as MuJoCo reads it (so that rbody accepts no file MuJoCo refuses: tests/rbody/test_mjcf_fuzz.py):
numbers by C's strtod and strtol, as MuJoCo's StringToVector (rbody.mjcf.grammar: no '1_0', no non-ASCII digits,
hex accepted, overflow refused, an int attribute such as contype, conaffinity, condim, group or
inertiagrouprange refused when fractional), every attribute of the elements read or ignored (sites, cameras,
lights included) checked against MuJoCo's schema types, counts and keywords, and a blank number read as absent;
child elements of <joint>, <freejoint>, <geom>, <inertial>, <site>, <camera>, <light> refused; one <joint>,
<geom>, ... per <default> class and one <flag> per <option>; a file included twice, or an include with children,
or an included file without elements; a mocap body that is not a fixed child of the world; condim other than
1, 3, 4, 6; a plane's third size <= 0; a ball joint's range not starting at 0; repeated site, camera or light
names; nesting beyond MuJoCo's XML parser's depth (tinyxml2: 496 nested bodies load, 497 do not; no recursion
here). A file's bytes are decoded as MuJoCo takes them (up to a NUL; bytes that are not UTF-8 kept as bytes:
a Latin-1 comment loads, a Latin-1 byte in a number is a bad number). MuJoCo's inf and nan are refused here (every
number rbody reads must be finite). A message never echoes a long value whole (MJCFError cuts it).

Joint limits: a limited joint's range (less its margin) is its Joint.range, also listed in ``MJCFModel.limits``
and ``MJCFScene.limits`` (joint name -> (lo, hi) [rad | m]; ball: (0, largest rotation angle)). A native run
holds every limit rigidly (rbody.engine.constraints); a model whose initial state lies outside a range starts
there, and the limit puts it back at once (the run's first event).

Initial state: the model's reference (qpos0: hinge and slide at ref, balls at identity, free bodies at
their pos/quat; at rest), a keyframe's (``keyframe=``), or the qpos0/qvel0 arguments, in MuJoCo's layout
(free joints: world velocity of the body origin, then body-frame angular velocity). Quaternions are made
unit (noted), as MuJoCo uses them.
"""

from __future__ import annotations

import dataclasses
import math
import os
from dataclasses import dataclass, field
from pathlib import Path
from typing import Mapping

import numpy as np

from rbody.inertia import Inertia
from rbody.mjcf.document import (Element, MJCFError, boolean, choice, expand_includes, integer, integers, number,
                                 numbers, read_source)
from rbody.mjcf.constraints import (EQUALITY_ATTRS, Frames, equality_from, equality_kind_error, read_numerics,
                                    restitution_of, softness_note, unknown_restitutions)
from rbody.mjcf.grammar import ATTRIBUTES, CHILDLESS, NUMERIC, UNIQUE_CHILDREN, check_value
from rbody.mjcf.frames import MJ_EPS, frame_to_quat, normalize, quat_matrix, quat_product, z_to_quat
from rbody.mjcf.geoms import (MESH_INERTIA_MODES, GeomMass, MeshMass, fitted_size, mesh_mass, mujoco_principal,
                              primitive_moments, primitive_volume, principal_tensor, sum_geoms)
from rbody.layout import WORLD, Body, Joint, Layout, Shape
from rbody.mjcf import actuators as mjcf_actuators
from rbody.scene import TreeScene

DEFAULT_T_END = 1.0        # [s] duration of a scene read from MJCF when t_end is not given
OVERLAP_CHOICES = ("refuse", "sum")
INTEGRATORS = {"Euler": "Euler", "RK4": "RK4", "implicit": "implicit", "implicitfast": "implicitfast"}
FILE_METHODS = {"Euler": "mujoco_euler", "RK4": "rk4", "implicit": "implicit", "implicitfast": "implicitfast"}
ORIENTATIONS = ("quat", "axisangle", "xyaxes", "zaxis", "euler")
PRINCIPAL_NOTE_RTOL = 1e-12  # a tensor MuJoCo's eigen-solver moves by more than this (relative) is noted
MJ_MINVAL = 1e-15            # MuJoCo's mjMINVAL: the floor of its divisions (mj_setTotalmass, AutoSpringDamper)


# ----- the reader --------------------------------------------------------------------------------------

_VISUAL_ELEMENTS = ("light", "camera", "site")
_VISUAL_ATTRS = {"site": set(ATTRIBUTES["site"]) | {"name", "class", "material"},
                 "camera": set(ATTRIBUTES["camera"]) | {"name", "class", "target"},
                 "light": set(ATTRIBUTES["light"]) | {"name", "class", "target", "texture"}}
_REFUSED_IN_BODY = {
    "replicate": "<replicate> is not supported: write the copies out",
    "attach": "<attach> (model composition) is not supported",
    "composite": "composites are not supported (they make many bodies, joints and constraints)",
    "flexcomp": "flexes are not supported (deformable bodies)",
    "plugin": "plugins are not supported (their physics is unknown to rbody)",
}
_BODY_ATTRS = {"name", "childclass", "pos", "quat", "axisangle", "xyaxes", "zaxis", "euler", "mocap", "gravcomp",
               "sleep", "simple", "user"}
_INERTIAL_ATTRS = {"pos", "quat", "mass", "diaginertia", "axisangle", "xyaxes", "zaxis", "euler", "fullinertia"}
_JOINT_ATTRS = {"name", "class", "type", "group", "pos", "axis", "springdamper", "limited", "actuatorfrclimited",
                "solreflimit", "solimplimit", "solreffriction", "solimpfriction", "stiffness", "range",
                "actuatorfrcrange", "actuatorgravcomp", "margin", "ref", "springref", "armature", "damping",
                "frictionloss", "user"}
_PAIR_ATTRS = {"name", "class", "geom1", "geom2", "condim", "friction", "solref", "solreffriction", "solimp", "gap",
               "margin"}
_GEOM_ATTRS = {"name", "class", "type", "contype", "conaffinity", "condim", "group", "priority", "size", "material",
               "friction", "mass", "density", "shellinertia", "solmix", "solref", "solimp", "margin", "gap",
               "surfacevel", "adhesion", "fromto", "pos", "quat", "axisangle", "xyaxes", "zaxis", "euler", "hfield",
               "mesh", "fitscale", "rgba", "fluidshape", "fluidcoef", "user"}
_HFIELD_ATTRS = {"name", "content_type", "file", "nrow", "ncol", "size", "elevation"}
_MESH_ATTRS = {"name", "class", "content_type", "file", "vertex", "normal", "texcoord", "face", "refpos", "refquat",
               "scale", "smoothnormal", "maxhullvert", "inertia", "builtin", "params", "material"}
_COMPILER_ATTRS = {"autolimits", "boundmass", "boundinertia", "settotalmass", "balanceinertia", "strippath",
                   "coordinate", "angle", "fitaabb", "eulerseq", "meshdir", "texturedir", "discardvisual",
                   "usethread", "fusestatic", "inertiafromgeom", "inertiagrouprange", "saveinertial", "assetdir",
                   "alignfree", "conflict"}
_OPTION_ATTRS = {"timestep", "impratio", "tolerance", "ls_tolerance", "noslip_tolerance", "ccd_tolerance",
                 "sleep_tolerance", "gravity", "wind", "magnetic", "density", "viscosity", "o_margin", "o_solref",
                 "o_solimp", "o_friction", "integrator", "cone", "jacobian", "solver", "iterations",
                 "ls_iterations", "noslip_iterations", "ccd_iterations", "sdf_iterations", "sdf_initpoints",
                 "actuatorgroupdisable"}
_FLAG_ATTRS = {"constraint", "equality", "frictionloss", "limit", "contact", "spring", "damper", "gravity",
               "clampctrl", "warmstart", "filterparent", "actuation", "refsafe", "sensor", "midphase", "eulerdamp",
               "autoreset", "nativeccd", "island", "multiccd", "override", "energy", "fwdinv", "invdiscrete",
               "sleep", "diagexact"}
_ACTUATORS = ("general", "motor", "position", "velocity", "intvelocity", "orientation", "pid", "damper", "cylinder",
              "muscle", "adhesion", "dcmotor")
_DEFAULT_CHILDREN = {"mesh", "material", "joint", "geom", "site", "camera", "light", "pair", "equality", "tendon",
                     *_ACTUATORS}
_GEOM_KINDS = ("plane", "hfield", "sphere", "capsule", "ellipsoid", "cylinder", "box", "mesh", "sdf")
_SIZES = {"sphere": 1, "capsule": 2, "cylinder": 2, "ellipsoid": 3, "box": 3, "plane": 3}


@dataclass
class _Geom:
    element: Element
    attrib: dict
    name: str
    kind: str
    size: np.ndarray
    pos: np.ndarray
    quat: np.ndarray
    contype: int
    conaffinity: int
    group: int
    mesh: str | None = None
    mass: GeomMass | None = None
    ellipsoid: bool = False     # fluidshape="ellipsoid"
    axes: np.ndarray | None = None  # its principal axes (quat, body frame), as MuJoCo's compiler holds them


@dataclass
class _Body:
    element: Element
    name: str
    index: int                    # MuJoCo's body id (world = 0)
    parent: "_Body | None"
    pos: np.ndarray
    quat: np.ndarray
    joints: list = field(default_factory=list)      # (element, attrib)
    geoms: list = field(default_factory=list)       # _Geom
    inertial: Element | None = None
    mass: float = 0.0
    com: np.ndarray = field(default_factory=lambda: np.zeros(3))
    tensor: np.ndarray = field(default_factory=lambda: np.zeros((3, 3)))
    weld: int = 0
    gravcomp: float = 0.0
    axes: np.ndarray = field(default_factory=lambda: np.array([1.0, 0.0, 0.0, 0.0]))  # principal axes (body_iquat)

    @property
    def dofs(self) -> int:
        return sum({"free": 6, "ball": 3}.get(kind, 1) for kind in self.joint_kinds)

    @property
    def joint_kinds(self) -> list[str]:
        return [attrib.get("type", "hinge") if element.tag == "joint" else "free" for element, attrib in self.joints]


@dataclass(frozen=True)
class MJCFModel:
    """What layout_from_mjcf read: everything Scene.from_layout needs, and what was left out.

    layout:     the bodies, joints, fixed shapes and the contacts MuJoCo's rules keep (rbody.mjcf.contacts)
    name:       the model's name (<mujoco model>)
    gravity:    magnitude g along -z [m/s^2]
    timestep:   option timestep [s] (MuJoCo's default 0.002 when not given); integrator: MuJoCo's name
    qpos0, qvel0: (nq,), (nv,) the initial state in MuJoCo's layout (the keyframe's, or the arguments')
    keyframes:  name (or "key<i>" when unnamed) -> (qpos (nq,), qvel (nv,)), in document order
    limits:     joint name -> (lo, hi) declared range [rad | m] (ball: (0, largest angle) [rad])
    notes:      what was ignored, one line each
    source:     the file read, or "<string>"
    act0, ctrl0: (na,), (nu,) the chosen keyframe's activations and controls (zeros without one)
    """

    layout: Layout
    name: str
    gravity: float
    timestep: float
    integrator: str
    qpos0: np.ndarray
    qvel0: np.ndarray
    keyframes: dict
    limits: dict
    notes: tuple
    source: str
    act0: np.ndarray = field(default_factory=lambda: np.zeros(0))
    ctrl0: np.ndarray = field(default_factory=lambda: np.zeros(0))


def _hfield_elevation(element: Element, attrib: dict) -> np.ndarray:
    """A <hfield>'s nrow x ncol elevations given in the XML (elevation; none given: all 0), normalised to [0, 1] as
    MuJoCo's compiler does (less the least, over the range where it exceeds 1e-14), with row 0 at y = -size[1]:
    elevation lists its rows from y = +size[1] down, and MuJoCo's compiler reverses them."""
    nrow, ncol = integer(element, "nrow", attrib, 0), integer(element, "ncol", attrib, 0)
    if nrow < 2 or ncol < 2:
        raise element.error(f"nrow={nrow}, ncol={ncol}: a height field needs at least 2 of each")
    if "elevation" in attrib:
        data = numbers(element, "elevation", attrib)
        if data.size != nrow * ncol:
            raise element.error(f"elevation has {data.size} numbers: nrow x ncol = {nrow * ncol} expected "
                                "(MuJoCo: elevation data length must match nrow*ncol)")
        data = data.astype(np.float32).astype(float)  # MuJoCo keeps them as floats
    else:
        data = np.zeros(nrow * ncol)
    data = data - data.min()
    if data.max() > 1e-14:
        data = data / data.max()
    return data.reshape(nrow, ncol)[::-1].copy()  # elevation's last row at y = -size[1]


class _Reader:
    def __init__(self, root: Element, folder: Path | None, overlapping_geoms: str):
        self.root = root
        self.folder = folder
        self.overlapping_geoms = overlapping_geoms
        self.notes: list[str] = []
        self.noted: set[str] = set()
        self.classes: dict[str, dict[str, dict]] = {}
        self.class_parent: dict[str, str | None] = {}
        self.meshes: dict[str, tuple[Element, dict]] = {}
        self.hfields: dict[str, tuple[np.ndarray, np.ndarray]] = {}  # name -> (heights (nrow, ncol) in [0, 1], size)
        self.mesh_cache: dict[str, MeshMass] = {}
        self.hull_cache: dict[str, tuple] = {}                 # mesh name -> its convex hull's vertices
        self.colliding: set[str] = set()                       # the names of geoms in some contact pair
        self.bodies: list[_Body] = []
        self.world: _Body | None = None
        self.excluded: set[frozenset] = set()
        self.explicit_pairs: list = []  # (<pair> element, its attributes with its class's defaults)
        self.mesh_paths: dict[str, str] = {}                 # mesh name -> absolute file path
        self.plane_bodies: list[tuple[Element, _Body]] = []  # planes on bodies (only static ones may hold them)
        self.key_elements: list[Element] = []
        self.sites: dict[str, tuple[_Body, np.ndarray, np.ndarray]] = {}  # name -> (body, pos, quat in its frame)
        self.equality_elements: list[tuple[Element, dict]] = []
        self.numerics: dict[str, np.ndarray] = {}
        self.carriers: dict = {}
        self._nested_defaults: list[tuple[Element, str]] = []  # <default> classes still to read, with their parent
        self.visual_names: dict[str, set[str]] = {}               # names of sites, cameras, lights (each unique)
        self.actuator_defaults: dict[str, mjcf_actuators.ActuatorSpec] = {}   # class -> its one actuator default
        self.actuator_specs: list[tuple[str, mjcf_actuators.ActuatorSpec]] = []
        self.tendon_specs: list[tuple[str, mjcf_actuators.TendonSpec]] = []

    # ----- helpers -----

    def note(self, key: str, text: str) -> None:
        if key not in self.noted:
            self.noted.add(key)
            self.notes.append(text)

    def check_attrs(self, element: Element, known: set) -> None:
        """Unknown attributes refused; every attribute's value checked as MuJoCo reads it (rbody.mjcf.grammar: types,
        counts, keywords, also where rbody does not use the value), and a blank number dropped from the element (MuJoCo
        reads it as absent); child elements of an element that has none in MuJoCo's schema (joint, geom, inertial,
        site, camera, light, ...) refused, and a second child where MuJoCo allows one."""
        unknown = sorted(set(element.attrib) - known)
        if unknown:
            raise element.error(f"unknown attribute {unknown[0]!r} (MJCF's <{element.tag}> has {sorted(known)})")
        for name, value in list(element.attrib.items()):
            problem = check_value(element.tag, name, value)
            if problem:
                raise element.error(problem)
            if not value.strip(" \t\n\r") and ATTRIBUTES.get(element.tag, {}).get(name, ("",))[0] in NUMERIC:
                del element.attrib[name]  # MuJoCo reads a blank number as no attribute (a class default then holds)
        for tag in UNIQUE_CHILDREN.get(element.tag, ()):
            found = [child for child in element.children if child.tag == tag]
            if len(found) > 1:
                raise found[1].error(f"a second <{tag}> in <{element.tag}>: MJCF allows one")
            for child in found if tag == "lengthrange" else ():  # read by no one here, but checked as MuJoCo does
                self.check_attrs(child, set(ATTRIBUTES["lengthrange"]))
        if element.children and (element.tag in CHILDLESS or element.tag == "geom"):
            child = element.children[0]
            if element.tag == "geom" and child.tag == "plugin":
                raise child.error("plugins are not supported (their physics is unknown to rbody)")
            raise child.error(f"unknown element <{child.tag}> in <{element.tag}> (MJCF's <{element.tag}> has no child "
                              "elements)")

    def attrs(self, element: Element, tag: str, childclass: str | None) -> dict:
        """The element's attributes over its class's defaults (class, else the body's childclass, else main)."""
        name = element.attrib.get("class", childclass or "main")
        if name not in self.classes:
            raise element.error(f"class={name!r} is not a <default> class of the model")
        merged = dict(self.classes[name].get(tag, {}))
        own = {k: v for k, v in element.attrib.items() if k != "class"}
        if any(key in own for key in ORIENTATIONS):  # the element's own orientation replaces the default's
            merged = {k: v for k, v in merged.items() if k not in ORIENTATIONS}
        merged.update(own)
        return merged

    def orientation(self, element: Element, attrib: dict) -> np.ndarray:
        """(4,) unit quaternion from quat, axisangle, xyaxes, zaxis or euler (MuJoCo's ResolveOrientation)."""
        given = [key for key in ORIENTATIONS if key in attrib]
        if len(given) > 1:
            raise element.error(f"orientation given twice ({' and '.join(given)}): give one of {ORIENTATIONS}")
        if not given:
            return np.array([1.0, 0.0, 0.0, 0.0])
        key = given[0]
        if key == "quat":
            quat, norm = normalize(numbers(element, key, attrib, 4))
            if norm == 0:
                raise element.error(f"quat={attrib[key]!r}: a quaternion must be non-zero")
            return quat
        if key == "axisangle":
            values = numbers(element, key, attrib, 4)
            angle = values[3] / 180.0 * math.pi if self.degree else values[3]
            axis, norm = normalize(values[:3])
            if norm < MJ_EPS:
                raise element.error(f"axisangle={attrib[key]!r}: the axis is too small")
            return np.concatenate([[math.cos(angle / 2)], math.sin(angle / 2) * axis])
        if key == "xyaxes":
            values = numbers(element, key, attrib, 6)
            x, nx = normalize(values[:3])
            if nx < MJ_EPS:
                raise element.error(f"xyaxes={attrib[key]!r}: the x axis is too small")
            y = values[3:] - x * float(x @ values[3:])
            y, ny = normalize(y)
            z, nz = normalize(np.cross(x, y))
            if ny < MJ_EPS or nz < MJ_EPS:
                raise element.error(f"xyaxes={attrib[key]!r}: the y axis is parallel to the x axis or too small")
            return frame_to_quat(x, y, z)
        if key == "zaxis":
            z, norm = normalize(numbers(element, key, attrib, 3))
            if norm < MJ_EPS:
                raise element.error(f"zaxis={attrib[key]!r}: the axis is too small")
            return z_to_quat(z)
        angles = numbers(element, key, attrib, 3)
        if self.degree:
            angles = angles / 180.0 * math.pi
        quat = np.array([1.0, 0.0, 0.0, 0.0])
        for angle, axis in zip(angles, self.eulerseq):
            turn = np.array([math.cos(angle / 2), 0.0, 0.0, 0.0])
            turn[1 + "xyz".index(axis.lower())] = math.sin(angle / 2)
            quat = quat_product(quat, turn) if axis.islower() else quat_product(turn, quat)
        return normalize(quat)[0]

    # ----- sections -----

    def read(self) -> None:
        root = self.root
        if root.tag != "mujoco":
            raise root.error("the root element of an MJCF document must be <mujoco>")
        self.check_attrs(root, {"model"})
        self.name = root.attrib.get("model", "model") or "model"
        sections: dict[str, list[Element]] = {}
        for child in root.children:
            sections.setdefault(child.tag, []).append(child)
        known = {"compiler", "option", "size", "statistic", "visual", "default", "custom", "asset", "worldbody",
                 "contact", "equality", "tendon", "actuator", "sensor", "keyframe", "extension", "deformable"}
        for child in root.children:
            if child.tag not in known:
                raise child.error(f"unknown element <{child.tag}> (MJCF's sections are {sorted(known)})")
        for tag in ("extension", "deformable"):
            for child in sections.get(tag, []):
                raise child.error(f"<{tag}> is not supported (plugins and deformable bodies change the dynamics "
                                  "in ways rbody does not model)")
        self.read_compiler(sections.get("compiler", []))
        self.read_option(sections.get("option", []))
        self.numerics = read_numerics(sections.get("custom", []))  # rbody's restitution (rbody.mjcf.constraints)
        self.nkey = 0  # <size nkey>: MuJoCo allocates max(nkey, <key> count) keyframes, the extra ones at qpos0
        for element in sections.get("size", []):
            self.nkey = max(self.nkey, integer(element, "nkey", element.attrib, 0))  # MuJoCo takes -1 as none
        for tag in ("size", "statistic", "visual", "custom"):
            if tag in sections:
                self.note(tag, f"<{tag}> ignored (no effect on the dynamics rbody runs)" if tag not in ("custom", "size")
                          else "<size> ignored but for nkey (the keyframes MuJoCo allocates)" if tag == "size" else
                          "<custom> ignored (except the numerics rbody.restitution[.JOINT], rbody.mjcf.constraints)")
        self.classes = {"main": {}}
        for element in sections.get("default", []):
            self.read_default(element, None, top=True)
        for element in sections.get("asset", []):
            self.read_assets(element)
        world = Element("worldbody", {}, self.root.file, self.root.line)
        for element in sections.get("worldbody", []):
            self.check_attrs(element, set())
            world.children.extend(element.children)
        self.world = _Body(world, WORLD, 0, None, np.zeros(3), np.array([1.0, 0.0, 0.0, 0.0]))
        self.read_body_contents(self.world, None)
        for element in sections.get("contact", []):
            self.read_contact(element)
        for element in sections.get("equality", []):
            self.read_equality(element)
        for element in sections.get("tendon", []):
            self.read_tendons(element)
        for element in sections.get("actuator", []):
            self.read_actuators(element)
        if "sensor" in sections:
            self.note("sensor", "<sensor> ignored (sensors only measure)")
        self.key_elements = [key for element in sections.get("keyframe", []) for key in element.children]
        for element in sections.get("keyframe", []):
            self.check_attrs(element, set())
            for key in element.children:
                if key.tag != "key":
                    raise key.error("unknown element in <keyframe> (expected <key>)")
                self.check_attrs(key, {"name", "time", "qpos", "qvel", "act", "mpos", "mquat", "ctrl"})

    def read_compiler(self, elements: list[Element]) -> None:
        attrib: dict = {}
        for element in elements:
            self.check_attrs(element, _COMPILER_ATTRS)
            attrib.update(element.attrib)
            for child in element.children:
                if child.tag != "lengthrange":
                    raise child.error("unknown element in <compiler>")
        where = elements[-1] if elements else self.root
        self.degree = choice(where, "angle", attrib, ("degree", "radian"), "degree") == "degree"
        self.eulerseq = attrib.get("eulerseq", "xyz")
        if len(self.eulerseq) != 3 or any(c not in "xyzXYZ" for c in self.eulerseq):
            raise where.error(f"eulerseq={self.eulerseq!r}: expected three of x, y, z, X, Y, Z")
        self.inertiafromgeom = choice(where, "inertiafromgeom", attrib, ("true", "false", "auto"), "auto")
        self.group_range = (0, 5)
        if "inertiagrouprange" in attrib:
            low, high = integers(where, "inertiagrouprange", attrib, 2)
            self.group_range = (low, high)
        self.autolimits = boolean(where, "autolimits", attrib, True)
        self.balanceinertia = boolean(where, "balanceinertia", attrib, False)
        self.fitaabb = boolean(where, "fitaabb", attrib, False)  # a fitted primitive: by the mesh's box, not inertia
        self.strippath = boolean(where, "strippath", attrib, False)
        base = self.folder if self.folder is not None else Path.cwd()
        assetdir = attrib.get("assetdir", "")
        self.meshdir = base / attrib.get("meshdir", assetdir)
        for key, default in (("boundmass", 0.0), ("boundinertia", 0.0)):
            if number(where, key, attrib, default) != default:
                raise where.error(f"{key} is not supported: it changes bodies' masses; give the masses explicitly")
        self.settotalmass = number(where, "settotalmass", attrib, -1.0)
        if boolean(where, "fusestatic", attrib, False):
            raise where.error("fusestatic is not supported: rbody keeps one body per MJCF body")
        if boolean(where, "alignfree", attrib, False):
            raise where.error("alignfree is not supported: it moves free bodies' frames to their inertial frames")
        if attrib.get("coordinate", "local") != "local":
            raise where.error("coordinate must be 'local'")

    def read_option(self, elements: list[Element]) -> None:
        attrib: dict = {}
        flags: dict = {}
        for element in elements:
            self.check_attrs(element, _OPTION_ATTRS)
            attrib.update(element.attrib)
            for child in element.children:
                if child.tag != "flag":
                    raise child.error("unknown element in <option> (expected <flag>)")
                self.check_attrs(child, _FLAG_ATTRS)
                for key, value in child.attrib.items():
                    if value not in ("enable", "disable"):
                        raise child.error(f"{key}={value!r}: expected 'enable' or 'disable'")
                flags.update(child.attrib)
        where = elements[-1] if elements else self.root
        self.option_element = where
        self.timestep = number(where, "timestep", attrib, 0.002)
        if not self.timestep > 0:
            raise where.error(f"timestep={self.timestep!r}: must be > 0 [s]")
        self.integrator = choice(where, "integrator", attrib, tuple(INTEGRATORS), "Euler")
        gravity = numbers(where, "gravity", attrib, 3) if "gravity" in attrib else np.array([0.0, 0.0, -9.81])
        self.density, self.viscosity = number(where, "density", attrib, 0.0), number(where, "viscosity", attrib, 0.0)
        for key in ("density", "viscosity"):
            if getattr(self, key) < 0:
                raise where.error(f"{key}={attrib[key]!r}: must be >= 0")
        self.wind = numbers(where, "wind", attrib, 3) if "wind" in attrib else np.zeros(3)
        self.disabled_groups = set()
        if "actuatorgroupdisable" in attrib:
            self.disabled_groups = {int(g) for g in numbers(where, "actuatorgroupdisable", attrib)}
        ignored = sorted(set(attrib) - {"timestep", "integrator", "gravity", "density", "viscosity", "wind",
                                        "actuatorgroupdisable"})
        if ignored:
            self.note("option", f"<option> {', '.join(ignored)} ignored (constraint-solver and sensor settings; "
                                "the model has no active constraint)")
        self.flags = {key: value == "enable" for key, value in flags.items()}

        def on(name: str, default: bool = True) -> bool:
            return self.flags.get(name, default)

        self.constraints_on = on("constraint")
        self.contacts_on = self.constraints_on and on("contact")
        # <flag override="enable">: o_margin replaces every contact's margin (MuJoCo's mj_assignMargin)
        self.override_margin = number(where, "o_margin", attrib, 0.0) if on("override", False) else None
        self.equality_on = self.constraints_on and on("equality")
        self.limits_on = self.constraints_on and on("limit")
        self.frictionloss_on = self.constraints_on and on("frictionloss")
        self.spring_on, self.damper_on = on("spring"), on("damper")
        self.actuation_on, self.clampctrl_on = on("actuation"), on("clampctrl")
        if not on("eulerdamp") and self.integrator == "Euler":
            self.note("eulerdamp", "<flag eulerdamp=\"disable\"/>: MuJoCo's Euler then takes the joints' damping "
                                   "explicitly; rbody's mujoco_euler keeps it implicit (a difference at O(h) where "
                                   "joints are damped)")
        self.filterparent = on("filterparent")
        if not on("gravity"):
            gravity = np.zeros(3)
            self.note("gravity", "gravity off (<flag gravity=\"disable\"/>): g = 0")
        if gravity[0] != 0 or gravity[1] != 0 or gravity[2] > 0:
            raise where.error(f"gravity={' '.join(map(repr, gravity.tolist()))}: rbody's scenes have gravity along "
                              "-z (0 0 -g); rotate the model so that gravity points down z")
        self.gravity = float(-gravity[2]) + 0.0

    def read_default(self, element: Element, parent: str | None, top: bool = False) -> None:
        self.check_attrs(element, {"class"})
        name = element.attrib.get("class", "main" if top else None)
        if name is None:
            raise element.error("a nested <default> needs a class name")
        if name in self.classes and not (top and name == "main"):
            raise element.error(f"class {name!r} is defined twice")
        values = {tag: dict(attrs) for tag, attrs in self.classes.get(parent, {}).items()} if parent else {}
        if top and name == "main":
            values = self.classes.get("main", {})
        seen: set[str] = set()
        inherited = self.actuator_defaults.get(parent if parent else "main")
        actuator = inherited.copy() if inherited is not None else mjcf_actuators.ActuatorSpec()
        for child in element.children:
            if child.tag == "default":
                continue
            if child.tag not in _DEFAULT_CHILDREN:
                raise child.error(f"unknown element <{child.tag}> in <default>")
            if child.tag in _ACTUATORS:  # MuJoCo: every actuator element of a class writes its one default
                mjcf_actuators.apply_actuator(actuator, child, child.attrib)
                continue
            if child.tag in seen:  # MuJoCo: "Schema violation: unique element found 2 times" (not a merge)
                raise child.error(f"a second <{child.tag}> in <default class={name!r}>: a class holds at most one "
                                  f"<{child.tag}> (merge their attributes into one)")
            seen.add(child.tag)
            known = {"joint": _JOINT_ATTRS, "geom": _GEOM_ATTRS, "mesh": _MESH_ATTRS, **_VISUAL_ATTRS}.get(child.tag)
            if known is not None:
                self.check_attrs(child, known - {"name", "class"})
            values.setdefault(child.tag, {}).update(child.attrib)
        self.classes[name] = values
        self.actuator_defaults[name] = actuator
        for child in reversed([c for c in element.children if c.tag == "default"]):
            self._nested_defaults.append((child, name))
        if top:  # the nested classes, depth first through an explicit stack (no recursion)
            while self._nested_defaults:
                child, parent_name = self._nested_defaults.pop()
                self.read_default(child, parent_name)

    def read_hfield(self, element: Element) -> None:
        """A <hfield> asset: its elevations in [0, 1] as MuJoCo's compiler keeps them, row 0 at y = -size[1] (given
        in the XML: _hfield_elevation; a PNG or MuJoCo's binary file, found in meshdir as MuJoCo looks for it:
        _hfield_file), and its size (sx, sy, sz, base) [m], all > 0."""
        self.check_attrs(element, _HFIELD_ATTRS)
        attrib = element.attrib
        name = attrib.get("name")
        if not name:
            raise element.error("a <hfield> needs a name")
        if name in self.hfields:
            raise element.error(f"two height fields are called {name!r}")
        size = numbers(element, "size", attrib, 4) if "size" in attrib else np.zeros(4)
        if not np.all(size > 0):
            raise element.error(f"size={attrib.get('size', '')!r}: a height field needs 4 sizes > 0 (MuJoCo: size "
                                "parameter is not positive in hfield)")
        if "file" in attrib:
            if "elevation" in attrib:
                raise element.error(f"file={attrib['file']!r} and elevation: give one of them")
            heights = self._hfield_file(element, attrib)
        else:
            heights = _hfield_elevation(element, attrib)
        self.hfields[name] = (heights, size)
        self.note("hfield", "height fields: world-fixed terrain, collided by its triangles' faces and convex edges "
                            "(rbody.engine.contacts.terrain)")

    def asset_file(self, element: Element, file: str, kind: str) -> Path:
        """The absolute path of a mesh's or height field's `file` (kind names it), where MuJoCo looks for it: in
        meshdir, its folders stripped under strippath; a file that does not exist is refused naming it."""
        if self.strippath:
            file = os.path.basename(file)
        path = (self.meshdir / file).resolve()
        if not path.is_file():
            raise element.error(f"{kind} file {str(path)!r} does not exist")
        return path

    def _hfield_file(self, element: Element, attrib: dict) -> np.ndarray:
        """The elevations (nrow, ncol) in [0, 1], row 0 at y = -size[1], of a <hfield>'s file as MuJoCo's compiler
        reads and normalises them (a PNG's rows from its top at y = +size[1], its pixels' grey levels; MuJoCo's
        binary: int32 nrow, int32 ncol, then nrow x ncol float32 from y = -size[1]): the asset alone compiled by
        MuJoCo, whose reading is then the same to the bit. A missing file, or one MuJoCo cannot read, is refused
        naming it."""
        import mujoco
        from xml.sax.saxutils import quoteattr

        path = self.asset_file(element, attrib["file"], "height field")
        given = {key: attrib[key] for key in ("content_type", "nrow", "ncol") if key in attrib}
        attrs = " ".join(f"{key}={quoteattr(value)}" for key, value in {**given, "file": str(path)}.items())
        xml = (f'<mujoco><asset><hfield name="field" size="1 1 1 1" {attrs}/></asset><worldbody>'
               '<geom type="hfield" hfield="field"/></worldbody></mujoco>')
        try:
            model = mujoco.MjModel.from_xml_string(xml)
        except ValueError as error:
            message = str(error).splitlines()[0].removeprefix("Error: ")
            raise element.error(f"height field file {str(path)!r}: MuJoCo's compiler cannot read it ({message})") \
                from None
        nrow, ncol = int(model.hfield_nrow[0]), int(model.hfield_ncol[0])
        if nrow < 2 or ncol < 2:
            raise element.error(f"height field file {str(path)!r} holds {nrow} x {ncol} elevations: a height "
                                "field needs at least 2 of each")
        return np.array(model.hfield_data, dtype=float).reshape(nrow, ncol)

    def read_assets(self, element: Element) -> None:
        self.check_attrs(element, set())
        for child in element.children:
            if child.tag == "mesh":
                self.check_attrs(child, _MESH_ATTRS)
                attrib = self.attrs(child, "mesh", None)
                name = attrib.get("name")
                if name is None:
                    if "file" not in attrib:
                        raise child.error("a mesh needs a name or a file")
                    name = Path(attrib["file"]).stem  # MuJoCo names an unnamed mesh after its file
                if name in self.meshes:
                    raise child.error(f"two meshes are called {name!r}")
                self.meshes[name] = (child, attrib)
            elif child.tag in ("texture", "material", "skin"):
                self.note(child.tag, f"<{child.tag}> assets ignored (appearance only)")
            elif child.tag == "hfield":
                self.read_hfield(child)
            elif child.tag == "model":
                raise child.error("<model> assets (model composition) are not supported")
            else:
                raise child.error(f"unknown element <{child.tag}> in <asset>")

    # ----- bodies -----

    def read_body_contents(self, body: _Body, childclass: str | None) -> None:
        """The contents of `body` and of every body below it, depth first (MuJoCo's body order), through an explicit
        stack: no recursion, however deep the tree (MuJoCo reads 496 nested bodies)."""
        pending: list[tuple[Element, _Body, str | None, tuple | None]] = []
        self.read_children(body, childclass, pending)
        while pending:
            element, parent, inherited, frame = pending.pop()
            child, classname = self.read_body(element, parent, inherited, frame)
            self.read_children(child, classname, pending)
            self.check_mocap(child)

    def read_children(self, body: _Body, childclass: str | None, pending: list, children: list | None = None,
                      frame: tuple | None = None, bodies: list | None = None) -> None:
        """The joints, geoms, inertial and ignored elements of `body` (or of a <frame> in it: `children`, placed by
        `frame` = (pos, quat) in the body's frame); its child bodies pushed on `pending` (in reverse, so that they
        are read in document order; a frame's bodies join its body's list `bodies` where they stand)."""
        own = bodies is None
        bodies = [] if own else bodies
        for child in body.element.children if children is None else children:
            tag = child.tag
            if tag == "frame":
                self.read_frame(child, body, childclass, frame, pending, bodies)
            elif tag == "body":
                bodies.append((child, body, childclass, frame))
            elif tag == "geom":
                self.read_geom(child, body, childclass, frame)
            elif tag in ("joint", "freejoint", "inertial") and frame is not None:
                raise child.error(f"a <{tag}> inside a <frame>: MuJoCo's frames hold bodies, geoms, sites, cameras, "
                                  "lights and frames")
            elif tag in ("joint", "freejoint"):
                if body.index == 0:
                    raise child.error("the world body cannot have joints")
                self.read_joint(child, body, childclass)
            elif tag == "inertial":
                if body.index == 0:
                    raise child.error("the world body has no inertial")
                if body.inertial is not None:
                    raise child.error("a body has at most one <inertial>")
                self.check_attrs(child, _INERTIAL_ATTRS)
                body.inertial = child
            elif tag in _VISUAL_ELEMENTS:
                self.check_attrs(child, _VISUAL_ATTRS[tag])
                self.check_visual(child)
                if tag == "site" and "name" in child.attrib:  # a tendon or an actuator may use it
                    attrib = self.attrs(child, "site", childclass)
                    if "fromto" in attrib:
                        fromto = numbers(child, "fromto", attrib, 6)
                        position = (fromto[:3] + fromto[3:]) / 2
                        orientation = z_to_quat(normalize(fromto[:3] - fromto[3:])[0])
                    else:
                        position = numbers(child, "pos", attrib, 3) if "pos" in attrib else np.zeros(3)
                        orientation = self.orientation(child, attrib)
                    if frame is not None:
                        position = frame[0] + quat_matrix(frame[1]) @ position
                        orientation = quat_product(frame[1], orientation)
                    self.sites[child.attrib["name"]] = (body, position, orientation)
                self.note(tag, f"<{tag}> elements ignored (they do not change the dynamics)")
            elif tag in _REFUSED_IN_BODY:
                raise child.error(_REFUSED_IN_BODY[tag])
            else:
                raise child.error(f"unknown element <{tag}> in a body")
        if own:
            pending.extend(reversed(bodies))

    def read_frame(self, element: Element, body: _Body, childclass: str | None, outer: tuple | None, pending: list,
                   bodies: list) -> None:
        """A <frame>: its children placed by its pos and orientation (composed with any frame around it), read
        with its childclass, as MuJoCo reads them."""
        self.check_attrs(element, {"name", "childclass", "pos", "quat", "axisangle", "xyaxes", "zaxis", "euler"})
        if "childclass" in element.attrib:
            childclass = element.attrib["childclass"]
            if childclass not in self.classes:
                raise element.error(f"childclass={childclass!r} is not a <default> class of the model")
        pos = numbers(element, "pos", element.attrib, 3) if "pos" in element.attrib else np.zeros(3)
        quat = self.orientation(element, element.attrib)
        if outer is not None:
            pos, quat = outer[0] + quat_matrix(outer[1]) @ pos, quat_product(outer[1], quat)
        self.note("frame", "<frame> elements read: their poses composed into the bodies, geoms and sites they hold")
        self.read_children(body, childclass, pending, element.children, (pos, quat), bodies)

    def read_body(self, element: Element, parent: _Body, childclass: str | None,
                  frame: tuple | None = None) -> tuple[_Body, str | None]:
        self.check_attrs(element, _BODY_ATTRS)
        attrib = element.attrib
        if "childclass" in attrib:
            childclass = attrib["childclass"]
            if childclass not in self.classes:
                raise element.error(f"childclass={childclass!r} is not a <default> class of the model")
        if boolean(element, "mocap", attrib, False):
            self.note("mocap", "mocap bodies are held fixed (nothing moves them in a run)")
        pos = numbers(element, "pos", attrib, 3) if "pos" in attrib else np.zeros(3)
        quat = self.orientation(element, attrib)
        if frame is not None:
            pos, quat = frame[0] + quat_matrix(frame[1]) @ pos, quat_product(frame[1], quat)
        body = _Body(element, attrib.get("name", ""), len(self.bodies) + 1, parent, pos, quat,
                     gravcomp=number(element, "gravcomp", attrib, 0.0))
        self.bodies.append(body)
        return body, childclass

    def check_visual(self, element: Element) -> None:
        """A site, camera or light: ignored, but as MuJoCo reads it, its name unique among its kind and its class a
        <default> class of the model."""
        name = element.attrib.get("name")
        if name:
            seen = self.visual_names.setdefault(element.tag, set())
            if name in seen:
                raise element.error(f"two {element.tag}s are called {name!r}")
            seen.add(name)
        if "class" in element.attrib and element.attrib["class"] not in self.classes:
            raise element.error(f"class={element.attrib['class']!r} is not a <default> class of the model")
        if element.tag in ("site", "camera"):
            self.orientation(element, element.attrib)  # refused as MuJoCo refuses it (an axis too small, two given)
        if element.tag == "site" and element.attrib.get("type") in ("plane", "hfield", "mesh"):
            raise element.error(f"type={element.attrib['type']!r}: MuJoCo allows no plane, height field or mesh site "
                                "here (a mesh site needs a mesh asset)")
        if element.tag == "site" and "fromto" not in element.attrib:
            kind = element.attrib.get("type", "sphere")
            size = numbers(element, "size", element.attrib) if element.attrib.get("size", "").strip() else None
            needed = {"sphere": 1, "capsule": 2, "cylinder": 2, "ellipsoid": 3, "box": 3}.get(kind, 0)
            if size is not None and (len(size) < needed or np.any(size[:needed] <= 0)):
                raise element.error(f"size={element.attrib['size']!r}: a {kind} site needs {needed} sizes > 0 (MuJoCo: "
                                    "size must be positive)")

    def check_mocap(self, body: _Body) -> None:
        """A mocap body must be a fixed child of the world, as MuJoCo's compiler requires (no joints, the world its
        parent): a mocap body with joints, or below another body, is refused. So is a sleep policy other than auto
        on a body that is not a moving child of the world (MuJoCo's rule; rbody has no sleeping)."""
        if body.element.attrib.get("sleep", "auto") != "auto" and (not body.joints or body.parent.index != 0):
            raise body.element.error(f"sleep={body.element.attrib['sleep']!r}: MuJoCo allows a sleep policy only on a "
                                     "moving child of the world")
        if not boolean(body.element, "mocap", body.element.attrib, False):
            return
        if body.joints or body.parent.index != 0:
            why = "it has joints" if body.joints else "its parent is not the world"
            raise body.element.error(f"a mocap body must be a fixed child of the world (MuJoCo's rule), and {why}")

    def read_joint(self, element: Element, body: _Body, childclass: str | None) -> None:
        if element.tag == "freejoint":
            self.check_attrs(element, {"name", "group", "align"})
            if element.attrib.get("align", "auto") == "true":
                raise element.error("align=\"true\" is not supported: it moves the body frame to its inertial frame")
            body.joints.append((element, dict(element.attrib)))
            return
        self.check_attrs(element, _JOINT_ATTRS)
        attrib = self.attrs(element, "joint", childclass)
        kind = choice(element, "type", attrib, ("hinge", "slide", "ball", "free"), "hinge")
        attrib["type"] = kind
        if "springdamper" in attrib:
            timeconst, dampratio = numbers(element, "springdamper", attrib, 2)
            if timeconst > 0 and dampratio > 0 and kind in ("ball", "free"):
                raise element.error("springdamper on a ball or free joint (MuJoCo's averaged inverse weights and "
                                    "quaternion spring) is not modelled: use it on hinge and slide joints")
        body.joints.append((element, attrib))

    def read_geom(self, element: Element, body: _Body, childclass: str | None, frame: tuple | None = None) -> None:
        self.check_attrs(element, _GEOM_ATTRS)
        attrib = self.attrs(element, "geom", childclass)
        kind = choice(element, "type", attrib, _GEOM_KINDS, "sphere")
        if kind == "sdf" or (kind == "hfield" and body.index != 0):
            raise element.error(f"{kind} geoms are not supported" + (" on a body (only a world-fixed height field, "
                                                                    "which moves nothing, is read)" if kind == "hfield"
                                                                    else ""))
        if kind == "hfield":  # on the world: static terrain, massless
            size, pos, quat, mesh, fluidshape = self.field_shape(element, attrib)
        else:
            size, pos, quat, fluidshape = self.primitive_shape(element, attrib, kind)
            mesh = attrib.get("mesh")
            if mesh is not None and kind != "mesh":  # MuJoCo fits the primitive to the mesh and forgets the mesh
                size, pos, quat = self.fitted_shape(element, attrib, kind, mesh, pos, quat)
                mesh = None
        if any(key in attrib for key in ("rgba", "material")):
            self.note("appearance", "geoms' appearance (rgba, material) ignored")
        if frame is not None:
            pos, quat = frame[0] + quat_matrix(frame[1]) @ pos, quat_product(frame[1], quat)
        if kind == "plane" and body.index != 0:
            self.plane_bodies.append((element, body))
        if integer(element, "condim", attrib, 3) not in (1, 3, 4, 6):
            raise element.error(f"condim={attrib['condim']!r}: MuJoCo allows 1, 3, 4 or 6 (invalid condim)")
        geom = _Geom(element, attrib, attrib.get("name", ""), kind, size, pos, quat,
                     integer(element, "contype", attrib, 1), integer(element, "conaffinity", attrib, 1),
                     integer(element, "group", attrib, 0), mesh=mesh, ellipsoid=fluidshape == "ellipsoid")
        if kind == "mesh" and geom.mesh is None:
            raise element.error("a mesh geom needs mesh=\"name of a <mesh> asset\"")
        if kind == "mesh" and geom.mesh not in self.meshes:
            raise element.error(f"mesh={geom.mesh!r} is not a <mesh> asset of the model")
        body.geoms.append(geom)

    def field_shape(self, element: Element, attrib: dict) -> tuple:
        """(size (4,) the <hfield>'s, pos (3,), quat (4,), its asset's name, fluidshape "none") of a hfield geom."""
        field = attrib.get("hfield")
        if field not in self.hfields:
            raise element.error(f"hfield={field!r}: a hfield geom needs hfield=\"name of a <hfield> asset\"")
        pos = numbers(element, "pos", attrib, 3) if "pos" in attrib else np.zeros(3)
        return self.hfields[field][1].copy(), pos, self.orientation(element, attrib), field, "none"

    def primitive_shape(self, element: Element, attrib: dict, kind: str) -> tuple:
        """(size (3,) [m], pos (3,) [m], quat (4,), fluidshape) of a plane, primitive or mesh geom in its body's
        frame: its sizes checked, fromto turned into a pose and a length."""
        fluidshape = choice(element, "fluidshape", attrib, ("none", "ellipsoid"), "none")
        if fluidshape == "ellipsoid" and kind in ("mesh", "plane"):
            raise element.error(f'fluidshape="ellipsoid" on a {kind} geom (MuJoCo sizes its ellipsoid from the '
                                "geom's size, which rbody does not form for meshes and planes) is not modelled")
        fromto = numbers(element, "fromto", attrib, 6) if "fromto" in attrib else None
        fitted = "mesh" in attrib and kind != "mesh"
        if fitted and (kind == "plane" or fromto is not None):
            raise element.error(f"a {kind} fitted to a mesh" + (" cannot have fromto (MuJoCo: fromto cannot be used "
                                                               "with mesh geom)" if kind != "plane" else
                                                               ": MuJoCo fits a sphere, capsule, cylinder, ellipsoid "
                                                               "or box"))
        if kind == "mesh" or fitted:  # a fitted primitive's size comes from its mesh (fitted_shape)
            size = np.zeros(3)
        else:
            size = numbers(element, "size", attrib, (1, 2, 3)) if "size" in attrib else np.zeros(0)
            needed = _SIZES[kind] - (2 if fromto is not None and kind in ("ellipsoid", "box") else
                                     1 if fromto is not None else 0)
            if kind == "plane":
                needed = 0
            if len(size) < needed:
                raise element.error(f"a {kind} needs {needed} sizes, got size={attrib.get('size', '')!r}")
            size = np.concatenate([size, np.zeros(3 - len(size))])
            if kind == "plane" and not size[2] > 0:
                raise element.error(f"size={attrib.get('size', '')!r}: a plane's third size (its grid spacing) must be "
                                    "> 0 (MuJoCo: plane size(3) must be positive)")
        pos = numbers(element, "pos", attrib, 3) if "pos" in attrib else np.zeros(3)
        if fromto is not None:
            if kind not in ("capsule", "cylinder", "ellipsoid", "box"):
                raise element.error("fromto needs a capsule, cylinder, ellipsoid or box")
            if np.any(pos != 0):
                raise element.error("both pos and fromto are given: give one")
            if any(key in attrib for key in ORIENTATIONS):
                raise element.error("orientation given twice (fromto and an orientation): give one")
            vector = fromto[:3] - fromto[3:]
            vector, length = normalize(vector)
            size[1] = length / 2
            if size[1] < MJ_EPS:
                raise element.error("fromto's two points are too close")
            if kind in ("ellipsoid", "box"):
                size[2], size[1] = size[1], size[0]
            pos = (fromto[:3] + fromto[3:]) / 2
            quat = z_to_quat(vector)
        else:
            quat = self.orientation(element, attrib)
        if kind != "plane" and kind != "mesh" and not fitted and np.any(size[:_SIZES[kind]] <= 0):
            raise element.error(f"size={attrib.get('size', '')!r}: a {kind} needs sizes > 0")
        return size, pos, quat, fluidshape

    def fitted_shape(self, element: Element, attrib: dict, kind: str, mesh: str, pos: np.ndarray,
                     quat: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(size (3,) [m], pos (3,) [m], quat (4,)) of a primitive that MuJoCo fits to mesh asset `mesh` (a geom with
        both a primitive type and mesh=): sized by fitted_size (compiler fitaabb, the geom's fitscale), placed in the
        mesh's principal frame as MuJoCo moves a mesh geom there. Its mass and contacts are then the primitive's."""
        if mesh not in self.meshes:
            raise element.error(f"mesh={mesh!r} is not a <mesh> asset of the model")
        fitscale = number(element, "fitscale", attrib, 1.0)
        if not fitscale > 0:
            raise element.error(f"fitscale={fitscale!r}: must be > 0 (the fitted {kind}'s sizes are scaled by it)")
        fit = self.mesh_named(mesh)
        size, centre = fitted_size(kind, fit, self.fitaabb, fitscale)
        if np.any(size[:_SIZES[kind]] <= 0):
            raise element.error(f"the {kind} fitted to mesh {mesh!r} has size {size[:_SIZES[kind]].tolist()}: MuJoCo "
                                f"needs sizes > 0 (size must be positive in geom); use another type or fitscale")
        axes = fit.principal()[1]
        rotation = quat_matrix(quat)
        return size, pos + rotation @ (fit.com + quat_matrix(axes) @ centre), quat_product(quat, axes)

    # ----- other sections -----

    def read_contact(self, element: Element) -> None:
        self.check_attrs(element, set())
        for child in element.children:
            if child.tag == "pair":
                self.check_attrs(child, _PAIR_ATTRS)
                self.explicit_pairs.append((child, self.attrs(child, "pair", None)))
            elif child.tag == "exclude":
                self.check_attrs(child, {"name", "body1", "body2"})
                self.excluded.add(frozenset((child.attrib.get("body1"), child.attrib.get("body2"))))
            else:
                raise child.error(f"unknown element <{child.tag}> in <contact>")

    def read_equality(self, element: Element) -> None:
        self.check_attrs(element, set())
        for child in element.children:
            error = equality_kind_error(child)
            attrib = self.attrs(child, "equality", None) if error is None else dict(child.attrib)
            if not self.equality_on:
                self.note("equality", "equality constraints ignored (<flag equality=\"disable\"/>)")
                continue
            if error is not None:
                raise error
            self.check_attrs(child, EQUALITY_ATTRS[child.tag])
            soft = softness_note(attrib)
            if soft:
                self.note("equality soft", f"equality {soft} ignored: rbody holds equalities rigidly (to round-off)")
            self.equality_elements.append((child, attrib))

    def read_tendons(self, element: Element) -> None:
        """<fixed> and <spatial> tendons (rbody.mjcf.actuators: what is read, what is refused)."""
        self.check_attrs(element, set())
        for child in element.children:
            if child.tag not in ("spatial", "fixed"):
                raise child.error(f"unknown element <{child.tag}> in <tendon>")
            attrib = self.attrs(child, "tendon", None)
            name = attrib.get("name") or f"tendon{len(self.tendon_specs)}"
            self.tendon_specs.append((name, mjcf_actuators.read_tendon(child, attrib)))

    def read_actuators(self, element: Element) -> None:
        """Each actuator over its class's one actuator default (rbody.mjcf.actuators)."""
        self.check_attrs(element, set())
        for child in element.children:
            if child.tag not in _ACTUATORS and child.tag != "plugin":
                raise child.error(f"unknown element <{child.tag}> in <actuator>")
            name = child.attrib.get("class", "main")
            if name not in self.classes:
                raise child.error(f"class={name!r} is not a <default> class of the model")
            spec = self.actuator_defaults.get(name, mjcf_actuators.ActuatorSpec()).copy()
            mjcf_actuators.apply_actuator(spec, child, {k: v for k, v in child.attrib.items() if k != "class"})
            label = child.attrib.get("name") or f"actuator{len(self.actuator_specs)}"
            self.actuator_specs.append((label, spec))

    # ----- mass properties -----

    def mesh_path(self, name: str) -> str | None:
        """The absolute path of mesh asset `name`'s file (checked to exist; None for a mesh given by its vertices in
        the XML); no file is read here, so that a mesh whose mass an explicit <inertial> makes unused costs nothing
        to load."""
        if name in self.mesh_paths:
            return self.mesh_paths[name]
        element, attrib = self.meshes[name]
        if "file" not in attrib and "vertex" in attrib:
            return None  # given by its vertices in the XML: no file
        if "file" not in attrib:
            raise element.error("a <mesh> needs a file or its vertices (vertex)")
        if "builtin" in attrib:
            raise element.error("builtin meshes are not supported")
        path = self.asset_file(element, attrib["file"], "mesh")
        self.mesh_paths[name] = str(path)
        return str(path)

    def mesh_of(self, geom: _Geom) -> MeshMass:
        return self.mesh_named(geom.mesh)

    def mesh_named(self, name: str) -> MeshMass:
        """The mass properties (per unit density) of mesh asset `name`, read once."""
        if name in self.mesh_cache:
            return self.mesh_cache[name]
        file = self.mesh_path(name)
        element, attrib = self.meshes[name]
        mode = choice(element, "inertia", attrib, MESH_INERTIA_MODES, "legacy")
        import trimesh

        if file is None:  # vertex (and face) in the XML; without faces MuJoCo takes the convex hull
            points = numbers(element, "vertex", attrib)
            if points.size % 3 or points.size < 12:
                raise element.error(f"vertex has {points.size} numbers: expected 3 per vertex, at least 4 vertices")
            indices = numbers(element, "face", attrib) if "face" in attrib else np.zeros(0)
            if indices.size % 3 or np.any(indices != np.round(indices)) or np.any(indices < 0) \
                    or np.any(indices >= points.size // 3):
                raise element.error("face: expected 3 vertex indices per face, each below the vertex count")
            loaded = trimesh.Trimesh(points.reshape(-1, 3), indices.reshape(-1, 3).astype(np.int64), process=False)
            path = Path(f"<mesh {name!r} given by its vertices>")
        else:
            path = Path(file)
            try:
                loaded = trimesh.load(str(path), force="mesh", process=False)
            except Exception as error:  # trimesh raises many types for unreadable files
                raise element.error(f"mesh file {str(path)!r} could not be read ({error})") from None
        scale = numbers(element, "scale", attrib, 3) if "scale" in attrib else np.ones(3)
        refpos = numbers(element, "refpos", attrib, 3) if "refpos" in attrib else np.zeros(3)
        refquat = numbers(element, "refquat", attrib, 4) if "refquat" in attrib else np.array([1.0, 0, 0, 0])
        if np.any(scale != 1):
            self.note(f"scale {name}", f"mesh {name!r}: scale {scale.tolist()} applies to its mass properties; the "
                                       "rbody Shape keeps the unscaled file (drawing only)")
        try:
            result = mesh_mass(np.asarray(loaded.vertices), np.asarray(loaded.faces), mode=mode, scale=scale,
                               refpos=refpos, refquat=refquat)
        except ValueError as error:
            raise element.error(f"mesh {name!r} ({str(path)!r}): {error}") from None
        self.mesh_cache[name] = result
        return result

    def hull_vertices(self, geom: _Geom) -> tuple:
        """The vertices of the convex hull of a mesh geom's vertices (scaled, refpos and refquat applied, in the
        geom's frame as the file gives it: MuJoCo's move of the mesh to its centre of mass moves the geom frame with
        it), by which it collides."""
        name = geom.mesh
        if name not in self.hull_cache:
            from scipy.spatial import ConvexHull, QhullError

            vert = np.asarray(self.mesh_of(geom).vertices, dtype=np.float64)
            element, attrib = self.meshes[name]
            try:
                points = vert[ConvexHull(vert).vertices]
            except QhullError:
                raise element.error(f"mesh {name!r} is flat (its vertices span no volume): it has no convex hull "
                                    "to collide by") from None
            if "maxhullvert" in attrib and int(attrib["maxhullvert"]) > 0:
                self.note(f"maxhullvert {name}", f"mesh {name!r}: maxhullvert ignored: rbody collides the mesh's "
                                                 f"whole convex hull ({len(points)} vertices), MuJoCo one of at most "
                                                 f"{attrib['maxhullvert']}")
            self.hull_cache[name] = tuple(map(tuple, points.tolist()))
        return self.hull_cache[name]

    def geom_mass(self, geom: _Geom) -> GeomMass | None:
        """The geom's mass properties as MuJoCo's compiler forms them; None when it has no mass."""
        element, attrib = geom.element, geom.attrib
        if geom.kind == "plane":
            return None
        shell = boolean(element, "shellinertia", attrib, False)
        rotation = quat_matrix(geom.quat)
        if geom.kind == "mesh":
            if shell:
                raise element.error("shellinertia on a mesh geom: MuJoCo wants inertia=\"shell\" on the mesh asset")
            mesh = self.mesh_of(geom)
            volume = mesh.volume
        else:
            volume = primitive_volume(geom.kind, geom.size, shell)
        if "mass" in attrib:
            given = number(element, "mass", attrib, 0.0)
            if given < 0:
                raise element.error(f"mass={given!r}: must be >= 0 [kg]")
            mass = given if (given != 0 and volume > MJ_EPS) else 0.0
        else:
            density = number(element, "density", attrib, 1000.0)
            if density < 0:
                raise element.error(f"density={density!r}: must be >= 0")
            mass = density * volume
        if mass <= MJ_EPS:
            return None
        if geom.kind == "mesh":
            # MuJoCo moves the mesh to its centre of mass and principal axes, and the geom frame with it
            pos = geom.pos + rotation @ mesh.com
            geom.axes = quat_product(geom.quat, mesh.principal()[1])
            tensor = principal_tensor(mesh.moments(mass), geom.axes)
            exact = rotation @ (mesh.tensor * (mass / volume)) @ rotation.T
            self.compare_exact(geom.element, f"mesh geom {geom.name!r}", tensor, exact)
        else:
            pos = geom.pos
            geom.axes = geom.quat
            tensor = principal_tensor(primitive_moments(geom.kind, geom.size, mass, shell), geom.quat)
        return GeomMass(geom.name, mass, pos, tensor)

    def compare_exact(self, element: Element, what: str, mujoco: np.ndarray, exact: np.ndarray) -> None:
        """Note where MuJoCo's principal-axis solver (mujoco_principal) moved a tensor beyond round-off."""
        scale = float(np.max(np.abs(exact)))
        difference = float(np.max(np.abs(mujoco - exact)))
        if difference > PRINCIPAL_NOTE_RTOL * scale:
            self.note(f"eig {what}", f"{what} (line {element.line}): MuJoCo's principal-axis solver leaves its "
                                     f"inertia tensor {difference / scale:.2g} (relative) from the exact one; rbody "
                                     "uses MuJoCo's, so that both engines run the same body")

    def inertial_mass(self, body: _Body) -> tuple[float, np.ndarray, np.ndarray]:
        element = body.inertial
        attrib = element.attrib
        if "mass" not in attrib:
            raise element.error("<inertial> needs mass")
        mass = number(element, "mass", attrib, 0.0)
        pos = numbers(element, "pos", attrib, 3) if "pos" in attrib else None
        if pos is None:
            raise element.error("<inertial> needs pos")
        if "fullinertia" in attrib:
            if "diaginertia" in attrib:
                raise element.error("both diaginertia and fullinertia are given: give one")
            if any(key in attrib for key in ORIENTATIONS):
                raise element.error("fullinertia with an orientation: the full tensor is already in the body axes")
            xx, yy, zz, xy, xz, yz = numbers(element, "fullinertia", attrib, 6)
            exact = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
            moments, axes = mujoco_principal(exact)
            tensor = principal_tensor(moments, axes)
            self.compare_exact(element, f"body {body.name!r} fullinertia", tensor, exact)
        elif "diaginertia" in attrib:
            axes = self.orientation(element, attrib)
            rotation = quat_matrix(axes)
            tensor = rotation @ np.diag(numbers(element, "diaginertia", attrib, 3)) @ rotation.T
        else:
            raise element.error("<inertial> needs diaginertia or fullinertia")
        if mass < 0:
            raise element.error(f"mass={mass!r}: must be >= 0 [kg]")
        return mass, pos, 0.5 * (tensor + tensor.T), axes

    def body_mass(self, body: _Body) -> None:
        from_geoms = self.inertiafromgeom == "true" or (self.inertiafromgeom == "auto" and body.inertial is None)
        if from_geoms:
            low, high = self.group_range
            parts = []
            for geom in body.geoms:
                geom.mass = self.geom_mass(geom) if low <= geom.group <= high else None
                if geom.mass is not None:
                    parts.append(geom)
            if parts:
                body.mass, body.com, body.tensor = sum_geoms([g.mass for g in parts])
                body.axes = parts[0].axes
                if len(parts) > 1:
                    exact = body.tensor
                    moments, body.axes = mujoco_principal(exact)
                    body.tensor = principal_tensor(moments, body.axes)
                    self.compare_exact(body.element, f"body {body.name!r}", body.tensor, exact)
                    self.check_overlaps(body, parts)
        elif body.inertial is not None:
            body.mass, body.com, body.tensor, body.axes = self.inertial_mass(body)

    def check_overlaps(self, body: _Body, parts: list[_Geom]) -> None:
        from rbody.mjcf.overlap import overlapping

        if self.overlapping_geoms == "sum":
            return
        for i, first in enumerate(parts):
            for second in parts[i + 1:]:
                verdict = overlapping(self.solid(first), self.solid(second))
                if verdict:
                    label = lambda g: g.name or f"geom at line {g.element.line}"  # noqa: E731
                    if body.weld == 0:  # welded to the world: its mass moves nothing
                        self.note(f"overlap {body.name}", f"body {body.name!r} is welded to the world and its geoms "
                                  f"{label(first)!r} and {label(second)!r} {verdict}: their masses are summed as "
                                  "MuJoCo sums them (the body does not move, so nothing depends on it)")
                        return
                    raise body.element.error(
                        f"geoms {label(first)!r} and {label(second)!r} {verdict}: their masses would be counted twice "
                        "where they overlap (MuJoCo sums geom masses). Make the parts meet without overlapping, give "
                        "the body an <inertial>, or pass overlapping_geoms=\"sum\" to sum them as MuJoCo does")

    def solid(self, geom: _Geom):
        from rbody.mjcf.overlap import Solid

        rotation = quat_matrix(geom.quat)
        if geom.kind == "mesh":
            mesh = self.mesh_of(geom)
            return Solid("mesh", geom.size, geom.pos, rotation, vertices=mesh.vertices @ rotation.T + geom.pos,
                         faces=mesh.faces)
        return Solid(geom.kind, geom.size, geom.pos, rotation)

    # ----- assembly -----

    def name_everything(self) -> None:
        taken = {b.element.attrib["name"] for b in self.bodies if b.element.attrib.get("name")}
        for body in self.bodies:
            if not body.name:
                name = f"body{body.index}"
                while name in taken:
                    name += "_"
                body.name = name
                taken.add(name)
        seen: dict[str, Element] = {}
        for body in self.bodies:
            if body.name in seen or body.name == WORLD:
                raise body.element.error(f"two bodies are called {body.name!r}" if body.name != WORLD else
                                         "a body cannot be called 'world' (the world body's name)")
            seen[body.name] = body.element
        joint_names = {a.get("name") for b in self.bodies for _e, a in b.joints if a.get("name")}
        geom_names = {g.name for b in [self.world, *self.bodies] for g in b.geoms if g.name}
        for body in [self.world, *self.bodies]:
            for k, (_element, attrib) in enumerate(body.joints):
                if not attrib.get("name"):
                    name = f"{body.name}_joint{k}"
                    while name in joint_names:
                        name += "_"
                    attrib["name"] = name
                    joint_names.add(name)
            for k, geom in enumerate(body.geoms):
                if not geom.name:
                    name = f"{body.name}_geom{k}"
                    while name in geom_names:
                        name += "_"
                    geom.name = name
                    geom_names.add(name)
        for kind, names in (("joint", [a["name"] for b in self.bodies for _e, a in b.joints]),
                            ("geom", [g.name for b in [self.world, *self.bodies] for g in b.geoms])):
            duplicates = sorted({n for n in names if names.count(n) > 1})
            if duplicates:
                raise MJCFError(f"{self.root.file}: two {kind}s are called {duplicates[0]!r}")

    def welds(self) -> None:
        """MuJoCo's weldid: a body with joints roots its own weld; a body without joints joins its parent's."""
        self.world.weld = 0
        for body in self.bodies:
            body.weld = body.index if body.joints else body.parent.weld
        for element, body in self.plane_bodies:
            if body.weld != 0:
                raise element.error("a plane can only be on the world or a body without joints (MuJoCo's rule)")

    def check_contacts(self) -> None:
        """The geom pairs MuJoCo's broad phase keeps (engine_collision_driver.c filterBodyPair: not within one weld,
        not both welded to the world, not parent and child unless filterparent is disabled, no <exclude>,
        contype/conaffinity matching), as rbody Contacts (rbody.mjcf.contacts); a pair rbody does not compute is
        refused, naming both geoms and their lines."""
        self.contact_pairs = []
        if not self.contacts_on:
            return
        everyone = [self.world, *self.bodies]
        by_index = {b.index: b for b in everyone}
        dofs = {b.index: b.dofs for b in everyone}
        candidates = []
        for i, b1 in enumerate(everyone):
            for b2 in everyone[i + 1:]:
                w1, w2 = b1.weld, b2.weld
                if w1 == w2 or (dofs[w1] == 0 and dofs[w2] == 0):
                    continue
                p1 = by_index[w1].parent.weld if w1 else 0
                p2 = by_index[w2].parent.weld if w2 else 0
                if self.filterparent and w1 != 0 and w2 != 0 and (w1 == p2 or w2 == p1):
                    continue
                if frozenset((b1.name if b1.index else WORLD, b2.name)) in self.excluded:
                    continue
                for g1 in b1.geoms:
                    for g2 in b2.geoms:
                        if (g1.contype & g2.conaffinity) or (g2.contype & g1.conaffinity):
                            candidates.append((g1, g2))
        from rbody.mjcf.contacts import explicit_pairs, unsupported_pair

        named = {g.attrib["name"]: g for b in everyone for g in b.geoms if g.attrib.get("name")}
        carrier = {0: WORLD}  # the rbody body of each: a body with neither mass nor joints is folded into its parent
        for b in self.bodies:
            carrier[b.index] = carrier[b.parent.index] if b.mass <= MJ_EPS and not b.joints else b.name
        body_of = {g.attrib["name"]: (carrier[b.index], b.name if b.index else WORLD) for b in everyone
                   for g in b.geoms if g.attrib.get("name")}
        explicit = explicit_pairs(self.explicit_pairs, named, body_of)  # MuJoCo: an explicit pair replaces the
        # dynamic one
        listed = {frozenset((g1.name, g2.name)) for g1, g2, _spec in explicit}
        candidates = [(g1, g2, None) for g1, g2 in candidates if frozenset((g1.name, g2.name)) not in listed]
        candidates += explicit
        for g1, g2, spec in candidates:
            why = unsupported_pair(g1, g2, spec)
            if why:
                more = f" (and {len(candidates) - 1} more pairs can collide)" if len(candidates) > 1 else ""
                raise g1.element.error(
                    f"geoms {g1.name!r} and {g2.name!r} (line {g2.element.line}) can collide, and {why}{more}. Set "
                    "contype=\"0\" conaffinity=\"0\" on the geoms that must not collide, or disable contacts with "
                    "<option><flag contact=\"disable\"/></option>")
        self.contact_pairs = candidates
        self.colliding = {g.name for g1, g2, _spec in candidates for g in (g1, g2)}

    def gravcomp_of(self, body: _Body) -> float:
        """The body's gravcomp as MuJoCo applies it: none where gravity is off, or where <flag spring> and <flag
        damper> are both disabled (MuJoCo then skips every passive force, gravity compensation included)."""
        if body.gravcomp == 0.0:
            return 0.0
        if not self.spring_on and not self.damper_on:
            self.note("gravcomp", "gravcomp ignored: <flag spring> and <flag damper> are both disabled, and MuJoCo "
                                  "then applies no passive force at all")
            return 0.0
        self.note("gravcomp bodies", "body gravcomp applied as MuJoCo applies it (an upward force gravcomp m g at "
                                     "the centre of mass)")
        return float(body.gravcomp)

    def actuator_joint(self, element: Element, attrib: dict) -> dict:
        """actuatorgravcomp and actuatorfrcrange (limited by actuatorfrclimited, "auto": where a range is given)."""
        values = {"actuatorgravcomp": boolean(element, "actuatorgravcomp", attrib, False)}
        limited = choice(element, "actuatorfrclimited", attrib, ("true", "false", "auto"), "auto")
        has_range = "actuatorfrcrange" in attrib and np.any(numbers(element, "actuatorfrcrange", attrib, 2) != 0)
        if limited == "true" or (limited == "auto" and self.autolimits and has_range):
            low, high = numbers(element, "actuatorfrcrange", attrib, 2)
            if not low < high:
                raise element.error(f"actuatorfrcrange={attrib.get('actuatorfrcrange')!r}: needs low < high")
            values["actuatorfrcrange"] = (float(low), float(high))
        return values

    def passive(self, element: Element, attrib: dict) -> dict:
        """damping, stiffness, armature of a joint, >= 0; stiffness and damping 0 where the flags disable them."""
        values = {key: number(element, key, attrib, 0.0) for key in ("damping", "stiffness", "armature")}
        for key, value in values.items():
            if value < 0:
                raise element.error(f"{key}={value!r}: must be >= 0")
        if not self.spring_on and values["stiffness"]:
            self.note("spring", "joint stiffness ignored (<flag spring=\"disable\"/>)")
            values["stiffness"] = 0.0
        if not self.damper_on and values["damping"]:
            self.note("damper", "joint damping ignored (<flag damper=\"disable\"/>)")
            values["damping"] = 0.0
        return values

    def joints_of(self, body: _Body) -> list[tuple[Joint, np.ndarray, int, tuple | None]]:
        """(rbody Joint at the reference state, qpos0 (MuJoCo), nv, limit) for each joint of `body`."""
        out = []
        for element, attrib in body.joints:
            kind = attrib.get("type", "free") if element.tag == "joint" else "free"
            name = attrib["name"]
            angular = self.degree and kind == "hinge"

            def angle(key: str, default: float = 0.0) -> float:
                value = number(element, key, attrib, default)
                return value / 180.0 * math.pi if angular else value

            if kind == "free":
                values = self.passive(element, attrib)
                values.pop("stiffness")  # MuJoCo gives a free joint no spring
                joint = Joint(name, "free", body.name, **values, **self.actuator_joint(element, attrib))
                qpos = np.concatenate([body.pos, body.quat])
                nv = 6
            else:
                pos = numbers(element, "pos", attrib, 3) if "pos" in attrib else np.zeros(3)
                axis = numbers(element, "axis", attrib, 3) if "axis" in attrib else np.array([0.0, 0.0, 1.0])
                axis, norm = normalize(axis)
                if kind in ("hinge", "slide") and norm < MJ_EPS:
                    raise element.error(f"axis={attrib.get('axis')!r}: a joint axis must be non-zero")
                values = self.passive(element, attrib)
                ref = angle("ref") if kind in ("hinge", "slide") else 0.0
                springref = angle("springref") if kind in ("hinge", "slide") else 0.0
                if kind == "ball":
                    if values["stiffness"]:
                        raise element.error("stiffness on a ball joint (MuJoCo's quaternion spring) is not supported")
                    qpos = np.array([1.0, 0.0, 0.0, 0.0])
                    joint = Joint(name, "ball", body.name, anchor=tuple(pos.tolist()), qpos0=(1.0, 0.0, 0.0, 0.0),
                                  qvel0=(0.0, 0.0, 0.0), **values, **self.actuator_joint(element, attrib))
                    nv = 3
                else:
                    qpos = np.array([ref])
                    joint = Joint(name, kind, body.name, axis=tuple(axis.tolist()), anchor=tuple(pos.tolist()),
                                  qpos0=ref, ref=ref, springref=springref, **values,
                                  **self.actuator_joint(element, attrib))
                    nv = 1
            limit = None
            if kind != "free" and self.limits_on:
                limited = choice(element, "limited", attrib, ("true", "false", "auto"), "auto")
                if limited == "true" or (limited == "auto" and self.autolimits and "range" in attrib):
                    if "range" not in attrib:
                        raise element.error("limited=\"true\" needs a range")
                    low, high = numbers(element, "range", attrib, 2)
                    if angular or (kind == "ball" and self.degree):
                        low, high = low / 180.0 * math.pi, high / 180.0 * math.pi
                    if kind == "ball":
                        if low != 0:
                            raise element.error(f"range={attrib['range']!r}: a ball joint's range starts at 0 (it "
                                                "limits the rotation angle; MuJoCo: range[0] should be 0)")
                        low = 0.0
                    if not low < high:
                        raise element.error(f"range={attrib['range']!r}: needs lo < hi")
                    margin = number(element, "margin", attrib, 0.0)
                    low = 0.0 if kind == "ball" else low + margin
                    limit = (float(low), float(high - margin))
            joint = self.joint_constraints(element, attrib, joint, limit)
            out.append((joint, qpos, nv, limit))
        return out

    def joint_constraints(self, element: Element, attrib: dict, joint: Joint, limit: tuple | None) -> Joint:
        """The joint with its limit, dry friction and restitution (rbody.mjcf.constraints), as the flags allow."""
        friction = number(element, "frictionloss", attrib, 0.0)
        if friction < 0:
            raise element.error(f"frictionloss={friction!r}: must be >= 0")
        if friction and not self.frictionloss_on:
            self.note("frictionloss", "joint frictionloss ignored (<flag frictionloss=\"disable\"/>)")
            friction = 0.0
        soft = softness_note({k: v for k, v in attrib.items() if k.startswith(("solref", "solimp"))})
        if soft and (limit is not None or friction):
            self.note("joint soft", f"joint {soft} ignored: rbody's limits and dry friction are rigid")
        if limit is not None and limit[0] >= limit[1]:
            raise element.error(f"range={attrib.get('range')!r} less margin={attrib.get('margin')!r} leaves no room")
        try:
            return dataclasses.replace(joint, range=limit, frictionloss=friction,
                                       restitution=restitution_of(self.numerics, joint.name))
        except ValueError as error:
            raise element.error(str(error)) from None

    def equalities(self, layout: Layout) -> tuple:
        """The model's equality constraints (rbody.mjcf.constraints), in document order; unnamed ones are called
        equality<i> (i its index in <equality>, MuJoCo's id)."""
        frames = Frames(self.bodies, self.carriers)
        sites = {name: (body.index, pos, quat) for name, (body, pos, quat) in self.sites.items()}
        joints = {joint.name: joint for joint in layout.joints}
        taken = {attrib.get("name") for _e, attrib in self.equality_elements}
        out = []
        for i, (element, attrib) in enumerate(self.equality_elements):
            name = attrib.get("name") or f"equality{i}"
            while not attrib.get("name") and name in taken:
                name += "_"
            taken.add(name)
            try:
                out.append(equality_from(element, attrib, name, frames, sites, joints,
                                         {tendon.name for tendon in layout.tendons}))
            except MJCFError:
                raise
            except ValueError as error:  # the Equality's own checks
                raise element.error(str(error)) from None
        names = [e.name for e in out]
        duplicates = sorted({n for n in names if names.count(n) > 1})
        if duplicates:
            raise MJCFError(f"{self.root.file}: two equalities are called {duplicates[0]!r}")
        return tuple(out)

    def build(self, qpos0, qvel0, keyframe) -> MJCFModel:
        self.name_everything()
        self.welds()
        for body in self.bodies:
            self.body_mass(body)
        if self.settotalmass > 0:  # MuJoCo's mj_setTotalmass, after compiling, before its constants
            total = sum(body.mass for body in self.bodies)
            scale = max(MJ_MINVAL, self.settotalmass / max(MJ_MINVAL, total))
            for body in self.bodies:
                body.mass *= scale
                body.tensor = body.tensor * scale
            self.note("settotalmass", f"settotalmass={self.settotalmass!r}: every body's mass and inertia scaled by "
                                      f"{scale:.17g}, as MuJoCo scales them")
        for body in self.bodies:
            kinds = body.joint_kinds
            if "free" in kinds and (len(kinds) > 1 or body.parent.index != 0):
                raise body.element.error("a free joint must be the only joint of a child of the world")
            if body.dofs > 6:
                raise body.element.error(f"{body.dofs} degrees of freedom: MuJoCo allows at most 6 per body")
            if body.joints and body.mass <= MJ_EPS:
                raise body.element.error(
                    "the body has a joint but no mass: give it an <inertial> or geoms with mass (a massless body "
                    "on a joint has no defined motion of its own)")
        self.check_contacts()

        joints, qpos_parts, nv, limits = [], [], 0, {}
        for body in self.bodies:
            for joint, qpos, dofs, limit in self.joints_of(body):
                joints.append(joint)
                qpos_parts.append(qpos)
                nv += dofs
                if limit is not None:
                    limits[joint.name] = limit
        model_qpos0 = np.concatenate(qpos_parts) if qpos_parts else np.zeros(0)
        keyframes = self.read_keyframes(model_qpos0, nv)
        state_qpos, state_qvel = model_qpos0, np.zeros(nv)
        if keyframe is not None:
            names = list(keyframes)
            if isinstance(keyframe, (int, np.integer)) and not isinstance(keyframe, bool):
                if not 0 <= keyframe < len(names):
                    raise MJCFError(f"keyframe={keyframe!r}: the model has {len(names)} keyframes")
                state_qpos, state_qvel = keyframes[names[int(keyframe)]]
            elif isinstance(keyframe, str) and keyframe in keyframes:
                state_qpos, state_qvel = keyframes[keyframe]
            else:
                raise MJCFError(f"keyframe={keyframe!r}: expected an index or one of the key names {names}")
        if qpos0 is not None:
            state_qpos = _state_vector(qpos0, "qpos0", len(model_qpos0))
        if qvel0 is not None:
            state_qvel = _state_vector(qvel0, "qvel0", nv)
        state_qpos = self.unit_quaternions(joints, state_qpos)
        joints = self.joints_at(joints, state_qpos, state_qvel)
        stray = unknown_restitutions(self.numerics, {joint.name for joint in joints}
                                     | {name for name, _spec in self.tendon_specs})
        if stray:
            raise MJCFError(f"{self.root.file}: <custom><numeric name={stray[0]!r}> names no joint or tendon of the "
                            "model")
        layout = self.force_elements(self.spring_dampers(self.layout(joints), model_qpos0), model_qpos0)
        layout = dataclasses.replace(layout, equalities=self.equalities(layout))
        if self.contact_pairs:
            from rbody.mjcf.contacts import contacts_of

            layout = dataclasses.replace(layout, contacts=contacts_of(self.contact_pairs, self.numerics,
                                                                      self.root.file, self.override_margin))
        na = sum(a.stateful for a in layout.actuators)
        state_act, state_ctrl = np.zeros(na), np.zeros(len(layout.actuators))
        if keyframe is not None:
            state_act, state_ctrl = self.key_controls(keyframe, keyframes, na, len(layout.actuators))
        return MJCFModel(layout=layout, name=self.name, gravity=self.gravity, timestep=self.timestep,
                         integrator=self.integrator, qpos0=state_qpos.copy(), qvel0=state_qvel.copy(),
                         keyframes=keyframes, limits=limits, notes=tuple(self.notes), source=self.root.file,
                         act0=state_act, ctrl0=state_ctrl)

    def spring_dampers(self, layout: Layout, reference_qpos: np.ndarray) -> Layout:
        """The joints with springdamper="timeconst dampratio" given their stiffness and damping as MuJoCo's
        compiler forms them (AutoSpringDamper): with I = 1 / (M^-1)_dd at the reference pose (MuJoCo's
        dof_invweight0 of a hinge or slide), stiffness = I / (timeconst dampratio)^2, damping = 2 I / timeconst."""
        wanted = {}
        for body in self.bodies:
            for element, attrib in body.joints:
                if element.tag == "joint" and "springdamper" in attrib:
                    timeconst, dampratio = numbers(element, "springdamper", attrib, 2)
                    if timeconst > 0 and dampratio > 0:
                        wanted[attrib["name"]] = (float(timeconst), float(dampratio))
        if not wanted:
            return layout
        from rbody.engine.multibody import Multibody

        model = Multibody(layout, gravity=self.gravity)
        inverse = np.linalg.inv(model.mass_matrix(reference_qpos))
        dofs = dict(zip(model.joint_names, model.arrays.dofadr))
        joints = []
        for joint in layout.joints:
            if joint.name in wanted:
                timeconst, dampratio = wanted[joint.name]
                inertia = 1.0 / max(MJ_MINVAL, inverse[dofs[joint.name], dofs[joint.name]])
                stiffness = inertia / max(MJ_MINVAL, timeconst * timeconst * dampratio * dampratio)
                damping = 2 * inertia / max(MJ_MINVAL, timeconst)
                joint = dataclasses.replace(joint, stiffness=stiffness if self.spring_on else 0.0,
                                            damping=damping if self.damper_on else 0.0)
            joints.append(joint)
        self.note("springdamper", "joint springdamper turned into stiffness and damping as MuJoCo's compiler does "
                                  "(from the mass matrix at the reference pose)")
        return dataclasses.replace(layout, joints=tuple(joints))

    def force_elements(self, layout: Layout, reference_qpos: np.ndarray) -> Layout:
        """The layout with the model's tendons and actuators (rbody.mjcf.actuators), every damping ratio of a
        position servo resolved against the mass matrix at the reference pose, as MuJoCo's compiler does."""
        if not self.tendon_specs and not self.actuator_specs:
            return layout
        sites, frames = {}, {}
        for name, (body, position, orientation) in self.sites.items():
            carrier, pos, quat = self.frames[body.index]
            sites[name] = (carrier, tuple((pos + quat_matrix(quat) @ position).tolist()))
            frames[name] = (carrier, sites[name][1], tuple(quat_product(quat, orientation).tolist()))
        tendons, ranges = [], {}
        for name, spec in self.tendon_specs:
            if any(t.name == name for t in tendons):
                raise spec.element.error(f"two tendons are called {name!r}")
            tendons.append(mjcf_actuators.tendon_of(spec, name, sites, self.spring_on, self.damper_on, self.limits_on,
                                                    self.frictionloss_on, self.autolimits, self.note,
                                                    restitution_of(self.numerics, name)))
            if "range" in spec.attrib:
                ranges[name] = tuple(numbers(spec.element, "range", spec.attrib, 2).tolist())
        for body in self.bodies:
            for element, attrib in body.joints:
                if element.tag == "joint" and "range" in attrib:
                    low, high = numbers(element, "range", attrib, 2)
                    if self.degree and attrib.get("type", "hinge") == "hinge":
                        low, high = low / 180.0 * math.pi, high / 180.0 * math.pi
                    ranges[attrib["name"]] = (float(low), float(high))
        kinds = {joint.name: joint.kind for joint in layout.joints}
        actuators = []
        for name, spec in self.actuator_specs:
            if any(a.name == name for a in actuators):
                raise spec.element.error(f"two actuators are called {name!r}")
            actuators.append(mjcf_actuators.actuator_of(spec, name, kinds, ranges, {t.name for t in tendons},
                                                        self.autolimits, self.disabled_groups, self.actuation_on,
                                                        self.clampctrl_on, frames))
        if actuators and not self.actuation_on:
            self.note("actuation", "actuators apply no force (<flag actuation=\"disable\"/>): kept, disabled")
        elif any(a.disabled for a in actuators):
            self.note("actuatorgroupdisable", "actuators of the groups in actuatorgroupdisable apply no force")
        if actuators and not self.clampctrl_on:
            self.note("clampctrl", "controls are not clamped to ctrlrange (<flag clampctrl=\"disable\"/>)")
        layout = dataclasses.replace(layout, tendons=tuple(tendons), actuators=tuple(actuators))
        if any(mjcf_actuators.dampratio_pending(a) for a in actuators):
            from rbody.engine.system import Multibody

            model = Multibody(layout, gravity=self.gravity)
            layout = dataclasses.replace(layout, actuators=mjcf_actuators.resolve_dampratio(
                layout.actuators, model, reference_qpos))
        return layout

    def key_controls(self, keyframe, keyframes: dict, na: int, nu: int) -> tuple[np.ndarray, np.ndarray]:
        """(act (na,), ctrl (nu,)) of the chosen keyframe (zeros where it gives none)."""
        names = list(keyframes)
        index = int(keyframe) if isinstance(keyframe, (int, np.integer)) else names.index(keyframe)
        if index >= len(self.key_elements):  # one of <size nkey>'s keyframes: at rest, no control
            return np.zeros(na), np.zeros(nu)
        key = self.key_elements[index]
        act = numbers(key, "act", key.attrib, na) if "act" in key.attrib else np.zeros(na)
        ctrl = numbers(key, "ctrl", key.attrib, nu) if "ctrl" in key.attrib else np.zeros(nu)
        return act, ctrl

    def read_keyframes(self, qpos0: np.ndarray, nv: int) -> dict:
        keys = {}
        for i, key in enumerate(self.key_elements):
            attrib = key.attrib
            qpos = numbers(key, "qpos", attrib, len(qpos0)) if "qpos" in attrib else qpos0.copy()
            qvel = numbers(key, "qvel", attrib, nv) if "qvel" in attrib else np.zeros(nv)
            name = attrib.get("name") or f"key{i}"
            if name in keys:
                raise key.error(f"two keyframes are called {name!r}")
            keys[name] = (qpos, qvel)
        for i in range(len(keys), self.nkey):  # <size nkey> beyond the <key> elements: MuJoCo's default keyframes
            keys[f"key{i}"] = (qpos0.copy(), np.zeros(nv))
        return keys

    def unit_quaternions(self, joints: list[Joint], qpos: np.ndarray) -> np.ndarray:
        """qpos with every ball and free quaternion made unit, as MuJoCo does before using it (noted)."""
        qpos, p = qpos.copy(), 0
        for joint in joints:
            start, width = {"free": (3, 7), "ball": (0, 4)}.get(joint.kind, (0, 1))
            if joint.kind in ("free", "ball"):
                quat = qpos[p + start:p + start + 4]
                norm = math.sqrt(float(quat @ quat))
                if norm == 0:
                    raise MJCFError(f"{self.root.file}: the initial quaternion of joint {joint.name!r} is zero")
                if abs(norm - 1) > 1e-12:
                    qpos[p + start:p + start + 4] = quat / norm
                    self.note(f"unit {joint.name}", f"joint {joint.name!r}: the initial quaternion (length {norm:.6g}) "
                                                    "made unit, as MuJoCo uses it")
            p += width
        return qpos

    def joints_at(self, joints: list[Joint], qpos: np.ndarray, qvel: np.ndarray) -> list[Joint]:
        """The joints with their initial state set from MuJoCo's qpos and qvel."""
        out, p, v = [], 0, 0
        bodies = {b.name: b for b in self.bodies}
        for joint in joints:
            if joint.kind == "free":
                quat = qpos[p + 3:p + 7]
                rotation = quat_matrix(quat / np.linalg.norm(quat))
                velocity = (tuple(qvel[v:v + 3].tolist()), tuple((rotation @ qvel[v + 3:v + 6]).tolist()))
                if not (np.array_equal(qpos[p:p + 3], bodies[joint.body].pos)
                        and np.array_equal(quat, bodies[joint.body].quat)):
                    self.note(f"free {joint.name}", f"free joint {joint.name!r} starts from the chosen state's "
                              "pose (qpos0), not the body's pos/quat")
                out.append(dataclasses.replace(joint, qvel0=velocity))
                p, v = p + 7, v + 6
            elif joint.kind == "ball":
                out.append(dataclasses.replace(joint, qpos0=tuple(qpos[p:p + 4].tolist()),
                                               qvel0=tuple(qvel[v:v + 3].tolist())))
                p, v = p + 4, v + 3
            else:
                out.append(dataclasses.replace(joint, qpos0=float(qpos[p]), qvel0=float(qvel[v])))
                p, v = p + 1, v + 1
        return out

    def layout(self, joints: list[Joint]) -> Layout:
        """Bodies in MuJoCo's order; a body with neither mass nor joints is folded into its parent."""
        kept: dict[int, tuple[str, np.ndarray, np.ndarray]] = {0: (WORLD, np.zeros(3), np.array([1.0, 0, 0, 0]))}
        # kept[index] = (rbody body that carries it, pos, quat of its frame in that body's frame)
        shapes: dict[str, list[Shape]] = {WORLD: []}
        bodies: list[Body] = []
        for geom in self.world.geoms:
            shapes[WORLD].extend(self.shapes_of(geom, np.zeros(3), np.array([1.0, 0, 0, 0])))
        for body in self.bodies:
            carrier, ppos, pquat = kept[body.parent.index]
            pos = ppos + quat_matrix(pquat) @ body.pos
            quat = quat_product(pquat, body.quat)
            if body.mass <= MJ_EPS and not body.joints:
                kept[body.index] = (carrier, pos, quat)
                self.note(f"fold {body.name}", f"body {body.name!r} has neither mass nor joints: folded into "
                                               f"{carrier!r}")
                for geom in body.geoms:
                    shapes[carrier].extend(self.shapes_of(geom, pos, quat))
                continue
            if body.mass <= MJ_EPS:
                raise body.element.error("the body has a joint but no mass")
            try:
                inertia = Inertia(body.mass, body.com, body.tensor)
            except ValueError as error:
                raise body.element.error(f"mass properties refused: {error}") from None
            kept[body.index] = (body.name, np.zeros(3), np.array([1.0, 0, 0, 0]))
            shapes[body.name] = []
            for geom in body.geoms:
                shapes[body.name].extend(self.shapes_of(geom, np.zeros(3), np.array([1.0, 0, 0, 0])))
            bodies.append(Body(body.name, inertia, parent=carrier, pos=tuple(pos.tolist()),
                               quat=tuple(quat.tolist()), gravcomp=self.gravcomp_of(body)))
        self.frames = kept
        bodies = [dataclasses.replace(b, shapes=tuple(shapes[b.name])) for b in bodies]
        self.carriers = kept
        return Layout(bodies=tuple(bodies), joints=tuple(joints), fixed=tuple(shapes[WORLD]), fluid=self.fluid())

    def fluid(self):
        """rbody.layout.Fluid of the model (rbody.mjcf.fluid), or None without density or viscosity."""
        from rbody.layout import Fluid, FluidBox, FluidEllipsoid
        from rbody.mjcf import fluid as mjcf_fluid

        if self.density <= 0 and self.viscosity <= 0:
            return None
        if not self.spring_on and not self.damper_on:
            self.note("fluid", "fluid forces ignored: <flag spring> and <flag damper> are both disabled, and MuJoCo "
                               "then applies no passive force at all")
            return None
        boxes, ellipsoids = [], []
        for body in self.bodies:
            if body.mass < MJ_MINVAL or self.frames[body.index][0] != body.name:
                continue  # massless (MuJoCo skips it; a folded body is massless)
            own = [g for g in body.geoms if g.ellipsoid]
            if not own:
                boxes.append(FluidBox(body.name, tuple(np.asarray(body.axes, dtype=np.float64).tolist())))
                continue
            for geom in own:
                axes = mjcf_fluid.semiaxes(geom.kind, geom.size)
                mass, inertia = mjcf_fluid.added_mass(axes)
                ellipsoids.append(FluidEllipsoid(body.name, tuple(geom.pos.tolist()), tuple(geom.quat.tolist()), axes,
                                                 mass, inertia,
                                                 mjcf_fluid.coefficients(geom.element, geom.attrib, numbers)))
        self.note("fluid forces", f"fluid forces as MuJoCo's (density {self.density:g}, viscosity {self.viscosity:g}): "
                                  f"{len(boxes)} bodies by the inertia box, "
                                  f"{len(ellipsoids)} geoms by the ellipsoid model")
        return Fluid(density=self.density, viscosity=self.viscosity, wind=tuple(self.wind.tolist()), boxes=tuple(boxes),
                     ellipsoids=tuple(ellipsoids))

    def shapes_of(self, geom: _Geom, pos: np.ndarray, quat: np.ndarray) -> list[Shape]:
        """The rbody Shape of a geom, in the frame (pos, quat) of the body that carries it."""
        gpos = pos + quat_matrix(quat) @ geom.pos
        gquat = quat_product(quat, geom.quat)
        common = dict(pos=tuple(gpos.tolist()), quat=tuple(gquat.tolist()))
        if geom.kind == "hfield":  # the asset's name rides in the geom's mesh field
            heights, size = self.hfields[geom.mesh]
            return [Shape(geom.name, "hfield", tuple(size.tolist()), heights=heights, **common)]
        if geom.kind == "mesh":  # a mesh that can collide carries its convex hull's vertices
            vertices = self.hull_vertices(geom) if geom.name in self.colliding else ()
            return [Shape(geom.name, "mesh", (), mesh=self.mesh_path(geom.mesh), vertices=vertices, **common)]
        count = {"sphere": 1, "capsule": 2, "cylinder": 2, "box": 3, "plane": 3, "ellipsoid": 3}[geom.kind]
        size = tuple(float(s) for s in geom.size[:count])
        if geom.kind == "plane":
            size = size[:2]
        return [Shape(geom.name, geom.kind, size, **common)]


def _state_vector(value, name: str, size: int) -> np.ndarray:
    try:
        array = np.asarray(value, dtype=float)
    except (TypeError, ValueError):
        raise MJCFError(f"{name}={value!r}: expected {size} numbers (MuJoCo's layout)") from None
    if array.shape != (size,) or not np.all(np.isfinite(array)):
        raise MJCFError(f"{name} has shape {array.shape}: expected ({size},) finite numbers in MuJoCo's layout")
    return array.copy()


# ----- public -------------------------------------------------------------------------------------------

def layout_from_mjcf(source, *, qpos0=None, qvel0=None, keyframe: int | str | None = None,
                     overlapping_geoms: str = "refuse") -> MJCFModel:
    """Read an MJCF model (a path or an XML string) into an MJCFModel (see the module docstring).

    qpos0 (nq,), qvel0 (nv,): the initial state in MuJoCo's layout (default the keyframe's, else the
    model's reference state at rest); keyframe: a <key>'s index or name.
    overlapping_geoms: "refuse" (MJCFError when two geoms of one body overlap) or "sum" (MuJoCo's sum).
    """
    if overlapping_geoms not in OVERLAP_CHOICES:
        raise MJCFError(f"overlapping_geoms={overlapping_geoms!r}: expected one of {OVERLAP_CHOICES}")
    root, folder = read_source(source)
    expand_includes(root, folder if folder is not None else Path.cwd(), (root.file,))
    reader = _Reader(root, folder, overlapping_geoms)
    reader.read()
    return reader.build(qpos0, qvel0, keyframe)


def from_mjcf(source, *, t_end: float | None = None, qpos0=None, qvel0=None, keyframe: int | str | None = None,
              overlapping_geoms: str = "refuse") -> "MJCFScene":
    """The Scene of an MJCF model (a path or an XML string), run natively by rbody's general engine.

    t_end: duration [s] (default DEFAULT_T_END = 1 s); qpos0, qvel0, keyframe, overlapping_geoms: as
    layout_from_mjcf. The scene is a TreeScene (Scene.from_layout) that also carries import_notes (what
    was ignored), timestep and integrator (the model's option) and the declared joint limits.
    """
    model = layout_from_mjcf(source, qpos0=qpos0, qvel0=qvel0, keyframe=keyframe,
                             overlapping_geoms=overlapping_geoms)
    return MJCFScene(name=model.name, t_end=DEFAULT_T_END if t_end is None else t_end, gravity=model.gravity,
                     tree=model.layout, qpos0=model.qpos0, qvel0=model.qvel0, import_notes=model.notes,
                     timestep=model.timestep, integrator=model.integrator, limits=dict(model.limits),
                     act0=model.act0, ctrl0=model.ctrl0)


@dataclass(frozen=True, kw_only=True, eq=False)
class MJCFScene(TreeScene):
    """Scene.from_layout's TreeScene of a model read from MJCF, with its declared joint limits.

    limits: joint name -> (lo, hi) [rad | m] (ball joints: (0, largest rotation angle) [rad]), the ranges its
    joints hold (Joint.range; rbody.engine.constraints holds them rigidly). limit_violation tells where a run of
    any engine leaves them (MuJoCo's soft limits let a joint pass its stop).
    """

    limits: Mapping[str, tuple[float, float]] = field(default_factory=dict)

    @property
    def file_method(self) -> str:
        """The rbody method that is the model's own <option integrator> (MuJoCo's Euler: "mujoco_euler"; RK4:
        "rk4"; implicit, implicitfast: the same names): simulate(scene, dt=scene.timestep, method=scene.file_method)
        runs the file as MuJoCo runs it."""
        return FILE_METHODS[self.integrator or "Euler"]

    def limit_violation(self, t: np.ndarray, qpos: np.ndarray) -> str:
        """The first place a run leaves a declared range: qpos (T, ..., nq) at times t (T,) [s] from any engine;
        a message naming the joint, its range, the time and the value, or "" when every coordinate stays inside
        (ball joints: the rotation angle 2 atan2(|v|, |w|) of their quaternion)."""
        arrays = self.multibody.arrays
        qpos = np.asarray(qpos)
        for name, (low, high) in self.limits.items():
            j = arrays.joint_names.index(name)
            address = int(arrays.qposadr[j])
            if arrays.joint_kinds[j] == "ball":
                quat = qpos[..., address:address + 4]
                value = 2 * np.arctan2(np.linalg.norm(quat[..., 1:], axis=-1), np.abs(quat[..., 0]))
            else:
                value = qpos[..., address]
            outside = (value < low) | (value > high)
            if np.any(outside):
                step = int(np.argmax(np.any(outside.reshape(len(t), -1), axis=1)))
                found = float(np.ravel(value[step])[np.argmax(np.ravel(outside[step]))])
                return (f"joint {name!r} left its range [{low:.6g}, {high:.6g}] at t={t[step]:.6g} s (value "
                        f"{found:.6g})")
        return ""
