"""URDF geometry: <visual> and <collision> elements as rbody Shapes, mesh files found through package://,
file:// and relative paths, and package_dirs and ROS_PACKAGE_PATH."""

from __future__ import annotations

import os
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from rbody.layout import Shape
from rbody.urdf.document import Element, rpy_quaternion

PRIMITIVES = ("box", "cylinder", "sphere", "capsule", "mesh")
# Mesh formats MuJoCo compiles (rbody.to_mjcf writes mesh shapes as MuJoCo <mesh file>): a collision mesh in
# another format (.dae) is kept for drawing only, with a note.
MUJOCO_MESH_SUFFIXES = (".stl", ".obj", ".msh")


@dataclass(frozen=True)
class Geometry:
    """One <visual> or <collision> of a link: its Shape in the link frame, and what the importer noted."""

    shape: Shape
    collision: bool
    element: Element


def package_roots(package_dirs) -> list[Path]:
    """Folders searched for package://NAME/...: package_dirs (a folder or a list of them), then the folders of
    the environment variable ROS_PACKAGE_PATH (separated by os.pathsep)."""
    if package_dirs is None:
        dirs: list = []
    elif isinstance(package_dirs, (str, os.PathLike)):
        dirs = [package_dirs]
    else:
        dirs = list(package_dirs)
    for entry in os.environ.get("ROS_PACKAGE_PATH", "").split(os.pathsep):
        if entry:
            dirs.append(entry)
    return [Path(d) for d in dirs]


def resolve_mesh(element: Element, filename: str, folder: Path | None, package_dirs) -> Path:
    """The absolute path of a mesh `filename`: package://NAME/REST looked up as ROOT/NAME/REST, ROOT/REST when ROOT
    is itself the folder NAME, and ROOT/*/NAME/REST, for each root of package_roots; file://PATH; a relative path
    from the URDF's folder (the working folder for an XML string). URDFError naming the element and the places
    looked in when no file is there."""
    if filename.startswith("package://"):
        rest = filename[len("package://"):].lstrip("/")  # package:///NAME/... is read as package://NAME/...
        package, _, inside = rest.partition("/")
        if not package or not inside:
            raise element.error(f"filename={filename!r}: expected package://PACKAGE/PATH")
        roots = package_roots(package_dirs)
        tried = []
        for root in roots:
            candidates = [root / package / inside]
            if root.name == package:
                candidates.append(root / inside)
            if root.is_dir():
                candidates += [sub / package / inside for sub in sorted(root.iterdir()) if sub.is_dir()]
            for candidate in candidates:
                tried.append(str(candidate))
                if candidate.is_file():
                    return candidate.resolve()
        where = (f"looked in {', '.join(tried[:6])}{' ...' if len(tried) > 6 else ''}" if tried else
                 "no package_dirs given and ROS_PACKAGE_PATH is empty")
        raise element.error(f"mesh {filename!r} not found ({where}): pass package_dirs=[folder that holds the "
                            f"package {package!r}]")
    path = Path(filename[len("file://"):]) if filename.startswith("file://") else Path(filename)
    if not path.is_absolute():
        path = (folder if folder is not None else Path.cwd()) / path
    if not path.is_file():
        raise element.error(f"mesh file {filename!r} not found (looked for {str(path)!r})")
    return path.resolve()


def read_geometry(element: Element, name: str, collision: bool, folder: Path | None, package_dirs,
                  notes: list[str]) -> Geometry:
    """The Shape of one <visual> or <collision> (named `name`), in its link's frame."""
    known = {"origin": None, "geometry": None, "material": "visual and collision materials ignored (appearance only)"}
    if collision:
        known["verbose"] = "collisions' <verbose> ignored (a planner's display flag)"
    element.check_children(known, notes)
    origin = element.one("origin")
    pos = origin.numbers("xyz", 3, (0.0, 0.0, 0.0)) if origin is not None else np.zeros(3)
    quat = rpy_quaternion(origin.numbers("rpy", 3, (0.0, 0.0, 0.0))) if origin is not None else np.array([1.0, 0, 0, 0])
    geometry = element.one("geometry", required=True)
    if len(geometry.children) != 1 or geometry.children[0].tag not in PRIMITIVES:
        found = [f"<{c.tag}>" for c in geometry.children] or ["nothing"]
        raise geometry.error(f"<geometry> holds {', '.join(found)}: expected one of "
                             f"{', '.join(f'<{p}>' for p in PRIMITIVES)}")
    primitive = geometry.children[0]
    kind = primitive.tag
    common = dict(pos=tuple(pos.tolist()), quat=tuple(quat.tolist()))
    if kind == "mesh":
        path = resolve_mesh(primitive, primitive.text_attribute("filename"), folder, package_dirs)
        scale = primitive.numbers("scale", 3, (1.0, 1.0, 1.0))
        if np.any(scale != 1.0):
            note = "mesh scale ignored (rbody's mesh shapes carry no scale; meshes only draw here, no mass comes " \
                   "from them)"
            if note not in notes:
                notes.append(note)
        return Geometry(Shape(name, "mesh", (), mesh=str(path), **common), collision, element)
    if kind == "box":
        size = primitive.numbers("size", 3) / 2
    elif kind == "sphere":
        size = np.array([primitive.number("radius")])
    else:  # cylinder, capsule (MuJoCo's and Bullet's extension): radius and length along the local z
        size = np.array([primitive.number("radius"), primitive.number("length") / 2])
        if kind == "capsule":
            note = "<capsule> geometry read (not standard URDF: MuJoCo's and Bullet's extension)"
            if note not in notes:
                notes.append(note)
    if np.any(size <= 0):
        raise primitive.error(f"a {kind} needs sizes > 0 (got {' '.join(f'{k}={v!r}' for k, v in primitive.attrib.items())})")
    return Geometry(Shape(name, kind, tuple(size.tolist()), **common), collision, element)
