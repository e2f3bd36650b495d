"""Drawing a scene's bodies: its Shapes as polygons, a camera, and one frame painted with matplotlib (Agg).

Every Shape kind is tessellated once, in the frame of the body that carries it (rbody.Shape: sphere, cylinder,
capsule, box, plane, mesh through trimesh; an "ellipsoid" of half axes (a, b, c) too, for when Shape has
it). A frame moves the polygons by the bodies' poses (rbody.poses), projects them through a Camera (a
perspective view, or an orthographic side view for motion in the x-z plane), drops the faces turned away from
the camera, sorts the rest far to near (the painter's algorithm) and fills them, shaded by a light beside
the camera, with one matplotlib PolyCollection per panel. Planes are the stage: drawn first, as tiled slabs
(so that a plane seen edge-on in a side view is still a strip), and never in front of a body.

The painter's algorithm sorts faces by their mean depth: exact for the convex, separate shapes of the
chapter's scenes; where two shapes interpenetrate, or a long face lies beside a small one, a face may be drawn
over one nearer to the camera. Round shapes carry darker sectors (a beach-ball pattern), so that a rolling
disc or sphere shows its turning.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, field
from typing import Sequence

import numpy as np

from rbody.motion import quat_to_matrix
from rbody.optional import optional

FIELD_OF_VIEW = 30.0          # vertical field of view of the perspective camera [deg]
SEGMENTS = 24                 # facets around a round shape
RINGS = 10                    # rings of a sphere from pole to pole (half that per capsule end)
PATTERN_TONE = 0.8            # brightness of a round shape's darker sectors (1: no pattern)
PLANE_TILES = 10              # tiles along the longer side of a plane
AMBIENT, DIFFUSE = 0.5, 0.5   # Lambert shading: ambient + diffuse max(0, n . light)

DRAWN_KINDS = ("sphere", "cylinder", "box", "capsule", "plane", "mesh", "ellipsoid", "hfield")


@dataclass(frozen=True)
class Polygons:
    """Faces of drawn shapes, each a quadrilateral (a triangle repeats its last corner).

    points:  (F, 4, 3) corners [m], in the frame of the body (or the world) that carries them
    normals: (F, 3) unit outward normals, same frame
    tone:    (F,) brightness factor of each face (the pattern of round shapes)
    closed:  True when the faces close a surface with outward normals, so faces turned away from the camera
             are hidden and skipped (False for an open or inconsistently wound mesh)"""

    points: np.ndarray
    normals: np.ndarray
    tone: np.ndarray
    closed: bool = True

    @staticmethod
    def join(parts: Sequence["Polygons"]) -> "Polygons":
        if not parts:
            return Polygons(np.zeros((0, 4, 3)), np.zeros((0, 3)), np.zeros(0), True)
        return Polygons(np.concatenate([p.points for p in parts]), np.concatenate([p.normals for p in parts]),
                        np.concatenate([p.tone for p in parts]), all(p.closed for p in parts))

    def moved(self, rotation: np.ndarray, translation: np.ndarray) -> "Polygons":
        """The faces carried by a rigid motion: rotation (3, 3), translation (3,) [m]."""
        return Polygons(self.points @ rotation.T + translation, self.normals @ rotation.T, self.tone, self.closed)

    @property
    def reach(self) -> float:
        """Largest distance of a corner from the frame's origin [m] (0 for no faces)."""
        return float(np.max(np.linalg.norm(self.points, axis=-1))) if len(self.points) else 0.0


# ----- tessellation ------------------------------------------------------------------------------------------

def _newell(points: np.ndarray) -> np.ndarray:
    """(F, 3) unit normals of (F, 4, 3) polygons by Newell's method (a repeated corner is harmless)."""
    nxt = np.roll(points, -1, axis=1)
    normal = np.stack([np.sum((points[..., 1] - nxt[..., 1]) * (points[..., 2] + nxt[..., 2]), axis=1),
                       np.sum((points[..., 2] - nxt[..., 2]) * (points[..., 0] + nxt[..., 0]), axis=1),
                       np.sum((points[..., 0] - nxt[..., 0]) * (points[..., 1] + nxt[..., 1]), axis=1)], axis=1)
    length = np.linalg.norm(normal, axis=1, keepdims=True)
    return normal / np.where(length > 0, length, 1.0)


