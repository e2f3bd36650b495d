"""Do two geoms of one body overlap? (MuJoCo sums geom masses, so overlapping solids count twice.)

Decided exactly, up to round-off (a shared face or a touching point is no overlap), for spheres and boxes
(the separating-axis theorem) and for capsules against spheres and capsules (segment distances);
conservatively for everything else: bounding boxes that do not intersect mean no overlap; otherwise
a regular grid of points over the intersection of their bounding boxes, one inside both (its winding
number) proves an overlap, and when none is the answer is "may overlap" (refused too: rbody cannot rule it out).
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

TOUCH_RTOL = 1e-9      # overlaps thinner than this fraction of the solids' size are touching (round-off)
GRID = 16              # grid points per axis for the conservative check


@dataclass(frozen=True)
class Solid:
    """A geom in the body frame: kind, size (MJCF's, half sizes), pos (3,), rotation (3,3) geom -> body;
    meshes: vertices (V, 3) in the body frame and faces (F, 3)."""

    kind: str
    size: np.ndarray
    pos: np.ndarray
    rotation: np.ndarray
    vertices: np.ndarray | None = None
    faces: np.ndarray | None = None

    def box(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Bounding box: centre (3,), axes (3,3) columns, half sizes (3,)."""
        r, h = self.size[0], self.size[1]
        if self.kind == "mesh":
            low, high = self.vertices.min(axis=0), self.vertices.max(axis=0)
            return (low + high) / 2, np.eye(3), (high - low) / 2
        half = {"sphere": (r, r, r), "capsule": (r, r, h + r), "cylinder": (r, r, h),
                "ellipsoid": tuple(self.size[:3]), "box": tuple(self.size[:3])}[self.kind]
        return self.pos, self.rotation, np.array(half, dtype=float)

    def scale(self) -> float:
        return float(np.max(self.box()[2]))

    def trimesh(self):
        import trimesh

        if self.kind == "mesh":
            return trimesh.Trimesh(self.vertices, self.faces, process=False)
        r, h = self.size[0], self.size[1]
        if self.kind == "sphere":
            mesh = trimesh.creation.icosphere(4, radius=r)
        elif self.kind == "capsule":
            mesh = trimesh.creation.capsule(height=2 * h, radius=r, count=[32, 32])
        elif self.kind == "cylinder":
            mesh = trimesh.creation.cylinder(radius=r, height=2 * h, sections=64)
        elif self.kind == "ellipsoid":
            mesh = trimesh.creation.icosphere(4, radius=1.0)
            mesh.apply_scale(self.size[:3])
        else:
            mesh = trimesh.creation.box(extents=2 * np.asarray(self.size[:3]))
        transform = np.eye(4)
        transform[:3, :3], transform[:3, 3] = self.rotation, self.pos
        mesh.apply_transform(transform)
        return mesh


def _boxes_overlap(a: tuple, b: tuple, tol: float) -> bool:
    """Separating-axis theorem for two oriented boxes (centre, axes, half sizes): True when every one of
    the 15 axes shows an overlap deeper than tol."""
    ca, ra, ha = a
    cb, rb, hb = b
    axes = [ra[:, i] for i in range(3)] + [rb[:, i] for i in range(3)]
    axes += [np.cross(ra[:, i], rb[:, j]) for i in range(3) for j in range(3)]
    d = cb - ca
    for axis in axes:
        norm = np.linalg.norm(axis)
        if norm < 1e-12:
            continue
        axis = axis / norm
        reach = np.sum(ha * np.abs(ra.T @ axis)) + np.sum(hb * np.abs(rb.T @ axis))
        if abs(d @ axis) >= reach - tol:
            return False
    return True


def _point_box_distance(point: np.ndarray, box: tuple) -> float:
    centre, axes, half = box
    local = axes.T @ (point - centre)
    return float(np.linalg.norm(np.maximum(np.abs(local) - half, 0.0)))


def _segment(solid: Solid) -> tuple[np.ndarray, np.ndarray]:
    axis = solid.rotation[:, 2] * solid.size[1]
    return solid.pos - axis, solid.pos + axis


def _point_segment_distance(point, a, b) -> float:
    ab = b - a
    t = np.clip((point - a) @ ab / (ab @ ab), 0.0, 1.0)
    return float(np.linalg.norm(point - (a + t * ab)))


def _segment_distance(p1, q1, p2, q2) -> float:
    """Least distance between segments p1q1 and p2q2 (Ericson, Real-Time Collision Detection 5.1.9)."""
    d1, d2, r = q1 - p1, q2 - p2, p1 - p2
    a, e, f = d1 @ d1, d2 @ d2, d2 @ r
    c, b = d1 @ r, d1 @ d2
    denom = a * e - b * b
    s = np.clip((b * f - c * e) / denom, 0.0, 1.0) if denom > 1e-15 * a * e else 0.0
    t = (b * s + f) / e
    if t < 0:
        t, s = 0.0, np.clip(-c / a, 0.0, 1.0)
    elif t > 1:
        t, s = 1.0, np.clip((b - c) / a, 0.0, 1.0)
    return float(np.linalg.norm((p1 + d1 * s) - (p2 + d2 * t)))


def _contains(mesh, points: np.ndarray) -> np.ndarray:
    """(Q,) True where points (Q, 3) lie inside the closed mesh: winding number above 1/2."""
    from rbody.mesh import _winding_number

    return _winding_number(points, np.asarray(mesh.vertices)[np.asarray(mesh.faces)]) > 0.5


def overlapping(a: Solid, b: Solid) -> str:
    """"" when the solids do not overlap (or only touch); otherwise a phrase saying how they overlap."""
    tol = TOUCH_RTOL * max(a.scale(), b.scale())
    kinds = {a.kind, b.kind}
    if a.kind == "box" and b.kind == "box":
        return "overlap" if _boxes_overlap(a.box(), b.box(), tol) else ""
    if kinds == {"sphere"}:
        gap = np.linalg.norm(a.pos - b.pos) - a.size[0] - b.size[0]
        return "overlap" if gap < -tol else ""
    if kinds == {"sphere", "box"}:
        sphere, box = (a, b) if a.kind == "sphere" else (b, a)
        return "overlap" if _point_box_distance(sphere.pos, box.box()) < sphere.size[0] - tol else ""
    if kinds == {"sphere", "capsule"}:
        sphere, capsule = (a, b) if a.kind == "sphere" else (b, a)
        gap = _point_segment_distance(sphere.pos, *_segment(capsule)) - sphere.size[0] - capsule.size[0]
        return "overlap" if gap < -tol else ""
    if kinds == {"capsule"}:
        gap = _segment_distance(*_segment(a), *_segment(b)) - a.size[0] - b.size[0]
        return "overlap" if gap < -tol else ""
    if not _boxes_overlap(a.box(), b.box(), tol):
        return ""
    # a regular grid over the intersection of the two axis-aligned bounding boxes: a point inside both
    # solids proves a common volume
    mesh_a, mesh_b = a.trimesh(), b.trimesh()
    low = np.maximum(mesh_a.bounds[0], mesh_b.bounds[0])
    high = np.minimum(mesh_a.bounds[1], mesh_b.bounds[1])
    if np.all(high - low > tol):
        axes = [np.linspace(lo, hi, GRID + 2)[1:-1] for lo, hi in zip(low, high)]
        points = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
        inside = _contains(mesh_a, points)
        if np.any(inside) and np.any(_contains(mesh_b, points[inside])):
            return "overlap"
    return "may overlap (their bounding boxes intersect and rbody cannot rule out a common volume)"
