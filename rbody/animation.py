"""Animations of any scene's runs, headless: rbody.animate(scene, trajectory, path).

    import rbody
    from rbody import scenes

    rod = scenes.swinging_rod(1.0, theta0=3.0, t_end=4.0)
    run = rbody.simulate(rod, dt=1e-3, method="rk4")
    rbody.animate(rod, run, "rod.gif")                          # GIF; ".webp": animated WebP; ".mp4": ffmpeg
    rbody.animate(race, {"rbody": a, "mujoco": b}, "race.gif")  # several runs of one scene, side by side
    rbody.animate(race, {"rbody": a, "mujoco": b}, "race.gif", arrangement="overlay")  # one panel, a colour each

Every body of the scene's layout is drawn with its Shapes (rbody.drawing: sphere, cylinder, capsule, box,
plane, mesh, and ellipsoid) where the run puts it (Scene.body_poses: from any engine's observables, rbody.poses),
with the time, optionally the values of some observables (`show`, e.g. a collision counter) and the bodies'
frames. The camera is fitted to the whole motion of every run (azimuth, elevation and distance can be set); a
motion that stays in the x-z plane and turns about y only (a pendulum, balls on a line) is seen from the side
in an orthographic view, any other in perspective. Playback follows simulated time: `speed` simulated seconds
per second (1: real time), `fps` frames per second, each frame showing every run at the last saved time at or
before the frame's time (an impact shows as sampled, never smoothed).

Size budget: frames cost bytes. Before rendering, a few frames are rendered and encoded to estimate the bytes
per frame, and the frame interval is widened (every k-th saved sample: the stride) until the file is expected
to stay within `max_bytes`; after encoding, a file still too large loses every other frame (each remaining
frame shown twice as long) until it fits. The stride is stated in the result (Animation.summary()) and in the
progress line, which a render longer than a few seconds prints on stderr.

Renderer, and why: matplotlib with its Agg backend (rbody.drawing): each frame's faces are projected by rbody's
own camera, sorted far to near (the painter's algorithm) and filled as one 2-D PolyCollection per panel; Agg
draws into memory, with no display and no system library, and matplotlib (with Pillow, which it depends on) is
part of rbody's install, so a fresh machine renders. Considered and not chosen: MuJoCo's offscreen renderer
(mujoco.Renderer) needs an OpenGL platform library from the system (EGL or OSMesa; MUJOCO_GL=egl works only
where libEGL is installed) and draws only MuJoCo models; trimesh's scene renderer needs pyglet and a display;
matplotlib's mplot3d (Poly3DCollection) sorts faces the same way but costs more per frame and does not expose
its projection, which the tests use to check that each body is drawn where its centre of mass is
(Animation.project). Cost per frame, mostly Agg filling the polygons: 5 to 8 ms for one panel of 480 x 360
pixels, 11 to 34 ms for three panels of 300 x 300 to 400 x 300 (Intel Xeon, 2 cores shared;
Animation.seconds_per_frame measures it, docs/make_animations.py prints it with the file sizes).

Frames are kept in memory as palette images (one fixed palette: the drawn colours and their shades, so that
colours do not flicker between frames), compressed; GIF and WebP are written by Pillow (GIF frame durations
are multiples of 10 ms: each is rounded so that the sum keeps to simulated time), MP4 by ffmpeg where it is
installed (matplotlib's ffmpeg path; ValueError before any rendering otherwise). Every file is written to a
temporary name and renamed into place.
"""

from __future__ import annotations

import math
import os
import shutil
import subprocess
import sys
import time
import zlib
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any, Callable, Mapping, Sequence

import numpy as np

from rbody.files import atomic_path, check_writable_folder
from rbody.drawing import Camera, Canvas, PanelContent, Polygons, fit_camera, placed, visible_faces
from rbody.motion import quat_to_matrix
from rbody.optional import optional
from rbody.trajectory import Trajectory

FORMATS = (".gif", ".webp", ".mp4")
ARRANGEMENTS = ("side", "overlay")
VIEWS = ("auto", "planar", "3d")
MAX_FPS = 50.0            # GIF players clamp shorter frame durations than 20 ms
DEFAULT_MAX_BYTES = 5_000_000
DEFAULT_AZIMUTH, DEFAULT_ELEVATION = -60.0, 25.0     # 3-D view [deg]
PLANAR_AZIMUTH, PLANAR_ELEVATION = -90.0, 0.0        # side view: from -y, x to the right, z up
PLANAR_TOLERANCE = 1e-9   # relative to the motion's extent: y spread and rotation off the y axis still planar
BODY_COLOURS = ("#1f77b4", "#ff7f0e", "#2ca02c", "#d62728", "#9467bd", "#8c564b", "#e377c2", "#bcbd22",
                "#17becf")
RUN_COLOURS = {"rbody": "#1f77b4", "mujoco": "#ff7f0e", "pymunk": "#2ca02c", "exact": "#444444"}
FIXED_COLOUR = "#9a9a9a"
STAGE_COLOUR = "#d4d4d4"
AXIS_COLOURS = ("#ff0000", "#00a000", "#0000ff")   # body frame x, y, z (none a body's colour)
PROBE_FRAMES = 3          # frames rendered and encoded to estimate the bytes per frame
TIME_FORMAT = "t = {:.3f} s"


