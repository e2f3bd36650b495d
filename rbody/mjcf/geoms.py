"""Mass properties of MJCF geoms and bodies, formed as MuJoCo's compiler forms them.

The formulas follow MuJoCo's compiler (src/user/user_objects.cc: mjCGeom::GetVolume, mjCGeom::SetInertia,
mjCBody::InertiaFromGeom; src/user/user_mesh.cc: mjCMesh::Process, ComputeVolume, ComputeInertia), so that
the compiled body_mass, body_ipos and body_inertia (with body_iquat) come out the same to round-off:

- a geom's mass is its `mass`, or density x volume (density 1000 kg/m^3 by default); with
  shellinertia="true" the "volume" is the surface area and the density is per area;
- primitives, in the geom frame (z the axis of capsules and cylinders; h = 2 size[1] the cylinder height):
  sphere 2/5 m r^2; cylinder m (3 r^2 + h^2)/12 across, m r^2/2 along; box m (b^2 + c^2)/3 with half
  sizes; ellipsoid m (b^2 + c^2)/5; capsule: the cylinder plus two hemispheres of the volume's share
  of mass, m_s (2 r^2/5 + h (3 r + 2 h)/8) across (the hemisphere centroids 3r/8 beyond the ends);
  shells as MuJoCo (thin surfaces; the ellipsoid shell is MuJoCo's difference of two solids 1e-6 apart);
- meshes: vertices rounded to float32 (MuJoCo stores them so), then refpos, refquat and scale applied;
  the volume is summed over pyramids from the area-weighted face centroid, signed ("exact", "convex":
  the convex hull's faces) or each taken positive ("legacy", MuJoCo's default, wrong for non-convex
  meshes), or the surface with areal density ("shell");
- a body's mass properties: one geom is copied; several are summed about their common centre of mass
  (parallel-axis theorem). Only geoms whose group lies in the compiler's inertiagrouprange and whose
  mass exceeds 1e-14 kg count.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from rbody.mjcf.frames import quat_matrix, quat_product, unit

MJ_MINVAL = 1e-15   # mjMINVAL

MESH_INERTIA_MODES = ("legacy", "exact", "convex", "shell")


def primitive_volume(kind: str, size, shell: bool = False) -> float:
    """Volume [m^3] of a primitive geom (surface area [m^2] with shell=True); size as in MJCF [m]."""
    pi = math.pi
    if kind == "sphere":
        r = size[0]
        return 4 * pi * r * r if shell else 4 * pi * r * r * r / 3
    if kind == "capsule":
        r, height = size[0], 2 * size[1]
        return 4 * pi * r * r + 2 * pi * r * height if shell else pi * (r * r * height + 4 * r * r * r / 3)
    if kind == "cylinder":
        r, height = size[0], 2 * size[1]
        return 2 * pi * r * r + 2 * pi * r * height if shell else pi * r * r * height
    if kind == "ellipsoid":
        if shell:  # Thomsen's approximation, as MuJoCo
            p = 1.6075
            total = (size[0] * size[1]) ** p + (size[1] * size[2]) ** p + (size[2] * size[0]) ** p
            return 4 * pi * (total / 3) ** (1 / p)
        return 4 * pi * size[0] * size[1] * size[2] / 3
    if kind == "box":
        if shell:
            return 8 * (size[0] * size[1] + size[1] * size[2] + size[2] * size[0])
        return size[0] * size[1] * size[2] * 8
    return 0.0  # plane


def primitive_moments(kind: str, size, mass: float, shell: bool = False) -> np.ndarray:
    """(3,) principal moments [kg m^2] of a primitive geom of `mass` about its centre, geom axes."""
    if kind == "sphere":
        moment = 2 * mass * size[0] ** 2 / (3 if shell else 5)
        return np.array([moment, moment, moment])
    if kind == "capsule":
        r, half = size[0], size[1]
        height = 2 * half
        if not shell:
            sphere_mass = mass * 4 * r / (4 * r + 3 * height)   # the hemispheres' share of the volume
            cylinder_mass = mass - sphere_mass
            across = cylinder_mass * (3 * r * r + height * height) / 12
            along = cylinder_mass * r * r / 2
            sphere = 2 * sphere_mass * r * r / 5
            across += sphere + sphere_mass * height * (3 * r + 2 * height) / 8
            return np.array([across, across, along + sphere])
        a_sphere, a_cylinder = 4 * math.pi * r * r, 2 * math.pi * r * height
        sphere_mass = mass * a_sphere / (a_sphere + a_cylinder)
        cylinder_mass = mass - sphere_mass
        across = cylinder_mass * (6 * r * r + height * height) / 12
        along = cylinder_mass * r * r
        sphere = 2 * sphere_mass * r * r / 3
        centroid = r / 2
        offset = half + centroid
        across += sphere + sphere_mass * (offset * offset - centroid * centroid)
        return np.array([across, across, along + sphere])
    if kind == "cylinder":
        r, half = size[0], size[1]
        height = 2 * half
        if not shell:
            across = mass * (3 * r * r + height * height) / 12
            return np.array([across, across, mass * r * r / 2])
        a_disk, a_cylinder = math.pi * r * r, 2 * math.pi * r * height
        disk_mass = mass * a_disk / (2 * a_disk + a_cylinder)
        tube_mass = mass - 2 * disk_mass
        across = tube_mass * (6 * r * r + height * height) / 12 + 2 * (disk_mass * r * r / 4 + disk_mass * half * half)
        along = tube_mass * r * r + 2 * (disk_mass * r * r / 2)
        return np.array([across, across, along])
    if kind == "ellipsoid":
        s00, s11, s22 = (size[i] * size[i] for i in range(3))
        if not shell:
            return np.array([mass * (s11 + s22) / 5, mass * (s00 + s22) / 5, mass * (s00 + s11) / 5])
        eps = 1e-6
        va = 4 * math.pi * size[0] * size[1] * size[2] / 3
        ae, be, ce = size[0] + eps, size[1] + eps, size[2] + eps
        vb = 4 * math.pi * ae * be * ce / 3
        density = mass / (vb - va)
        ma, mb = va * density, vb * density
        inner = np.array([ma * (s11 + s22) / 5, ma * (s00 + s22) / 5, ma * (s00 + s11) / 5])
        outer = np.array([mb * (be * be + ce * ce) / 5, mb * (ae * ae + ce * ce) / 5, mb * (ae * ae + be * be) / 5])
        return outer - inner
    if kind == "box":
        s00, s11, s22 = (size[i] * size[i] for i in range(3))
        if not shell:
            return np.array([mass * (s11 + s22) / 3, mass * (s00 + s22) / 3, mass * (s00 + s11) / 3])
        lx, ly, lz = 2 * size[0], 2 * size[1], 2 * size[2]
        a0, a1, a2 = lx * ly, ly * lz, lz * lx
        total = 2 * (a0 + a1 + a2)
        m0, m1, m2 = mass * a0 / total, mass * a1 / total, mass * a2 / total
        ix = m0 * ly * ly / 12 + m1 * (ly * ly + lz * lz) / 12 + m2 * lz * lz / 12
        iy = m0 * lx * lx / 12 + m1 * lz * lz / 12 + m2 * (lx * lx + lz * lz) / 12
        iz = m0 * (lx * lx + ly * ly) / 12 + m1 * ly * ly / 12 + m2 * lx * lx / 12
        return np.array([2 * (m0 * s22 + m2 * s11 + ix), 2 * (m0 * s22 + m1 * s00 + iy),
                         2 * (m1 * s00 + m2 * s11 + iz)])
    return np.zeros(3)


# ----- meshes ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class MeshMass:
    """Mass properties of a mesh asset per unit density, in the mesh's own frame (after scale etc.).

    volume:   volume [m^3] (area [m^2] for inertia="shell"), as MuJoCo holds it
    com:      (3,) centre of mass [m]
    tensor:   (3,3) inertia tensor per unit density about com [m^5 | m^4]
    vertices: (V, 3) vertices [m] (float32-rounded, transformed); faces (F, 3) the triangles used
    """

    volume: float
    com: np.ndarray
    tensor: np.ndarray
    vertices: np.ndarray
    faces: np.ndarray

    def principal(self) -> tuple[np.ndarray, np.ndarray]:
        """(moments (3,) per unit density, quat (4,)): the mesh frame MuJoCo moves the mesh to."""
        return mujoco_principal(self.tensor, MESH_EIG_RTOL)

    def inertia_box(self) -> list[float]:
        """Half sizes [m] of MuJoCo's equivalent inertia box (boxsz): the box of the mesh's volume and principal
        moments I, along its principal axes, 0.5 sqrt(6 (I_j + I_k - I_i) / V)."""
        eig = self.principal()[0]
        return [0.5 * math.sqrt(6 * (eig[1] + eig[2] - eig[0]) / self.volume),
                0.5 * math.sqrt(6 * (eig[0] + eig[2] - eig[1]) / self.volume),
                0.5 * math.sqrt(6 * (eig[0] + eig[1] - eig[2]) / self.volume)]

    def moments(self, mass: float) -> np.ndarray:
        """(3,) principal moments [kg m^2] of the mesh with `mass`, by MuJoCo's equivalent inertia box."""
        box = self.inertia_box()
        return np.array([mass * (box[1] ** 2 + box[2] ** 2) / 3, mass * (box[0] ** 2 + box[2] ** 2) / 3,
                         mass * (box[0] ** 2 + box[1] ** 2) / 3])

    def principal_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(centre (3,), half sizes (3,)) [m] of the vertices' axis-aligned box in the mesh's principal frame (the
        frame principal() gives, at com): MuJoCo's aamm."""
        rotation = quat_matrix(self.principal()[1])
        local = (self.vertices - self.com) @ rotation      # each row R^T (v - com)
        low, high = local.min(axis=0), local.max(axis=0)
        centre = (low + high) / 2
        return centre, high - centre