def _outward(points: np.ndarray, centre: np.ndarray | None = None) -> Polygons:
    """Polygons of a convex surface around `centre` (default the origin), normals turned outward."""
    normals = _newell(points)
    centre = np.zeros(3) if centre is None else centre
    flip = np.sum(normals * (points.mean(axis=1) - centre), axis=1) < 0
    normals[flip] *= -1
    return Polygons(points, normals, np.ones(len(points)))


def _sector_tone(column: np.ndarray, columns: int, row: np.ndarray | None = None, rows: int = 1) -> np.ndarray:
    """PATTERN_TONE on alternate quarters around the axis (and alternate halves along it): a beach ball."""
    quarter = (4 * column) // columns
    half = np.zeros_like(column) if row is None else (2 * row) // max(rows, 1)
    return np.where((quarter + half) % 2 == 0, 1.0, PATTERN_TONE)


def _grid_quads(grid: np.ndarray) -> np.ndarray:
    """(R-1)(C-1) quads (.., 4, 3) of a (R, C, 3) grid of points, row-major."""
    return np.stack([grid[:-1, :-1], grid[1:, :-1], grid[1:, 1:], grid[:-1, 1:]], axis=2).reshape(-1, 4, 3)


def _ellipsoid(axes: Sequence[float]) -> Polygons:
    """Half axes (a, b, c) along local x, y, z [m]; a sphere when equal."""
    theta = np.linspace(0.0, np.pi, RINGS + 1)[:, None]
    phi = np.linspace(0.0, 2 * np.pi, SEGMENTS + 1)[None, :]
    unit = np.stack(np.broadcast_arrays(np.sin(theta) * np.cos(phi), np.sin(theta) * np.sin(phi), np.cos(theta)),
                    axis=-1)
    quads = _grid_quads(unit * np.asarray(axes, dtype=float))
    rows, columns = np.divmod(np.arange(RINGS * SEGMENTS), SEGMENTS)
    polygons = _outward(quads)
    return Polygons(polygons.points, polygons.normals, _sector_tone(columns, SEGMENTS, rows, RINGS))


def _cylinder(radius: float, half: float) -> Polygons:
    """Along local z from -half to +half, with both caps as fans of triangles."""
    phi = np.linspace(0.0, 2 * np.pi, SEGMENTS + 1)
    ring = np.stack([radius * np.cos(phi), radius * np.sin(phi), np.zeros_like(phi)], axis=1)
    low, high = ring + [0, 0, -half], ring + [0, 0, half]
    side = np.stack([low[:-1], low[1:], high[1:], high[:-1]], axis=1)
    caps = []
    for z, edge in ((-half, low), (half, high)):
        centre = np.broadcast_to([0.0, 0.0, z], (SEGMENTS, 3))
        caps.append(np.stack([centre, edge[:-1], edge[1:], edge[1:]], axis=1))
    columns = np.arange(SEGMENTS)
    polygons = _outward(np.concatenate([side] + caps))
    tone = np.concatenate([_sector_tone(columns, SEGMENTS)] * 3)
    return Polygons(polygons.points, polygons.normals, tone)