# ----- the result --------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class Animation:
    """What animate() wrote.

    path: the file; frames: frames drawn (a GIF shows a frame equal to the one before it as one longer frame);
    times: (frames,) simulated time of each frame [s]; interval: simulated
    time between frames [s]; stride: saved samples of the first run per frame (None where its samples are not
    evenly spaced); samples: saved samples of the first run; speed: simulated seconds per second of playback;
    fps: frames per second of playback; width, height: pixels of the whole picture; panels: the panels' titles
    (side by side, each panel_size (width, height) pixels); bytes: file size; seconds_per_frame: rendering cost
    (drawing and palette) [s]; camera: the view of every panel."""

    path: Path
    frames: int
    times: np.ndarray
    interval: float
    stride: int | None
    samples: int
    speed: float
    fps: float
    width: int
    height: int
    panels: tuple[str, ...]
    bytes: int
    seconds_per_frame: float
    panel_size: tuple[int, int]
    camera: Camera = field(repr=False)

    def project(self, points, panel: int = 0) -> np.ndarray:
        """(..., 3) world points [m] -> (..., 2) pixel coordinates (column, row from the top; pixel (i, j)
        covers [i, i + 1) x [j, j + 1)) in the frames of this animation, in panel `panel`."""
        panels = len(self.panels)
        width, height = self.panel_size
        if not 0 <= panel < panels:
            raise ValueError(f"panel={panel!r}: the animation has panels 0..{panels - 1}")
        screen, _depth = self.camera.project(np.asarray(points, dtype=float))
        aspect = width / height
        column = panel * width + (screen[..., 0] + aspect) / (2 * aspect) * width
        row = (1.0 - screen[..., 1]) / 2 * height
        return np.stack([column, row], axis=-1)

    def summary(self) -> str:
        """One line: file, frames, the interval and stride chosen, size, cost per frame."""
        if self.samples == 1:
            stride = "a single saved sample"
        elif self.stride is not None:
            stride = f"every {_ordinal(self.stride)} of {self.samples} saved samples"
        else:
            stride = f"{self.samples} saved samples, unevenly spaced"
        return (f"{self.path.name}: {self.frames} frames of {self.width}x{self.height} px, one every "
                f"{self.interval:.4g} s of simulated time ({stride}), {self.fps:.3g} frames/s at {self.speed:g}x "
                f"real time; {self.bytes / 1e6:.2f} MB; {1e3 * self.seconds_per_frame:.0f} ms per frame")


def _ordinal(n: int) -> str:
    if n == 1:
        return "sample"
    suffix = "th" if 10 <= n % 100 <= 20 else {1: "st", 2: "nd", 3: "rd"}.get(n % 10, "th")
    return f"{n}{suffix}"


# ----- animate -----------------------------------------------------------------------------------------------