FITTED_KINDS = ("sphere", "capsule", "cylinder", "ellipsoid", "box")


def fitted_size(kind: str, mesh: MeshMass, aabb: bool, fitscale: float) -> tuple[np.ndarray, np.ndarray]:
    """MuJoCo's primitive fitted to a mesh (mjCMesh::FitGeom): (size (3,) [m], centre (3,) [m] of the primitive in
    the mesh's principal frame).

    aabb False (compiler fitaabb="false", MuJoCo's default): from the equivalent inertia box b, centred at the
    centre of mass: a sphere of radius (b0 + b1 + b2)/3, a capsule of radius r = (b0 + b1)/2 and half length
    max(0, b2 - r/2), a cylinder (b0 + b1)/2 and b2, a box or an ellipsoid b. aabb True: the smallest primitive whose
    own box holds the vertices' box a in the principal frame, centred on it: a sphere max(a), a cylinder max(a0, a1)
    and a2, a capsule the same with its cap taken off the length, a box or an ellipsoid a. Every size times fitscale.
    """
    if kind not in FITTED_KINDS:
        raise ValueError(f"a {kind} cannot be fitted to a mesh: MuJoCo fits a {', '.join(FITTED_KINDS)}")
    size, centre = np.zeros(3), np.zeros(3)
    if not aabb:
        box = mesh.inertia_box()
        if kind == "sphere":
            size[0] = (box[0] + box[1] + box[2]) / 3
        elif kind in ("capsule", "cylinder"):
            size[0] = (box[0] + box[1]) / 2
            size[1] = max(0.0, box[2] - size[0] / 2) if kind == "capsule" else box[2]
        else:
            size[:] = box
    else:
        centre, half = mesh.principal_bounds()
        if kind == "sphere":
            size[0] = max(half)
        elif kind in ("capsule", "cylinder"):
            size[0] = max(half[0], half[1])
            size[1] = half[2] - size[0] if kind == "capsule" else half[2]
        else:
            size[:] = half
    return size * fitscale, centre