def _capsule(radius: float, half: float) -> Polygons:
    """A cylinder of half length `half` along local z, closed by two hemispheres."""
    rings = max(RINGS // 2, 2)
    theta = np.concatenate([np.linspace(0.0, np.pi / 2, rings + 1), np.linspace(np.pi / 2, np.pi, rings + 1)])
    z_shift = np.concatenate([np.full(rings + 1, half), np.full(rings + 1, -half)])
    phi = np.linspace(0.0, 2 * np.pi, SEGMENTS + 1)[None, :]
    t = theta[:, None]
    grid = np.stack(np.broadcast_arrays(radius * np.sin(t) * np.cos(phi), radius * np.sin(t) * np.sin(phi),
                                        radius * np.cos(t) + z_shift[:, None]), axis=-1)
    quads = _grid_quads(grid)
    rows, columns = np.divmod(np.arange(len(quads)), SEGMENTS)
    normals = _newell(quads)
    # outward: from the nearest point of the axis segment
    centroid = quads.mean(axis=1)
    axis_point = np.stack([np.zeros(len(quads)), np.zeros(len(quads)), np.clip(centroid[:, 2], -half, half)], axis=1)
    flip = np.sum(normals * (centroid - axis_point), axis=1) < 0
    normals[flip] *= -1
    return Polygons(quads, normals, _sector_tone(columns, SEGMENTS, rows, len(theta) - 1))


def _box(half: Sequence[float]) -> Polygons:
    hx, hy, hz = (float(h) for h in half)
    corners = np.array([[sx * hx, sy * hy, sz * hz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
    faces = [(0, 1, 3, 2), (4, 6, 7, 5), (0, 4, 5, 1), (2, 3, 7, 6), (0, 2, 6, 4), (1, 5, 7, 3)]
    return _outward(corners[np.array(faces)])


def _plane(half_x: float, half_y: float, thickness: float) -> Polygons:
    """The plane z = 0 of the given half sizes as tiles (alternate tones) on a slab of `thickness` below it."""
    longer = max(half_x, half_y)
    nx = max(1, round(PLANE_TILES * half_x / longer))
    ny = max(1, round(PLANE_TILES * half_y / longer))
    x = np.linspace(-half_x, half_x, nx + 1)
    y = np.linspace(-half_y, half_y, ny + 1)
    grid = np.stack(np.broadcast_arrays(x[:, None], y[None, :], np.zeros((1, 1))), axis=-1)
    tiles = _grid_quads(grid)
    i, j = np.divmod(np.arange(len(tiles)), ny)
    top = Polygons(tiles, np.tile([0.0, 0.0, 1.0], (len(tiles), 1)), np.where((i + j) % 2 == 0, 1.0, 0.9))
    slab = _box((half_x, half_y, thickness / 2)).moved(np.eye(3), np.array([0.0, 0.0, -thickness / 2]))
    below = slab.normals[:, 2] < 0.5  # its top is the tiles
    return Polygons.join([top, Polygons(slab.points[below], slab.normals[below], np.full(int(below.sum()), 0.85))])


def _mesh(path: str | None, vertices=()) -> Polygons:
    """A mesh file's triangles, or, with no file, the convex hull of `vertices` (V, 3) [m] (a collision mesh)."""
    import trimesh

    if path is None:
        mesh = trimesh.Trimesh(np.asarray(vertices, dtype=float)).convex_hull
        path = "<the convex hull of its vertices>"
    else:
        try:
            mesh = trimesh.load_mesh(path, force="mesh")
        except Exception as error:  # trimesh raises many types for unreadable files
            raise ValueError(f"mesh {path!r}: trimesh could not load it to draw it ({error})") from None
    vertices = np.asarray(mesh.vertices, dtype=float)
    faces = np.asarray(mesh.faces)
    if faces.ndim != 2 or len(faces) == 0:
        raise ValueError(f"mesh {path!r} has no triangles to draw")
    points = vertices[faces[:, [0, 1, 2, 2]]]
    closed = bool(mesh.is_watertight and mesh.is_winding_consistent and mesh.volume > 0)
    return Polygons(points, _newell(points), np.ones(len(points)), closed)


def shape_polygons(kind: str, size: Sequence[float], *, mesh: str | None = None, plane_extent: float = 1.0,
                   plane_thickness: float = 0.0, vertices=(), heights=()) -> Polygons:
    """The faces of one shape in its own frame: kind one of DRAWN_KINDS; size as rbody.Shape gives it (sphere
    (r,), cylinder and capsule (r, half length) along local z, box (half sizes), ellipsoid (half axes), plane
    (half x, half y; 0 or absent: infinite, drawn `plane_extent` [m] each way) on a slab `plane_thickness` [m]
    deep); mesh: the file's path, or vertices (V, 3) [m] whose convex hull is drawn; hfield: size (sx, sy, sz,
    base) and heights (nrow, ncol) in [0, 1], its top surface. ValueError for an unknown kind or a mesh trimesh
    cannot read."""
    size = [float(s) for s in np.atleast_1d(size)] if np.size(size) else []
    if kind == "sphere":
        return _ellipsoid([size[0]] * 3)
    if kind == "ellipsoid":
        return _ellipsoid(size[:3])
    if kind == "cylinder":
        return _cylinder(size[0], size[1])
    if kind == "capsule":
        return _capsule(size[0], size[1])
    if kind == "box":
        return _box(size[:3])
    if kind == "plane":
        half_x = size[0] if len(size) > 0 and size[0] > 0 else plane_extent
        half_y = size[1] if len(size) > 1 and size[1] > 0 else plane_extent
        return _plane(half_x, half_y, plane_thickness)
    if kind == "mesh":
        if mesh is None and len(vertices) < 4:
            raise ValueError("a mesh shape needs the path of its file (Shape.mesh) or its vertices (Shape.vertices)")
        return _mesh(mesh, vertices)
    if kind == "hfield":
        return _terrain(size, heights)
    raise ValueError(f"shape kind {kind!r}: cannot draw it; expected one of {DRAWN_KINDS}")


def _terrain(size: Sequence[float], heights) -> Polygons:
    """A height field's top surface (rbody.Shape's hfield: size (sx, sy, sz, base), heights (nrow, ncol) in [0, 1]),
    its cells' two triangles each as the terrain's contacts see them (rbody.engine.contacts.terrain)."""
    heights = np.asarray(heights, dtype=float)
    if heights.ndim != 2 or min(heights.shape) < 2:
        raise ValueError(f"a hfield shape needs heights (nrow, ncol), each >= 2, got shape {heights.shape}")
    nrow, ncol = heights.shape
    x = np.linspace(-size[0], size[0], ncol)
    y = np.linspace(-size[1], size[1], nrow)
    grid = np.stack(np.broadcast_arrays(x[None, :], y[:, None], size[2] * heights), axis=-1)  # (nrow, ncol, 3)
    a, b, c, d = grid[:-1, :-1], grid[:-1, 1:], grid[1:, :-1], grid[1:, 1:]  # (r, c), (r, c+1), (r+1, c), (r+1, c+1)
    first = np.stack([c, a, d, d], axis=-2).reshape(-1, 4, 3)  # T0 and T1 of every cell
    second = np.stack([a, d, b, b], axis=-2).reshape(-1, 4, 3)
    points = np.concatenate([first, second])
    normals = _newell(points)
    normals *= np.where(normals[:, 2:3] < 0, -1.0, 1.0)  # up
    return Polygons(points, normals, np.ones(len(points)), closed=False)


def placed(shape, **options) -> Polygons:
    """shape_polygons of an rbody.Shape, moved to its pos and quat in the frame that carries it."""
    local = shape_polygons(shape.kind, shape.size, mesh=shape.mesh, vertices=shape.vertices,
                           heights=getattr(shape, "heights", ()), **options)
    return local.moved(quat_to_matrix(np.asarray(shape.quat, dtype=float)), np.asarray(shape.pos, dtype=float))


# ----- the camera --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Camera:
    """A camera looking at `target` (3,) [m] from azimuth and elevation [deg] (the direction from the target to
    the eye is (cos el cos az, cos el sin az, sin el), matplotlib's convention; z up) at `distance` [m].

    Perspective (orthographic False): a vertical field of view FIELD_OF_VIEW; orthographic: parallel rays, the
    view `distance` tan(FIELD_OF_VIEW / 2) high each way from the target. Screen coordinates: y up, the
    target at (0, 0), the view's vertical half extent 1 (at the target's depth for the perspective)."""

    target: np.ndarray
    azimuth: float
    elevation: float
    distance: float
    orthographic: bool = False
    basis: np.ndarray = field(init=False, repr=False)  # rows right, up, forward

    def __post_init__(self) -> None:
        az, el = math.radians(self.azimuth), math.radians(self.elevation)
        towards_eye = np.array([math.cos(el) * math.cos(az), math.cos(el) * math.sin(az), math.sin(el)])
        forward = -towards_eye
        right = np.cross(forward, [0.0, 0.0, 1.0])
        if np.linalg.norm(right) < 1e-9:  # looking straight down or up: screen right along world x
            right = np.array([1.0, 0.0, 0.0]) if el > 0 else np.array([-1.0, 0.0, 0.0])
        right /= np.linalg.norm(right)
        up = np.cross(right, forward)
        object.__setattr__(self, "target", np.asarray(self.target, dtype=float))
        object.__setattr__(self, "basis", np.stack([right, up, forward]))

    @property
    def eye(self) -> np.ndarray:
        return self.target - self.distance * self.basis[2]

    @property
    def focal(self) -> float:
        return 1.0 / math.tan(math.radians(FIELD_OF_VIEW) / 2)

    def camera_coordinates(self, points: np.ndarray) -> np.ndarray:
        """(..., 3) points -> (..., 3) (right, up, depth from the eye) [m]."""
        return (np.asarray(points, dtype=float) - self.eye) @ self.basis.T

    def project(self, points: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """(..., 3) world points [m] -> screen (..., 2) and depth (..., ) from the eye [m] (larger: farther)."""
        c = self.camera_coordinates(points)
        depth = c[..., 2]
        if self.orthographic:
            scale = self.focal / self.distance
            return c[..., :2] * scale, depth
        return c[..., :2] * (self.focal / np.maximum(depth, 1e-12))[..., None], depth

    def facing(self, centres: np.ndarray, normals: np.ndarray) -> np.ndarray:
        """(F,) True where a face (centre, outward normal) turns towards the eye."""
        if self.orthographic:
            return normals @ (-self.basis[2]) > 1e-12
        return np.sum(normals * (self.eye - centres), axis=-1) > 1e-12

    @property
    def light(self) -> np.ndarray:
        """(3,) unit direction towards the light: behind the camera, above and to its left."""
        right, up, forward = self.basis
        light = -forward + 0.8 * up - 0.4 * right
        return light / np.linalg.norm(light)


def fit_camera(points: np.ndarray, *, azimuth: float, elevation: float, distance: float | None,
               orthographic: bool, aspect: float, margin: float = 0.08) -> Camera:
    """The camera from azimuth, elevation [deg] whose view is centred on `points` (N, 3) [m] (the middle of their
    projection) and, at `distance` [m] or, None, at the distance where they all fit (width / height = aspect)
    with `margin` (a fraction of the view) to spare. Three rounds of centring and fitting (the perspective
    view's centre moves as the distance changes)."""
    points = np.asarray(points, dtype=float)
    low, high = points.min(axis=0), points.max(axis=0)
    target = (low + high) / 2
    radius = max(float(np.linalg.norm(high - low)) / 2, 1e-9)
    room = 1.0 - margin
    current = distance if distance is not None else 3.0 * radius
    for _round in range(3):
        camera = Camera(target, azimuth, elevation, current, orthographic)
        screen, depth = camera.project(points)
        if not orthographic and np.any(depth <= 0):  # points behind the eye: step back first
            current = float(np.max(-camera.camera_coordinates(points)[:, 2])) + current + radius
            continue
        middle = (screen.min(axis=0) + screen.max(axis=0)) / 2
        target = target + (middle[0] * camera.basis[0] + middle[1] * camera.basis[1]) * current / camera.focal
        if distance is not None:
            continue
        relative = (points - target) @ camera.basis.T  # right, up, depth beyond the target
        spread = np.maximum(np.abs(relative[:, 0]) / (aspect * room), np.abs(relative[:, 1]) / room)
        if orthographic:
            current = float(np.max(spread)) * camera.focal
        else:
            current = float(np.max(spread * camera.focal - relative[:, 2]))
            current = max(current, float(np.max(-relative[:, 2])) + 0.05 * radius)
        current = max(current, 1e-9)
    return Camera(target, azimuth, elevation, float(current), orthographic)


# ----- one frame ---------------------------------------------------------------------------------------------

def shade(colours: np.ndarray, normals: np.ndarray, tone: np.ndarray, light: np.ndarray) -> np.ndarray:
    """(F, 3) RGB in [0, 1] of faces of base colours (F, 3), lit by Lambert's law from `light` (3,), times tone."""
    lit = AMBIENT + DIFFUSE * np.clip(normals @ light, 0.0, 1.0)
    return np.clip(colours * (lit * tone)[:, None], 0.0, 1.0)


def visible_faces(camera: Camera, polygons: Polygons, colours: np.ndarray, shaded: bool,
                  bias: float = 0.0) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """The faces of world-frame `polygons` the camera sees: screen corners (F', 4, 2), depth (F',) [m] (less
    `bias`, which brings a group forward where it coincides with another), RGB (F', 3)."""
    centres = polygons.points.mean(axis=1)
    keep = camera.facing(centres, polygons.normals) if polygons.closed else np.ones(len(centres), bool)
    screen, depth = camera.project(polygons.points[keep])
    rgb = colours[keep]
    if shaded:
        normals = polygons.normals[keep]
        if not polygons.closed:  # either side may show: light the side facing the camera
            towards = camera.eye - centres[keep] if not camera.orthographic else -camera.basis[2]
            normals = np.where((np.sum(normals * towards, axis=-1) < 0)[:, None], -normals, normals)
        rgb = shade(rgb, normals, polygons.tone[keep], camera.light)
    in_front = np.all(depth > 0, axis=1) if not camera.orthographic else np.ones(len(depth), bool)
    return screen[in_front], depth[in_front].mean(axis=1) - bias, rgb[in_front]


def painter_order(depth: np.ndarray) -> np.ndarray:
    """Indices of faces far to near (stable: equal depths keep their order)."""
    return np.argsort(-depth, kind="stable")


@dataclass
class PanelContent:
    """What one panel shows in a frame: the stage (planes, drawn first) and the rest, each as screen corners
    (F, 4, 2), depth (F,) and RGB (F, 3); body-frame axes as segments (S, 2, 2) with RGB (S, 3); lines of
    text for the top-left corner."""

    stage: tuple[np.ndarray, np.ndarray, np.ndarray]
    solids: tuple[np.ndarray, np.ndarray, np.ndarray]
    segments: tuple[np.ndarray, np.ndarray] | None = None
    text: str = ""


class Canvas:
    """A matplotlib figure (Agg: no display) of `panels` panels side by side, each width x height pixels, screen
    coordinates x in [-width/height, width/height], y in [-1, 1] (Camera.project's). render() paints one frame
    and returns its pixels."""

    def __init__(self, panels: int, width: int, height: int, titles: Sequence[str] = (),
                 legend: Sequence[tuple[str, np.ndarray]] = ()) -> None:
        optional("matplotlib", "validation", "rbody.animate")
        # the Agg canvas and a bare Figure, never pyplot: no display is needed and the user's backend is untouched
        from matplotlib.backends.backend_agg import FigureCanvasAgg
        from matplotlib.collections import LineCollection, PolyCollection
        from matplotlib.figure import Figure

        self.panels, self.width, self.height = panels, width, height
        self.aspect = width / height
        dpi = 100
        self.figure = Figure(figsize=(panels * width / dpi, height / dpi), dpi=dpi, facecolor="white")
        self.agg = FigureCanvasAgg(self.figure)
        self.parts = []
        font = max(6.0, min(10.0, height / 36))
        for i in range(panels):
            axis = self.figure.add_axes((i / panels, 0.0, 1.0 / panels, 1.0))
            axis.set_xlim(-self.aspect, self.aspect)
            axis.set_ylim(-1.0, 1.0)
            axis.set_axis_off()
            stage = PolyCollection(np.zeros((0, 4, 2)), linewidths=0.3, antialiased=True, zorder=1)
            solids = PolyCollection(np.zeros((0, 4, 2)), linewidths=0.3, antialiased=True, zorder=2)
            axes_lines = LineCollection(np.zeros((0, 2, 2)), linewidths=1.2, zorder=3)
            for collection in (stage, solids, axes_lines):
                axis.add_collection(collection)
            text = axis.text(0.02, 0.98, "", transform=axis.transAxes, va="top", ha="left", fontsize=font,
                             family="monospace", zorder=4)
            if i < len(titles) and titles[i]:
                axis.text(0.98, 0.98, titles[i], transform=axis.transAxes, va="top", ha="right",
                          fontsize=font + 1, weight="bold", zorder=4)
            if i > 0:  # a thin rule between panels
                axis.axvline(-self.aspect, color="0.75", lw=1.0, zorder=5)
            if i == 0 and legend:
                from matplotlib.patches import Patch

                axis.legend(handles=[Patch(facecolor=rgb, edgecolor=rgb, label=label) for label, rgb in legend],
                            loc="lower left", fontsize=font, frameon=False, handlelength=1.0, borderaxespad=0.3)
            self.parts.append((stage, solids, axes_lines, text))

    def render(self, contents: Sequence[PanelContent]) -> np.ndarray:
        """(height, panels width, 3) uint8 RGB of one frame."""
        for (stage, solids, axes_lines, text), content in zip(self.parts, contents):
            for collection, (corners, depth, rgb) in ((stage, content.stage), (solids, content.solids)):
                order = painter_order(depth)
                collection.set_verts(corners[order])
                collection.set_facecolor(rgb[order])
                collection.set_edgecolor(rgb[order])
            if content.segments is not None and len(content.segments[0]):
                axes_lines.set_segments(content.segments[0])
                axes_lines.set_color(content.segments[1])
            else:
                axes_lines.set_segments(np.zeros((0, 2, 2)))
            text.set_text(content.text)
        self.agg.draw()
        return np.asarray(self.agg.buffer_rgba())[..., :3].copy()

    def close(self) -> None:
        self.figure.clear()