def animate(scene, trajectory, path: str | os.PathLike, *, arrangement: str = "side", view: str = "auto",
            azimuth: float | None = None, elevation: float | None = None, distance: float | None = None,
            speed: float = 1.0, fps: float = 25.0, max_bytes: int = DEFAULT_MAX_BYTES, max_frames: int = 2000,
            size: tuple[int, int] = (480, 360), body_frames: bool = False, shaded: bool = True,
            show: Sequence[str] = (), colours: Mapping[str, str] | None = None,
            legend: Mapping[str, str] | bool | None = None,
            progress: bool | Callable[[str], None] | None = None) -> Animation:
    """Write an animation of the bodies of `scene` over one or several of its runs to `path`.

    scene:       an rbody Scene (unbatched) whose bodies can be placed from its observables (Scene.body_poses)
    trajectory:  a Trajectory of the scene, or several: a mapping name -> Trajectory (the names title the
                 panels) or a sequence (titled by each run's meta["backend"]), from any engine
    path:        the file; its suffix picks the format: .gif, .webp (animated WebP), .mp4 (needs ffmpeg)
    arrangement: "side": a panel per run, side by side, bodies in their own colours; "overlay": one panel,
                 each run in its own colour (rbody blue, MuJoCo orange, pymunk green; where runs coincide, to
                 within about a body's size, the last one listed is drawn over the others)
    view:        "auto" (side view for motion in the x-z plane, else 3-D), "planar" (orthographic), "3d"
    azimuth, elevation: camera direction [deg] (default -60, 25 in 3-D; -90, 0 in the side view: from -y);
                 distance: from the target [m] (default: fitted so that the whole motion of every run fits)
    speed:       simulated seconds per second of playback (1: real time; 0.25: four times slower)
    fps:         frames per second of playback, at most 50 (fewer when the size budget or the samples say so)
    max_bytes:   the file's size budget [bytes]; max_frames: at most this many frames
    size:        (width, height) of one panel [pixels]
    body_frames: draw each body's frame (x red, y green, z blue); shaded: light the faces (False: each body one
                 flat colour, the pattern of round shapes off)
    show:        names of observables whose values each panel prints under the time (e.g. "collisions")
    colours:     body name -> colour ("side"), or run name -> colour ("overlay"); matplotlib colour strings
    legend:      body name -> label, shown with the bodies' colours in the first panel ("side"); None: the runs'
                 colours ("overlay"), nothing ("side"); False: none
    progress:    None: a progress line on stderr when the render takes more than a few seconds; True: always;
                 False: never; or a function called with each line
    Returns an Animation (frames, interval and stride chosen, size, cost per frame: Animation.summary()).
    Raises ValueError, before any rendering, for a bad path or format (an MP4 without ffmpeg), a batched scene,
    a trajectory that is not a run of this scene, or a bad option.
    """
    path = _checked_path(path)
    options = _checked_options(arrangement, view, azimuth, elevation, distance, speed, fps, max_bytes, max_frames,
                               size)
    runs = _named_runs(trajectory)
    check_animatable(scene)
    poses = {name: scene.body_poses(run) for name, run in runs.items()}  # ValueError for a run of another scene
    shown = _checked_show(show, runs)
    layout = scene.layout
    timing = _timing(runs, options["speed"], options["fps"], max_frames)
    colour_of = _colours(colours, layout, runs, arrangement)
    legend_entries = _legend(legend, colour_of, layout, runs, arrangement)
    report = _progress(progress)

    bodies = {body.name: Polygons.join([placed(s) for s in body.shapes if s.kind != "plane"])
              for body in layout.bodies}
    body_planes = [(body.name, s) for body in layout.bodies for s in body.shapes if s.kind == "plane"]
    fixed = Polygons.join([placed(s) for s in layout.fixed if s.kind != "plane"])
    extent_points = _motion_points(bodies, poses, timing)
    spread = float(np.linalg.norm(np.ptp(extent_points, axis=0))) if len(extent_points) > 1 else 0.0
    marker = 0.04 * spread if spread > 0 else 0.05  # [m]
    for name, polygons in bodies.items():
        if not len(polygons.points):  # a body with no shapes: a small sphere at its centre of mass
            com = next(b for b in layout.bodies if b.name == name).inertia.com
            bodies[name] = _marker(marker).moved(np.eye(3), com)
    extent_points = _motion_points(bodies, poses, timing)
    if not len(extent_points):
        extent_points = np.concatenate([fixed.points.reshape(-1, 3), np.zeros((1, 3))])

    planar = _planar(view, poses, extent_points)
    width, height = options["size"]
    camera = fit_camera(extent_points, azimuth=options["azimuth"] if options["azimuth"] is not None else
                        (PLANAR_AZIMUTH if planar else DEFAULT_AZIMUTH),
                        elevation=options["elevation"] if options["elevation"] is not None else
                        (PLANAR_ELEVATION if planar else DEFAULT_ELEVATION),
                        distance=options["distance"], orthographic=planar, aspect=width / height)
    view_size = camera.distance / camera.focal  # half the view's height at the target [m]
    stage_extent = 3.0 * max(view_size * width / height, float(np.max(np.ptp(extent_points, axis=0))))
    thickness = 0.02 * view_size
    stage = Polygons.join([placed(s, plane_extent=stage_extent, plane_thickness=thickness)
                           for s in layout.fixed if s.kind == "plane"])
    planes = {name: placed(s, plane_extent=stage_extent, plane_thickness=thickness) for name, s in body_planes}
    scale = float(np.max(np.ptp(extent_points, axis=0))) or 1.0

    panel_runs = [[name] for name in runs] if arrangement == "side" else [list(runs)]
    titles = tuple(runs) if arrangement == "side" else ("",)
    if isinstance(trajectory, Trajectory) and "backend" not in trajectory.meta:
        titles = ("",)  # one run with no name
    painter = _Painter(camera, bodies, planes, fixed, stage, poses, runs, panel_runs, colour_of, shaded,
                       body_frames, shown, scale)
    canvas = Canvas(len(panel_runs), width, height, titles, legend_entries)
    palette = _palette(colour_of, shaded)
    try:
        timing = _fit_budget(timing, painter, canvas, palette, path.suffix, options["max_bytes"], report)
        frames, seconds = _render(timing, painter, canvas, palette, report, path.name)
        written, timing = _write(frames, timing, palette, (canvas.width * canvas.panels, canvas.height), path,
                                 options["max_bytes"])
    finally:
        canvas.close()
    first = next(iter(runs.values()))
    animation = Animation(path=path, frames=len(timing.times), times=timing.times, interval=timing.interval,
                          stride=timing.stride, samples=first.t.size, speed=timing.speed,
                          fps=timing.speed / timing.interval if timing.interval > 0 else 0.0,
                          width=canvas.width * canvas.panels, height=canvas.height, panels=titles, bytes=written,
                          seconds_per_frame=seconds, panel_size=(canvas.width, canvas.height), camera=camera)
    if report.active:
        report.line(f"wrote {animation.summary()}", final=True)
    return animation


# ----- checks ------------------------------------------------------------------------------------------------

def check_animatable(scene) -> None:
    """ValueError saying why `scene`'s runs cannot be drawn (a batch, no layout of bodies, no way to place them
    from its observables); None when they can. animate() checks it too; a command checks it before its runs."""
    from rbody.scene import Scene

    if not isinstance(scene, Scene):
        raise ValueError(f"scene={type(scene).__name__}: expected an rbody Scene")
    scene.require_single("an animation")
    try:
        scene.layout
    except NotImplementedError as error:
        raise ValueError(f"scene {scene.name!r} cannot be drawn: it has no layout of bodies ({error})") from None
    if type(scene).joint_coordinates is Scene.joint_coordinates:
        raise ValueError(f"scene {scene.name!r} cannot be drawn: {type(scene).__name__} does not place its bodies "
                         "from its observables (it defines no joint_coordinates)")


