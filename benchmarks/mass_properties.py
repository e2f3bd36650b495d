"""Mass properties of the built-in primitives against their formulas, and the discretisation error
of trimesh's round meshes against the primitives they approximate.

    python benchmarks/mass_properties.py

Prints two tables: (primitive, formula, formula value, rbody value, relative difference) for unit
mass, a = 0.5 m, b = 0.25 m, L = 2 m; and (mesh, resolution, relative error of each principal moment)
for trimesh's cylinder, annulus and icosphere at growing resolution.
"""

from __future__ import annotations

import numpy as np
import trimesh

from rbody import Inertia

M, A, B, L = 1.0, 0.5, 0.25, 2.0


def primitive_rows() -> list[tuple[str, str, float, float]]:
    disc = Inertia.disc(M, A, "z")
    rod = Inertia.rod(M, L, "z")
    return [
        ("hoop, about its axis", "M a^2", M * A**2, Inertia.hoop(M, A, "z").moment("z")),
        ("hoop, about a diameter", "M a^2 / 2", M * A**2 / 2, Inertia.hoop(M, A, "z").moment("x")),
        ("rod, about its centre", "M L^2 / 12", M * L**2 / 12, rod.moment("x")),
        ("rod, about its end", "M L^2 / 3", M * L**2 / 3, rod.moment("x", through=[0, 0, L / 2])),
        ("disc, about its axis", "M a^2 / 2", M * A**2 / 2, disc.moment("z")),
        ("disc, about a diameter", "M a^2 / 4", M * A**2 / 4, disc.moment("x")),
        ("disc, about a rim point, normal", "3/2 M a^2", 1.5 * M * A**2, disc.moment("z", through=[A, 0, 0])),
        ("solid sphere", "2/5 M a^2", 0.4 * M * A**2, Inertia.solid_sphere(M, A).moment("x")),
        ("spherical shell", "2/3 M a^2", 2 / 3 * M * A**2, Inertia.spherical_shell(M, A).moment("x")),
        ("solid cylinder, across", "M (3 a^2 + L^2) / 12", M * (3 * A**2 + L**2) / 12,
         Inertia.solid_cylinder(M, A, L, "z").moment("x")),
        ("thick tube b..a, axis", "M (a^2 + b^2) / 2", M * (A**2 + B**2) / 2,
         Inertia.hollow_cylinder(M, B, A, L, "z").moment("z")),
        ("thin-walled cylinder, axis", "M a^2", M * A**2, Inertia.hollow_cylinder(M, A, A, L, "z").moment("z")),
        ("box 1 x 2 x 3, I_xx", "M (b^2 + c^2) / 12", M * 13 / 12, Inertia.box(M, [1, 2, 3]).moment("x")),
    ]


def mesh_rows() -> list[tuple[str, str, np.ndarray]]:
    rows = []
    exact = np.sort(np.linalg.eigvalsh(Inertia.solid_cylinder(M, 1.0, 2.0, "z").tensor))
    for sections in (16, 64, 256):
        mesh = trimesh.creation.cylinder(radius=1.0, height=2.0, sections=sections)
        got = Inertia.from_mesh(mesh, mass=M).principal()[0]
        rows.append(("cylinder r=1, L=2", f"{sections} sections", got / exact - 1))
    exact = np.sort(np.linalg.eigvalsh(Inertia.hollow_cylinder(M, 0.5, 1.0, 2.0, "z").tensor))
    for sections in (16, 64, 256):
        mesh = trimesh.creation.annulus(r_min=0.5, r_max=1.0, height=2.0, sections=sections)
        got = Inertia.from_mesh(mesh, mass=M).principal()[0]
        rows.append(("annulus 0.5..1, L=2", f"{sections} sections", got / exact - 1))
    for subdivisions in (2, 3, 4, 5):
        mesh = trimesh.creation.icosphere(subdivisions=subdivisions, radius=1.0)
        got = Inertia.from_mesh(mesh, mass=M).principal()[0]
        rows.append(("icosphere r=1, solid", f"{subdivisions} subdivisions", got / 0.4 - 1))
        shell = Inertia.from_mesh(mesh, mass=M, shell=True).principal()[0]
        rows.append(("icosphere r=1, shell", f"{subdivisions} subdivisions", shell / (2 / 3) - 1))
    box = Inertia.from_mesh(trimesh.creation.box(extents=[1, 2, 3]), mass=M).tensor
    rows.append(("box 1 x 2 x 3", "12 triangles", np.diag(box) / np.diag(Inertia.box(M, [1, 2, 3]).tensor) - 1))
    return rows


def main() -> None:
    print(f"Primitives (M = {M} kg, a = {A} m, b = {B} m, L = {L} m)")
    print(f"{'primitive':34} {'formula':22} {'formula value':>18} {'rbody':>18} {'rel. diff':>10}")
    for name, formula, want, got in primitive_rows():
        print(f"{name:34} {formula:22} {want:18.15g} {got:18.15g} {abs(got / want - 1):10.2g}")
    print("\nMeshes (relative error of the principal moments, ascending, against the primitive)")
    for name, resolution, error in mesh_rows():
        print(f"{name:22} {resolution:16} " + "  ".join(f"{e:+.3e}" for e in np.atleast_1d(error)))


if __name__ == "__main__":
    main()