def _triangles(vertices: np.ndarray, faces: np.ndarray):
    """Per face: area (F,), unit normal (F, 3) (0 for a degenerate face), centre (F, 3)."""
    a, b, c = vertices[faces[:, 0]], vertices[faces[:, 1]], vertices[faces[:, 2]]
    cross = np.cross(b - a, c - a)
    length = np.linalg.norm(cross, axis=1)
    normal = np.divide(cross, length[:, None], out=np.zeros_like(cross), where=length[:, None] > 0)
    return length / 2, normal, (a + b + c) / 3


def mesh_mass(vertices: np.ndarray, faces: np.ndarray, *, mode: str = "legacy", scale=(1.0, 1.0, 1.0),
              refpos=(0.0, 0.0, 0.0), refquat=(1.0, 0.0, 0.0, 0.0)) -> MeshMass:
    """MuJoCo's mesh volume, centre of mass and inertia per unit density (mjCMesh::Process).

    vertices: (V, 3) as read from the file [m]; faces: (F, 3) vertex indices (F = 0: the convex hull)
    mode: "legacy" | "exact" | "convex" | "shell". Raises ValueError where MuJoCo refuses the mesh.
    """
    vert = np.asarray(vertices, dtype=np.float32).astype(np.float64)   # MuJoCo keeps float vertices
    faces = np.asarray(faces, dtype=np.int64).reshape(-1, 3)
    if len(vert) < 4:
        raise ValueError(f"mesh has {len(vert)} vertices: MuJoCo needs at least 4")
    if faces.size == 0 or mode == "convex":
        from scipy.spatial import ConvexHull

        hull = ConvexHull(vert)
        hull_faces = hull.simplices.copy()
        # orient every hull triangle outwards (its normal away from the hull's interior point)
        inside = vert[hull.vertices].mean(axis=0)
        a, b, c = (vert[hull_faces[:, i]] for i in range(3))
        flip = np.einsum("ij,ij->i", np.cross(b - a, c - a), a - inside) < 0
        hull_faces[flip] = hull_faces[flip][:, [0, 2, 1]]
        if faces.size == 0:
            faces = hull_faces
    else:
        hull_faces = None
    if np.prod(scale) < 0:  # a mirrored mesh: MuJoCo flips the winding
        faces = faces[:, [0, 2, 1]]
        if hull_faces is not None:
            hull_faces = hull_faces[:, [0, 2, 1]]
    refpos, refquat, scale = (np.asarray(v, dtype=float) for v in (refpos, refquat, scale))
    if np.any(refpos != 0):
        vert = vert - refpos
    if not np.array_equal(refquat, [1.0, 0.0, 0.0, 0.0]):
        norm = math.sqrt(float(refquat @ refquat))
        vert = vert @ quat_matrix(refquat / norm)   # v -> R^T v, MuJoCo's mulvecmatT
    if np.any(scale != 1):
        vert = vert * scale

    area, _normal, centre = _triangles(vert, faces)
    total_area = float(area.sum())
    if total_area < MJ_MINVAL:
        raise ValueError("mesh surface area is too small")
    facecen = (area @ centre) / total_area
    used = hull_faces if mode == "convex" else faces

    if mode == "shell":
        volumes = area
    else:
        area_u, normal_u, centre_u = _triangles(vert, used)
        volumes = np.einsum("ij,ij->i", centre_u - facecen, normal_u) * area_u / 3
        if mode == "legacy":
            volumes = np.abs(volumes)
        centre = centre_u
    total = float(volumes.sum())
    if total < MJ_MINVAL:
        if total < 0:
            raise ValueError("mesh volume is negative (misoriented triangles)")
        raise ValueError("mesh volume is too small; try inertia=\"shell\"")
    com = (volumes @ (centre * 0.75 + facecen * 0.25)) / total

    # second moments about com, each face as a pyramid (shell: a triangle), MuJoCo's ComputeInertia
    local = vert - com
    d, e, f = local[used[:, 0]], local[used[:, 1]], local[used[:, 2]]
    area_c, normal_c, centre_c = _triangles(local, used)
    if mode == "shell":
        weights, divisor = area_c, 12.0
    else:
        weights = np.einsum("ij,ij->i", centre_c, normal_c) * area_c / 3
        if mode == "legacy":
            weights = np.abs(weights)
        divisor = 20.0
    products = np.zeros((3, 3))
    for i in range(3):
        for j in range(3):
            products[i, j] = weights @ (2 * (d[:, i] * d[:, j] + e[:, i] * e[:, j] + f[:, i] * f[:, j])
                                        + d[:, i] * e[:, j] + d[:, j] * e[:, i] + d[:, i] * f[:, j]
                                        + d[:, j] * f[:, i] + e[:, i] * f[:, j] + e[:, j] * f[:, i]) / divisor
    volume = float(weights.sum())
    tensor = np.trace(products) * np.eye(3) - products
    tensor = 0.5 * (tensor + tensor.T)
    eigen = np.linalg.eigvalsh(tensor)
    if eigen[-1] <= 0:
        raise ValueError("mesh inertia has no positive eigenvalue")
    if eigen[0] + eigen[1] < eigen[2] * (1 - 1e-6) - 1e-9:
        raise ValueError("mesh inertia violates A + B >= C")
    return MeshMass(volume, com, tensor, vert, used)