def _checked_path(path) -> Path:
    if not isinstance(path, (str, os.PathLike)) or str(path) == "":
        raise ValueError(f"path={path!r}: expected a file name ending in {', '.join(FORMATS)}")
    path = Path(path)
    suffix = path.suffix.lower()
    if path.is_dir():
        raise ValueError(f"path {str(path)!r} is a folder: expected a file name ending in {', '.join(FORMATS)}")
    if suffix not in FORMATS:
        raise ValueError(f"path {str(path)!r}: the suffix {path.suffix!r} names no format rbody writes; expected "
                         f"{', '.join(FORMATS)}")
    check_writable_folder(path.parent if str(path.parent) else Path("."))  # UnwritableFolder is a ValueError
    if suffix == ".mp4" and _ffmpeg() is None:
        raise ValueError(f"path {str(path)!r}: MP4 needs ffmpeg, which is not installed (not on PATH, nor "
                         "matplotlib's rcParams['animation.ffmpeg_path']); write .gif or .webp, which need nothing "
                         "beyond rbody's install")
    return path


def _ffmpeg() -> str | None:
    matplotlib = optional("matplotlib", "validation", "rbody.animate")

    configured = matplotlib.rcParams.get("animation.ffmpeg_path", "ffmpeg")
    return shutil.which(configured) or shutil.which("ffmpeg")


def _number(value, name: str, *, low: float | None = None, high: float | None = None, strict_low: bool = True):
    if isinstance(value, bool) or not isinstance(value, (int, float, np.integer, np.floating)):
        raise ValueError(f"{name}={value!r}: expected a number")
    value = float(value)
    if not math.isfinite(value):
        raise ValueError(f"{name}={value!r}: expected a finite number")
    if low is not None and (value <= low if strict_low else value < low):
        raise ValueError(f"{name}={value!r}: expected a number {'>' if strict_low else '>='} {low:g}")
    if high is not None and value > high:
        raise ValueError(f"{name}={value!r}: expected a number <= {high:g}")
    return value


def _checked_options(arrangement, view, azimuth, elevation, distance, speed, fps, max_bytes, max_frames,
                     size) -> dict[str, Any]:
    if arrangement not in ARRANGEMENTS:
        raise ValueError(f"arrangement={arrangement!r}: expected one of {ARRANGEMENTS}")
    if view not in VIEWS:
        raise ValueError(f"view={view!r}: expected one of {VIEWS}")
    out: dict[str, Any] = {}
    out["azimuth"] = None if azimuth is None else _number(azimuth, "azimuth")
    out["elevation"] = None if elevation is None else _number(elevation, "elevation", low=-90, high=90,
                                                               strict_low=False)
    out["distance"] = None if distance is None else _number(distance, "distance", low=0)
    out["speed"] = _number(speed, "speed", low=0)
    out["fps"] = _number(fps, "fps", low=0, high=MAX_FPS)
    out["max_bytes"] = _number(max_bytes, "max_bytes", low=0)
    if isinstance(max_frames, bool) or not isinstance(max_frames, (int, np.integer)) or max_frames < 1:
        raise ValueError(f"max_frames={max_frames!r}: expected a whole number >= 1")
    try:
        width, height = (int(s) for s in size)
        if (width, height) != tuple(size) or min(width, height) < 32 or max(width, height) > 4096:
            raise ValueError
    except (TypeError, ValueError):
        raise ValueError(f"size={size!r}: expected (width, height) of one panel, whole numbers of pixels in "
                         "32..4096") from None
    out["size"] = (width, height)
    return out


def _named_runs(trajectory) -> dict[str, Any]:
    """name -> Trajectory (order kept)."""
    if isinstance(trajectory, Trajectory):
        items = [(str(trajectory.meta.get("backend", "run")), trajectory)]
    elif isinstance(trajectory, Mapping):
        items = [(str(k), v) for k, v in trajectory.items()]
    elif isinstance(trajectory, Sequence) and not isinstance(trajectory, (str, bytes)):
        items = [(str(getattr(v, "meta", {}).get("backend", f"run {i}")) if isinstance(v, Trajectory) else f"run {i}",
                  v) for i, v in enumerate(trajectory)]
    else:
        raise ValueError(f"trajectory={type(trajectory).__name__}: expected a Trajectory, a mapping name -> "
                         "Trajectory or a sequence of them")
    if not items:
        raise ValueError("trajectory: no runs given; expected at least one Trajectory")
    runs: dict[str, Any] = {}
    for name, run in items:
        if not isinstance(run, Trajectory):
            raise ValueError(f"run {name!r} is a {type(run).__name__}: expected an rbody.Trajectory")
        unique, k = name, 2
        while unique in runs:
            unique, k = f"{name} ({k})", k + 1
        runs[unique] = run
    return runs


def _checked_show(show, runs) -> tuple[str, ...]:
    if isinstance(show, str):
        show = (show,)
    show = tuple(show)
    for name in show:
        for run_name, run in runs.items():
            if name not in run:
                raise ValueError(f"show={name!r}: run {run_name!r} has no such observable; it has "
                                 f"{sorted(run.observables)}")
            value = np.asarray(run[name])
            if value.ndim > 2 or (value.ndim == 2 and value.shape[1] > 4):
                raise ValueError(f"show={name!r}: its values have shape {value.shape}; only scalars and vectors "
                                 "of up to 4 components are printed")
    return show


# ----- timing ------------------------------------------------------------------------------------------------

@dataclass(frozen=True)
class _Timing:
    """Frame times (F,) [s], the simulated interval between frames [s], the stride (samples of the first run
    per frame, None when unevenly sampled), the playback speed, and each run's sample index per frame."""

    times: np.ndarray
    interval: float
    stride: int | None
    speed: float
    indices: dict[str, np.ndarray]


def _timing(runs: Mapping[str, Any], speed: float, fps: float, max_frames: int, stride: int | None = None,
            interval: float | None = None) -> _Timing:
    start = max(float(run.t[0]) for run in runs.values())
    end = min(float(run.t[-1]) for run in runs.values())
    if end < start:
        raise ValueError(f"the runs share no time: they start at {start:g} s and one ends at {end:g} s")
    first = next(iter(runs.values())).t
    steps = np.diff(first)
    even = bool(len(steps)) and np.all(np.abs(steps - steps[0]) <= 1e-9 * max(abs(steps[0]), 1e-300)) and steps[0] > 0
    span = end - start
    if interval is None:
        wanted = speed / fps
        if even:
            stride = stride or max(1, int(round(wanted / steps[0])))
            interval = stride * float(steps[0])
        else:
            typical = float(np.median(steps)) if len(steps) else 0.0
            interval = max(wanted, typical)
    if span > 0 and interval > 0 and span / interval + 1 > max_frames:  # too many frames: fewer, further apart
        factor = math.ceil((span / interval + 1) / max_frames)
        interval *= factor
        stride = stride * factor if even and stride else stride
    count = int(math.floor(span / interval + 1e-9)) + 1 if span > 0 and interval > 0 else 1
    times = start + interval * np.arange(count)
    indices = {name: _sample_indices(run.t, times) for name, run in runs.items()}
    return _Timing(times, float(interval), stride if even else None, speed, indices)


def _sample_indices(t: np.ndarray, times: np.ndarray) -> np.ndarray:
    """Index of the last sample at or before each frame time (within round-off of the sampling)."""
    slack = 1e-9 * max(float(np.max(np.abs(t))), 1e-300)
    return np.clip(np.searchsorted(t, times + slack, side="right") - 1, 0, t.size - 1)


def _every_other(timing: _Timing, keep: int) -> _Timing:
    """Every `keep`-th frame of `timing` (stride and interval `keep` times larger)."""
    stride = None if timing.stride is None else timing.stride * keep
    return _Timing(timing.times[::keep], timing.interval * keep, stride, timing.speed,
                   {name: index[::keep] for name, index in timing.indices.items()})


def _durations(count: int, interval: float, speed: float, step_ms: int) -> list[int]:
    """Display durations [ms] of `count` frames, each interval / speed, in multiples of step_ms, rounded so that
    the running total keeps to simulated time."""
    seconds = interval / speed if speed > 0 else 0.1
    ends = np.round(np.arange(1, count + 1) * seconds * 1000 / step_ms) * step_ms
    durations = np.diff(np.concatenate([[0.0], ends]))
    return [int(max(step_ms, d)) for d in durations]


# ----- what each frame shows -------------------------------------------------------------------------------

def _motion_points(bodies: Mapping[str, Polygons], poses, timing: _Timing, limit: int = 60) -> np.ndarray:
    """World corners of every body's faces at up to `limit` frames spread over the run, every run: what the
    camera is fitted to."""
    picks = np.unique(np.linspace(0, len(timing.times) - 1, min(limit, len(timing.times))).round().astype(int))
    points = []
    for name, run_poses in poses.items():
        index = timing.indices[name][picks]
        for body, polygons in bodies.items():
            if not len(polygons.points):
                continue
            corners = np.unique(polygons.points.reshape(-1, 3), axis=0)
            pose = run_poses[body]
            rotation = quat_to_matrix(pose.quat[index])
            points.append((np.einsum("kab,nb->kna", rotation, corners) + pose.pos[index][:, None, :]).reshape(-1, 3))
    return np.concatenate(points) if points else np.zeros((0, 3))


def _planar(view: str, poses, points: np.ndarray) -> bool:
    """True for the side view: asked for, or (auto) every body of every run keeps one y and turns about y only."""
    if view != "auto":
        return view == "planar"
    extent = float(np.max(np.ptp(points, axis=0))) if len(points) else 1.0
    tolerance = PLANAR_TOLERANCE * max(extent, 1e-300)
    ys = np.concatenate([pose.com[:, 1] for run in poses.values() for pose in run.values()])
    if np.ptp(ys) > tolerance:
        return False
    off_axis = PLANAR_TOLERANCE ** 0.5  # quaternion x and z: a turn about an axis off y
    return all(np.max(np.abs(pose.quat[:, [1, 3]])) <= off_axis for run in poses.values() for pose in run.values())


def _marker(radius: float) -> Polygons:
    from rbody.drawing import shape_polygons

    return shape_polygons("sphere", (radius,))


def _rgb(colour: str) -> np.ndarray:
    to_rgb = optional("matplotlib.colors", "validation", "rbody.animate").to_rgb

    return np.asarray(to_rgb(colour), dtype=float)