# ----- bodies ---------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class GeomMass:
    """One geom's contribution: mass [kg], pos (3,) its centre of mass in the body frame [m], tensor (3,3)
    about it in body axes [kg m^2]."""

    name: str
    mass: float
    pos: np.ndarray
    tensor: np.ndarray


def offcenter(mass: float, offset: np.ndarray) -> np.ndarray:
    """(3,3) parallel-axis term m (|d|^2 1 - d d^T) (MuJoCo's mjuu_offcenter)."""
    d = np.asarray(offset, dtype=float)
    return mass * (float(d @ d) * np.eye(3) - np.outer(d, d))


def sum_geoms(parts: list[GeomMass]) -> tuple[float, np.ndarray, np.ndarray]:
    """(mass [kg], com (3,) [m], tensor (3,3) about com [kg m^2]) of several geoms (mjCBody::InertiaFromGeom)."""
    if len(parts) == 1:
        return parts[0].mass, parts[0].pos, parts[0].tensor
    mass = sum(p.mass for p in parts)
    com = sum(p.mass * p.pos for p in parts) / mass
    tensor = sum(p.tensor + offcenter(p.mass, p.pos - com) for p in parts)
    return mass, com, tensor


# ----- MuJoCo's principal axes ------------------------------------------------------------------------------