def _colours(colours, layout, runs, arrangement) -> dict[tuple[str | None, str | None], np.ndarray]:
    """(run or None, body or None) -> RGB: bodies by body ("side"), or every body of a run by run ("overlay");
    (None, "fixed"), (None, "stage") the world's shapes."""
    colours = dict(colours or {})
    known = set(runs) | {b.name for b in layout.bodies}
    unknown = [k for k in colours if k not in known]
    if unknown:
        raise ValueError(f"colours names {unknown}, which are neither runs ({list(runs)}) nor bodies "
                         f"({[b.name for b in layout.bodies]})")
    try:
        out: dict[tuple[str | None, str | None], np.ndarray] = {
            (None, "fixed"): _rgb(FIXED_COLOUR), (None, "stage"): _rgb(STAGE_COLOUR)}
        if arrangement == "overlay":
            spare = iter(c for c in BODY_COLOURS if c not in RUN_COLOURS.values())
            for run in runs:
                out[(run, None)] = _rgb(colours.get(run) or RUN_COLOURS.get(run) or next(spare, "#444444"))
        else:
            for i, body in enumerate(layout.bodies):
                out[(None, body.name)] = _rgb(colours.get(body.name, BODY_COLOURS[i % len(BODY_COLOURS)]))
    except ValueError as error:
        raise ValueError(f"colours: {error}") from None
    return out


def _legend(legend, colour_of, layout, runs, arrangement) -> list[tuple[str, np.ndarray]]:
    """(label, RGB) of the legend: the runs' colours ("overlay"), or the bodies' named in `legend` ("side")."""
    if legend is False:
        return []
    if legend is not None and not isinstance(legend, Mapping):
        raise ValueError(f"legend={legend!r}: expected body name -> label, None or False")
    if arrangement == "overlay":
        if legend:
            raise ValueError("legend: bodies have their own colours only with arrangement='side'; 'overlay' "
                             "shows the runs' colours")
        return [(run, colour_of[(run, None)]) for run in runs]
    if not legend:
        return []
    names = [b.name for b in layout.bodies]
    unknown = [k for k in legend if k not in names]
    if unknown:
        raise ValueError(f"legend names {unknown}, which are not bodies of the scene ({names})")
    return [(str(label), colour_of[(None, body)]) for body, label in legend.items()]


class _Painter:
    """Builds each panel's content of a frame: bodies placed by their poses, projected, with text."""

    def __init__(self, camera, bodies, planes, fixed, stage, poses, runs, panel_runs, colour_of, shaded,
                 body_frames, shown, scale) -> None:
        self.camera, self.bodies, self.planes, self.fixed, self.stage = camera, bodies, planes, fixed, stage
        self.poses, self.runs, self.panel_runs, self.colour_of = poses, runs, panel_runs, colour_of
        self.shaded, self.body_frames, self.shown, self.scale = shaded, body_frames, shown, scale
        self.static_stage = visible_faces(camera, stage, np.tile(colour_of[(None, "stage")], (len(stage.points), 1)),
                                          shaded) if len(stage.points) else _empty()
        self.static_fixed = visible_faces(camera, fixed, np.tile(colour_of[(None, "fixed")], (len(fixed.points), 1)),
                                          shaded) if len(fixed.points) else _empty()
        self.reach = {name: max(p.reach, 1e-3 * scale) for name, p in bodies.items()}
        self.largest_reach = max(self.reach.values(), default=0.0)

    def _colour(self, run: str, body: str) -> np.ndarray:
        return self.colour_of.get((run, None), self.colour_of.get((None, body)))

    def contents(self, timing: _Timing, frame: int) -> list[PanelContent]:
        out = []
        for panel, names in enumerate(self.panel_runs):
            stage_parts, solid_parts, segments, colours = [self.static_stage], [self.static_fixed], [], []
            for order, run in enumerate(names):
                k = int(timing.indices[run][frame])
                # a later run's bodies are brought forward by twice the largest body's reach, so that where runs
                # (nearly) coincide the later one is drawn whole over the earlier, not face by face through it
                bias = 2.0 * self.largest_reach * order
                for body, polygons in self.bodies.items():
                    pose = self.poses[run][body]
                    rotation = quat_to_matrix(pose.quat[k])
                    world = polygons.moved(rotation, pose.pos[k])
                    rgb = np.tile(self._colour(run, body), (len(world.points), 1))
                    solid_parts.append(visible_faces(self.camera, world, rgb, self.shaded, bias))
                    if body in self.planes:
                        plane = self.planes[body].moved(rotation, pose.pos[k])
                        stage_parts.append(visible_faces(self.camera, plane, np.tile(
                            self.colour_of[(None, "stage")], (len(plane.points), 1)), self.shaded, bias))
                    if self.body_frames:
                        tips = pose.pos[k] + self.reach[body] * 0.8 * rotation.T
                        ends, _ = self.camera.project(np.vstack([pose.pos[k][None], tips]))
                        for a in range(3):
                            segments.append(np.stack([ends[0], ends[a + 1]]))
                            colours.append(_rgb(AXIS_COLOURS[a]))
            text = [TIME_FORMAT.format(float(timing.times[frame]))]
            for name in self.shown:
                for run in names:
                    value = np.asarray(self.runs[run][name])[int(timing.indices[run][frame])]
                    label = f"{name}" if len(names) == 1 else f"{name} ({run})"
                    text.append(f"{label} = {_format_value(value)}")
            out.append(PanelContent(_joined(stage_parts), _joined(solid_parts),
                                    (np.array(segments), np.array(colours)) if segments else None, "\n".join(text)))
        return out


def _empty() -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    return np.zeros((0, 4, 2)), np.zeros(0), np.zeros((0, 3))


def _joined(parts) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    parts = [p for p in parts if len(p[1])]
    if not parts:
        return _empty()
    return tuple(np.concatenate([p[i] for p in parts]) for i in range(3))  # type: ignore[return-value]


def _format_value(value) -> str:
    value = np.asarray(value)
    if value.ndim == 0:
        number = float(value)
        return str(int(number)) if number == int(number) and abs(number) < 1e15 else f"{number:.4g}"
    return "(" + ", ".join(f"{float(v):.3g}" for v in value.ravel()) + ")"


# ----- palette, rendering, encoding ---------------------------------------------------------------------------

def _palette(colour_of, shaded: bool):
    """One fixed Pillow palette image: greys from black to white, the body-frame colours, and every drawn colour
    with its shades (dark to full) and its blends with the white background (the edges Agg smooths)."""
    Image = optional("PIL.Image", "validation", "rbody.animate (Pillow, which matplotlib installs)")

    bases = list({tuple(np.round(c, 6)) for c in colour_of.values()})
    extras = [(g, g, g) for g in np.linspace(0.0, 1.0, 17)]  # the text's smoothed edges stay grey
    extras += [tuple(_rgb(c)) for c in AXIS_COLOURS]
    room = 256 - len(extras)
    blends = (0.25, 0.5, 0.75)
    levels = max(2, min(24, room // max(len(bases), 1) - len(blends)))
    lowest = 0.5 * 0.8 if shaded else 1.0  # AMBIENT times the darker pattern tone
    entries = list(extras)
    for base in bases:
        base = np.asarray(base)
        entries += [tuple(base * s) for s in np.linspace(lowest, 1.0, levels if shaded else 1)]
        entries += [tuple(base + (1.0 - base) * b) for b in blends]
    unique = list(dict.fromkeys(tuple(int(round(255 * v)) for v in e) for e in entries))[:256]
    flat = [v for rgb in unique for v in rgb]
    flat += flat[-3:] * (256 - len(unique))
    image = Image.new("P", (1, 1))
    image.putpalette(flat)
    return image


def _quantized(rgb: np.ndarray, palette) -> bytes:
    """A frame's pixels as palette indices, zlib-compressed."""
    Image = optional("PIL.Image", "validation", "rbody.animate (Pillow, which matplotlib installs)")

    indices = Image.fromarray(rgb).quantize(palette=palette, dither=Image.Dither.NONE)
    return zlib.compress(indices.tobytes(), 1)


class _Progress:
    """Progress lines: always, never, or (auto) once a render is predicted to take more than AUTO_SECONDS."""

    AUTO_SECONDS = 3.0

    def __init__(self, mode) -> None:
        self.mode = mode
        self.active = mode is True or callable(mode)
        self.last = 0.0
        self.tty = callable(mode) is False and hasattr(sys.stderr, "isatty") and sys.stderr.isatty()

    def consider(self, predicted_seconds: float) -> None:
        if self.mode is None and predicted_seconds > self.AUTO_SECONDS:
            self.active = True

    def line(self, text: str, *, final: bool = False, every: float = 1.0) -> None:
        if not self.active:
            return
        now = time.perf_counter()
        if not final and now - self.last < (every if self.tty else 5.0):
            return
        self.last = now
        if callable(self.mode):
            self.mode(text)
        elif self.tty:
            sys.stderr.write("\r" + text + ("\n" if final else "\x1b[K"))
            sys.stderr.flush()
        else:
            print(text, file=sys.stderr, flush=True)


def _progress(mode) -> _Progress:
    if not (mode is None or isinstance(mode, bool) or callable(mode)):
        raise ValueError(f"progress={mode!r}: expected None, True, False or a function of one line")
    return _Progress(mode)


def _render(timing: _Timing, painter: _Painter, canvas: Canvas, palette, report: _Progress,
            name: str) -> tuple[list[bytes], float]:
    """Every frame of `timing`, palette-quantised and compressed; the mean cost per frame [s]."""
    frames = []
    started = time.perf_counter()
    total = len(timing.times)
    for k in range(total):
        frames.append(_quantized(canvas.render(painter.contents(timing, k)), palette))
        spent = time.perf_counter() - started
        if k == 2:
            report.consider(spent / 3 * total)
        report.line(f"animating {name}: frame {k + 1}/{total}, {1e3 * spent / (k + 1):.0f} ms per frame, "
                    f"{spent / (k + 1) * (total - k - 1):.0f} s left"
                    + (f" (every {_ordinal(timing.stride)} saved sample)" if timing.stride else ""))
    return frames, (time.perf_counter() - started) / max(total, 1)


def _frames_of(frames: Sequence[bytes], size: tuple[int, int], palette) -> list:
    Image = optional("PIL.Image", "validation", "rbody.animate (Pillow, which matplotlib installs)")

    images = []
    for data in frames:
        image = Image.frombytes("P", size, zlib.decompress(data))
        image.putpalette(palette.getpalette())
        images.append(image)
    return images


def _encode(frames: Sequence[bytes], timing: _Timing, palette, size: tuple[int, int], suffix: str,
            target: Path) -> None:
    """Write `frames` to `target` in the format of `suffix`."""
    images = _frames_of(frames, size, palette)
    if suffix == ".gif":
        durations = _durations(len(images), timing.interval, timing.speed, 10)
        images[0].save(target, format="GIF", save_all=True, append_images=images[1:], duration=durations, loop=0,
                       optimize=False, disposal=1)
    elif suffix == ".webp":
        durations = _durations(len(images), timing.interval, timing.speed, 1)
        rgb = [image.convert("RGB") for image in images]
        rgb[0].save(target, format="WEBP", save_all=True, append_images=rgb[1:], duration=durations, loop=0,
                    lossless=True, quality=60, method=4)
    else:
        _encode_mp4(images, timing, target)


def _encode_mp4(images: Sequence, timing: _Timing, target: Path) -> None:
    ffmpeg = _ffmpeg()
    if ffmpeg is None:  # checked before rendering; gone since
        raise ValueError("MP4 needs ffmpeg, which is no longer installed")
    width, height = images[0].size
    rate = timing.speed / timing.interval if timing.interval > 0 else 1.0
    command = [ffmpeg, "-y", "-loglevel", "error", "-f", "rawvideo", "-pix_fmt", "rgb24", "-s", f"{width}x{height}",
               "-framerate", f"{rate:.6g}", "-i", "-", "-vf", "pad=ceil(iw/2)*2:ceil(ih/2)*2", "-c:v", "libx264",
               "-pix_fmt", "yuv420p", "-movflags", "+faststart", "-f", "mp4", str(target)]
    process = subprocess.Popen(command, stdin=subprocess.PIPE, stderr=subprocess.PIPE)
    try:
        for image in images:
            process.stdin.write(image.convert("RGB").tobytes())
        process.stdin.close()
    except BrokenPipeError:
        pass
    error = process.stderr.read().decode(errors="replace")
    if process.wait() != 0:
        raise RuntimeError(f"ffmpeg failed writing {target.name}: {error.strip()[-500:]}")


def _encoded_size(frames, timing, palette, size, suffix, folder: Path) -> int:
    import tempfile

    handle, name = tempfile.mkstemp(prefix=".probe.", suffix=suffix, dir=folder)
    os.close(handle)
    try:
        _encode(frames, timing, palette, size, suffix, Path(name))
        return os.path.getsize(name)
    finally:
        os.unlink(name)


def _fit_budget(timing: _Timing, painter: _Painter, canvas: Canvas, palette, suffix: str, max_bytes: float,
                report: _Progress) -> _Timing:
    """`timing` with its interval widened until the file is expected to fit max_bytes: frames probed in the
    middle of the run, encoded alone and together, give the bytes of the first frame and of each further one."""
    size = (canvas.width * canvas.panels, canvas.height)
    import tempfile

    folder = Path(tempfile.gettempdir())
    for _attempt in range(4):
        count = len(timing.times)
        if count <= PROBE_FRAMES:
            return timing
        middle = max(0, count // 2 - PROBE_FRAMES // 2)
        window = slice(middle, middle + PROBE_FRAMES)
        probe = _Timing(timing.times[window], timing.interval, timing.stride, timing.speed,
                        {n: i[window] for n, i in timing.indices.items()})
        started = time.perf_counter()
        frames = [_quantized(canvas.render(painter.contents(probe, k)), palette) for k in range(PROBE_FRAMES)]
        report.consider((time.perf_counter() - started) / PROBE_FRAMES * count)
        one = _encoded_size(frames[:1], probe, palette, size, suffix, folder)
        several = _encoded_size(frames, probe, palette, size, suffix, folder)
        each = max((several - one) / (PROBE_FRAMES - 1), 1.0)
        expected = one + each * (count - 1)
        if expected <= 0.9 * max_bytes:
            return timing
        keep = math.ceil(expected / (0.9 * max_bytes))
        report.line(f"size budget {max_bytes / 1e6:.3g} MB: {count} frames would take about {expected / 1e6:.3g} MB; "
                    f"keeping every {_ordinal(keep)} frame", final=True)
        timing = _every_other(timing, keep)
    return timing


def _write(frames: list[bytes], timing: _Timing, palette, size: tuple[int, int], path: Path,
           max_bytes: float) -> tuple[int, _Timing]:
    """Encode to `path` (a temporary name, renamed into place); while the file is over max_bytes, drop every
    other frame (each kept frame shown twice as long) and encode again. Returns the file's size and the timing
    of the frames kept. ValueError when even one frame is over max_bytes."""
    suffix = path.suffix.lower()
    while True:
        try:
            with atomic_path(path) as temporary:
                _encode(frames, timing, palette, size, suffix, temporary)
                written = os.path.getsize(temporary)
                if written > max_bytes:
                    if len(frames) == 1:
                        raise ValueError(f"max_bytes={max_bytes:g}: one frame of {size[0]}x{size[1]} px already "
                                         f"takes {written} bytes; give a larger budget or a smaller size")
                    raise _TooLarge()
            return written, timing
        except _TooLarge:
            frames, timing = frames[::2], _every_other(timing, 2)


class _TooLarge(Exception):
    """The encoded file is over its budget (caught by _write, which drops frames)."""