EIG_RTOL = 4e-15    # MuJoCo's Jacobi solver stops when the off-diagonal is below this fraction of the largest entry
MESH_EIG_RTOL = 1e-7    # ... looser for a mesh's own principal axes (mujoco 4.0, measured: between 3e-8 and 3e-7)
EIG_SORT_RTOL = 1e-12  # ... and swaps two eigenvalues only when they differ by more than this fraction


def mujoco_principal(tensor: np.ndarray, rtol: float = EIG_RTOL) -> tuple[np.ndarray, np.ndarray]:
    """(moments (3,) descending, quat (4,)) of a symmetric (3,3) tensor as MuJoCo's compiler finds them
    (mjuu_eig3 of mujoco 4: Jacobi rotations accumulated as a quaternion until the largest off-diagonal
    element is below 4e-15 of the largest entry; the eigenvalues then bubble-sorted (0, 1, 0), swapping
    only values 1e-12 (relative) apart, each swap a quarter turn of the quaternion).

    MuJoCo's compiled body_inertia and body_iquat are these, for a body of several geoms, a fullinertia
    and a mesh; rbody takes the same decomposition so that both engines hold the same tensor.
    """
    mat = np.asarray(tensor, dtype=float)
    scale = float(np.max(np.abs(mat)))
    quat = np.array([1.0, 0.0, 0.0, 0.0])
    eigval = np.zeros(3)
    for _ in range(500):
        vectors = quat_matrix(quat)
        d = (vectors.T @ mat) @ vectors
        eigval = np.array([d[0, 0], d[1, 1], d[2, 2]])
        if abs(d[0, 1]) > abs(d[0, 2]) and abs(d[0, 1]) > abs(d[1, 2]):
            rk, ck, rotk = 0, 1, 2
        elif abs(d[0, 2]) > abs(d[1, 2]):
            rk, ck, rotk = 0, 2, 1
        else:
            rk, ck, rotk = 1, 2, 0
        if abs(d[rk, ck]) <= scale * max(rtol, EIG_RTOL):
            break
        tau = (d[ck, ck] - d[rk, rk]) / (2 * d[rk, ck])
        t = 1.0 / (tau + math.sqrt(1 + tau * tau)) if tau >= 0 else -1.0 / (-tau + math.sqrt(1 + tau * tau))
        h = t / (1.0 + math.sqrt(1.0 + t * t))      # tan of half the rotation angle
        turn = np.zeros(4)
        turn[0] = 1.0 / math.sqrt(1.0 + h * h)
        turn[rotk + 1] = (h if rotk == 1 else -h) * turn[0]
        quat = unit(quat_product(quat, turn))
    eps = scale * max(rtol, EIG_SORT_RTOL)
    for j in range(3):
        lead = j % 2
        if eigval[lead] + eps < eigval[lead + 1]:
            eigval[lead], eigval[lead + 1] = eigval[lead + 1], eigval[lead]
            turn = np.zeros(4)
            turn[0] = 0.707106781186548
            turn[(lead + 2) % 3 + 1] = turn[0]
            quat = unit(quat_product(quat, turn))
    return eigval, quat


def principal_tensor(moments: np.ndarray, quat: np.ndarray) -> np.ndarray:
    """(3,3) R diag(moments) R^T, R the rotation of quat."""
    rotation = quat_matrix(quat)
    tensor = rotation @ np.diag(moments) @ rotation.T
    return 0.5 * (tensor + tensor.T)
