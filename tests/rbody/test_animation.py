"""rbody.animate: the pixels of the frames, not only the file. Small pictures, few frames.

A body drawn in one flat colour (shaded=False) is found in each frame by its colour: the centroid of its
pixels must be the projection of its centre of mass (Animation.project), runs that diverge must be drawn
apart by their divergence, a body at rest must not move, and every shape kind must show."""

import os
import stat

import numpy as np
import pytest
from PIL import Image

import rbody
from rbody import Body, Inertia, Joint, Layout, Scene, Shape, Trajectory, animate, scenes
from rbody.animation import BODY_COLOURS, STAGE_COLOUR
from rbody.drawing import SEGMENTS, shape_polygons

SIZE = (160, 120)


def rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i:i + 2], 16) for i in (1, 3, 5)])


def frames_at(animation) -> list[tuple[int, np.ndarray]]:
    """(index into animation.times, RGB frame) of every frame in the file, found from the frames' durations
    (a GIF merges a frame identical to the one before it into that one's duration)."""
    image = Image.open(animation.path)
    nominal = animation.interval / animation.speed * 1000
    out, start = [], 0.0
    for k in range(getattr(image, "n_frames", 1)):
        image.seek(k)
        out.append((int(round(start / nominal)), np.asarray(image.convert("RGB"))))
        start += image.info["duration"]
    return out


def pixels_of(frame: np.ndarray, colour: str, columns: slice = slice(None)) -> np.ndarray:
    """(N, 2) continuous pixel coordinates (column, row) of the centres of the pixels of exactly `colour`."""
    rows, cols = np.nonzero(np.all(frame[:, columns] == rgb(colour), axis=-1))
    offset = columns.start or 0
    return np.stack([cols + offset + 0.5, rows + 0.5], axis=1)


def sample_index(t: np.ndarray, time: float) -> int:
    return int(np.searchsorted(t, time + 1e-9, side="right") - 1)


def bob_scene(theta0=1.2, radius=0.15, joint="hinge"):
    """A ball on an arm: the body frame at the pivot, the centre of mass and the sphere 0.6 m below it."""
    bob = Body("bob", Inertia.solid_sphere(1.0, radius).translated([0.0, 0.0, -0.6]),
               shapes=(Shape("ball", "sphere", (radius,), pos=(0.0, 0.0, -0.6)),))
    if joint == "hinge":
        pin = Joint("pin", "hinge", "bob", axis=(0, 1, 0), qpos0=theta0)
    else:
        pin = Joint("pin", "ball", "bob", qpos0=(np.cos(0.4), np.sin(0.4), 0.0, 0.0), qvel0=(0.0, 0.0, 3.0))
    return Scene.from_layout(Layout(bodies=(bob,), joints=(pin,)), t_end=2.0)


@pytest.mark.parametrize("view", ["planar", "3d"])
def test_a_body_is_drawn_at_its_centre_of_mass_in_every_frame(tmp_path, view):
    scene = bob_scene(joint="hinge" if view == "planar" else "ball")
    run = rbody.simulate(scene, dt=1e-3, method="rk4")
    animation = animate(scene, run, tmp_path / "bob.gif", size=SIZE, fps=5, shaded=False, progress=False)
    assert animation.frames == 11 and animation.stride == 200
    seen = frames_at(animation)
    assert len(seen) >= 8
    centre = np.array(SIZE) / 2
    for index, frame in seen:
        k = sample_index(run.t, animation.times[index])
        com = run["bob.com"][k]
        drawn = pixels_of(frame, BODY_COLOURS[0])
        expected = animation.project(com)
        # in perspective a sphere's image is displaced from its centre's by about (r / depth)^2 times its
        # distance from the middle of the view
        depth = animation.camera.camera_coordinates(com)[2]
        bound = 0.5 + (0.0 if view == "planar" else 1.5 * (0.15 / depth) ** 2 * np.linalg.norm(expected - centre))
        assert np.linalg.norm(drawn.mean(axis=0) - expected) < bound, (index, drawn.mean(axis=0), expected)
        # its size too: a disc of the sphere's radius, in pixels
        radius_px = np.linalg.norm(animation.project(com + 0.15 * animation.camera.basis[1]) - expected)
        assert abs(len(drawn) / (np.pi * radius_px**2) - 1) < 0.12
        # and not at the body frame's origin, the pivot 0.6 m away
        assert np.linalg.norm(animation.project(np.zeros(3)) - expected) > 10


def test_a_family_scene_is_drawn_where_its_closed_form_puts_it(tmp_path):
    disc = scenes.rolling("disc", radius=0.1, incline=0.5, t_end=0.6)
    run = rbody.simulate(disc, dt=1e-3)
    animation = animate(disc, run, tmp_path / "disc.gif", size=SIZE, fps=5, shaded=False, progress=False)
    down, normal = np.array([np.cos(0.5), 0, -np.sin(0.5)]), np.array([np.sin(0.5), 0, np.cos(0.5)])
    for index, frame in frames_at(animation):
        com = 0.1 * normal + disc.exact([animation.times[index]])["distance"][0] * down
        drawn = pixels_of(frame, BODY_COLOURS[0])
        assert np.linalg.norm(drawn.mean(axis=0) - animation.project(com)) < 0.5
        assert len(pixels_of(frame, STAGE_COLOUR)) > 100  # the incline, drawn as the stage


def test_two_runs_that_diverge_are_drawn_apart(tmp_path):
    scene = bob_scene(theta0=2.5)
    accurate = rbody.simulate(scene, dt=1e-2, method="rk4")
    drifting = rbody.simulate(scene, dt=1e-2, method="euler")  # gains energy: swings higher, later
    runs = {"rk4": accurate, "euler": drifting}
    width = SIZE[0]
    side = animate(scene, runs, tmp_path / "side.gif", size=SIZE, fps=5, shaded=False, progress=False)
    overlay = animate(scene, runs, tmp_path / "overlay.gif", size=SIZE, fps=5, shaded=False, progress=False,
                      arrangement="overlay", colours={"rk4": "#1f77b4", "euler": "#d62728"}, legend=False)
    assert side.width == 2 * width and overlay.width == width and side.panels == ("rk4", "euler")
    apart = []
    for (index, frame), (index_2, frame_2) in zip(frames_at(side), frames_at(overlay)):
        assert index == index_2
        coms = [run["bob.com"][sample_index(run.t, side.times[index])] for run in (accurate, drifting)]
        for panel, com in enumerate(coms):  # each panel draws its own run
            drawn = pixels_of(frame, BODY_COLOURS[0], slice(panel * width, (panel + 1) * width))
            assert np.linalg.norm(drawn.mean(axis=0) - side.project(com, panel)) < 0.5
        separation = np.linalg.norm(overlay.project(coms[0]) - overlay.project(coms[1]))
        radius_px = np.linalg.norm(overlay.project(coms[0] + 0.15 * overlay.camera.basis[1]) - overlay.project(coms[0]))
        if separation > 2.2 * radius_px:  # the two balls do not overlap: each whole in its own colour
            a, b = pixels_of(frame_2, "#1f77b4").mean(axis=0), pixels_of(frame_2, "#d62728").mean(axis=0)
            assert np.linalg.norm(a - overlay.project(coms[0])) < 0.5
            assert np.linalg.norm(b - overlay.project(coms[1])) < 0.5
            apart.append(np.linalg.norm(a - b))
    assert apart and max(apart) > 20  # the divergence is drawn, tens of pixels


def test_a_body_at_rest_does_not_move_between_frames(tmp_path):
    # Newton's cradle in rbody: ball 1 never moves (the momentum passes through it), ball 0 stops at the impact
    cradle = scenes.line_collisions((1.0, 1.0, 1.0), (0.0, 0.5, 0.7), (1.0, 0.0, 0.0), radii=0.1, walls=(),
                                    t_end=1.0)
    run = rbody.simulate(cradle, dt=1e-3)
    animation = animate(cradle, run, tmp_path / "cradle.gif", size=SIZE, fps=10, shaded=False, progress=False)
    # each ball's pixels in a band about its centre, clear of the edges where a neighbour comes to touch it
    # (there the smoothing of the two edges changes)
    radius = 0.1 * animation.camera.focal / animation.camera.distance * SIZE[1] / 2  # [px]
    masks = {i: [] for i in range(3)}
    for index, frame in frames_at(animation):
        columns = np.arange(SIZE[0]) + 0.5
        for i in range(3):
            centre = animation.project(run["positions"][sample_index(run.t, animation.times[index]), i] * np.eye(3)[0])
            band = np.abs(columns - centre[0]) < radius - 2
            masks[i].append((animation.times[index], np.all(frame == rgb(BODY_COLOURS[i]), axis=-1) & band))
    for _, mask in masks[1]:
        assert mask.sum() > 30 and np.array_equal(mask, masks[1][0][1])
    after = [mask for time, mask in masks[0] if time > 0.31]
    assert len(after) > 3 and all(np.array_equal(m, after[0]) for m in after)
    assert not np.array_equal(masks[0][0][1], after[0])      # it moved before the impact
    assert not np.array_equal(masks[2][0][1], masks[2][-1][1])  # the last ball flies off


def _volume_and_outward(polygons) -> tuple[float, bool]:
    """Enclosed volume by the divergence theorem, sum of (centroid . n) area / 3, and whether every normal
    points away from the origin (a convex shape around it)."""
    p = polygons.points
    area = 0.5 * (np.linalg.norm(np.cross(p[:, 1] - p[:, 0], p[:, 2] - p[:, 0]), axis=1)
                  + np.linalg.norm(np.cross(p[:, 2] - p[:, 0], p[:, 3] - p[:, 0]), axis=1))
    centroid = p.mean(axis=1)
    outward = np.sum(centroid * polygons.normals, axis=1)
    return float(np.sum(outward * area) / 3), bool(np.all(outward[area > 1e-12] > 0))


@pytest.mark.parametrize("kind, size, volume", [
    ("sphere", (0.5,), 4 / 3 * np.pi * 0.5**3),
    ("ellipsoid", (0.3, 0.5, 0.8), 4 / 3 * np.pi * 0.3 * 0.5 * 0.8),
    ("cylinder", (0.2, 0.6), np.pi * 0.2**2 * 1.2),
    ("capsule", (0.2, 0.6), np.pi * 0.2**2 * 1.2 + 4 / 3 * np.pi * 0.2**3),
    ("box", (0.1, 0.2, 0.3), 0.2 * 0.4 * 0.6),
])
def test_every_solid_shape_is_tessellated_closed_with_outward_faces(kind, size, volume):
    polygons = shape_polygons(kind, size)
    enclosed, outward = _volume_and_outward(polygons)
    assert outward and polygons.closed
    # inscribed polygons: a little less than the exact volume (24 facets around, 10 rings: within 5 %)
    assert 0.95 * volume < enclosed <= volume * (1 + 1e-12)
    extent = np.ptp(polygons.points.reshape(-1, 3), axis=0) / 2
    if kind in ("cylinder", "capsule"):
        half = (size[0], size[0], size[1] + (size[0] if kind == "capsule" else 0.0))
    else:
        half = size * (3 // len(size))
    np.testing.assert_allclose(extent, half, rtol=1 - np.cos(np.pi / SEGMENTS))


def test_every_shape_kind_draws(tmp_path):
    import trimesh

    mesh = tmp_path / "tetra.stl"
    trimesh.creation.icosphere(subdivisions=1, radius=0.12).export(mesh)
    kinds = [Shape("sphere", "sphere", (0.12,)), Shape("cylinder", "cylinder", (0.1, 0.12)),
             Shape("capsule", "capsule", (0.08, 0.1)), Shape("box", "box", (0.1, 0.12, 0.1)),
             Shape("mesh", "mesh", mesh=str(mesh))]
    bodies = tuple(Body(s.name, Inertia.solid_sphere(1.0, 0.1), shapes=(s,), pos=(0.5 * i, 0.0, 0.3))
                   for i, s in enumerate(kinds))
    joints = tuple(Joint(f"z_{s.name}", "slide", s.name, axis=(0, 0, 1)) for s in kinds)
    floor = Shape("floor", "plane", (0.0, 0.0))  # infinite: drawn as far as the view reaches
    scene = Scene.from_layout(Layout(bodies=bodies, joints=joints, fixed=(floor,)), t_end=0.1, gravity=0.0)
    run = rbody.simulate(scene, dt=0.05, method="rk4")
    # orthographic, from above and aside: each shape's outline is symmetric about its centre, the centroid of its
    # pixels the projection of its centre (the frames' axes are drawn only in the second picture)
    animation = animate(scene, run, tmp_path / "kinds.gif", size=(240, 120), fps=10, shaded=False, view="planar",
                        azimuth=-60, elevation=25, progress=False)
    _index, frame = frames_at(animation)[0]
    for i, shape in enumerate(kinds):
        drawn = pixels_of(frame, BODY_COLOURS[i])
        assert len(drawn) > 60, shape.kind
        assert np.linalg.norm(drawn.mean(axis=0) - animation.project(bodies[i].pos)) < 0.5, shape.kind
    assert len(pixels_of(frame, STAGE_COLOUR)) > 2000  # the floor
    animation = animate(scene, run, tmp_path / "kinds.gif", size=(240, 120), fps=10, body_frames=True,
                        progress=False)
    _index, frame = frames_at(animation)[0]
    assert np.any(np.all(frame == rgb("#ff0000"), axis=-1))  # a body frame's x axis


def test_bad_input_is_refused_before_any_rendering(tmp_path, monkeypatch):
    import rbody.animation as module

    def no_rendering(*args, **kwargs):
        raise AssertionError("rendering started")

    monkeypatch.setattr(module, "Canvas", no_rendering)
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=0.5)
    run = rbody.simulate(rod, dt=1e-3)
    with pytest.raises(ValueError, match=r"suffix '\.png'"):
        animate(rod, run, tmp_path / "rod.png")
    with pytest.raises(ValueError, match="is a folder"):
        animate(rod, run, tmp_path)
    (tmp_path / "file").write_text("")
    with pytest.raises(ValueError, match="not a folder"):
        animate(rod, run, tmp_path / "file" / "rod.gif")
    monkeypatch.setattr(module, "_ffmpeg", lambda: None)
    with pytest.raises(ValueError, match="MP4 needs ffmpeg"):
        animate(rod, run, tmp_path / "rod.mp4")
    cradle = scenes.line_collisions((1.0, 1.0), (0.0, 0.5), (1.0, 0.0), radii=0.1, walls=(), t_end=1.0)
    other = rbody.simulate(cradle, dt=1e-2)
    with pytest.raises(ValueError, match="run of scene 'line_collisions'"):
        animate(rod, other, tmp_path / "rod.gif")
    three = scenes.line_collisions((1.0, 1.0, 1.0), (0.0, 0.5, 0.7), (1.0, 0.0, 0.0), radii=0.1, walls=(), t_end=1.0)
    with pytest.raises(ValueError, match="expected .* for scene"):
        animate(three, Trajectory(other.t, {"positions": other["positions"]}), tmp_path / "three.gif")
    with pytest.raises(ValueError, match="is a batch"):
        animate(scenes.swinging_rod(1.0, theta0=np.array([0.5, 1.0]), t_end=0.5), run, tmp_path / "rods.gif")
    particles = scenes.particles(3, seed=1, t_end=0.1)
    with pytest.raises(ValueError, match="no layout"):
        animate(particles, rbody.simulate(particles, dt=1e-2, method="rk4"), tmp_path / "p.gif")
    for options, message in (({"speed": 0.0}, "speed"), ({"fps": 100}, "fps"), ({"size": (10, 10)}, "size"),
                             ({"arrangement": "grid"}, "arrangement"), ({"view": "top"}, "view"),
                             ({"show": ("nope",)}, "show='nope'"), ({"colours": {"ghost": "red"}}, "ghost"),
                             ({"max_frames": 0}, "max_frames"), ({"elevation": 95}, "elevation"),
                             ({"progress": "loud"}, "progress"), ({"legend": {"ghost": "x"}}, "legend names")):
        with pytest.raises(ValueError, match=message):
            animate(rod, run, tmp_path / "rod.gif", **options)
    with pytest.raises(ValueError, match="expected an rbody.Trajectory"):
        animate(rod, {"a": run, "b": run["theta"]}, tmp_path / "rod.gif")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]  # nothing written


def test_the_file_keeps_to_its_size_budget_and_states_the_stride(tmp_path):
    rod = scenes.swinging_rod(1.0, theta0=3.0, t_end=4.0)
    run = rbody.simulate(rod, dt=1e-3)
    free = animate(rod, run, tmp_path / "free.gif", size=SIZE, progress=False)
    lines = []
    budget = free.bytes // 4
    tight = animate(rod, run, tmp_path / "tight.gif", size=SIZE, max_bytes=budget, progress=lines.append)
    assert free.stride == 40 and free.frames == 101  # 25 frames/s of a run saved every ms
    assert tight.bytes <= budget and os.path.getsize(tight.path) == tight.bytes
    assert tight.stride > free.stride and tight.frames < free.frames
    assert tight.interval == pytest.approx(tight.stride * 1e-3)
    assert f"every {tight.stride}th of 4001 saved samples" in tight.summary()
    assert any("size budget" in line for line in lines) and lines[-1].startswith("wrote tight.gif")


def test_playback_follows_simulated_time(tmp_path):
    rod = scenes.swinging_rod(1.0, theta0=2.0, t_end=2.0)
    run = rbody.simulate(rod, dt=1e-3)
    for speed in (1.0, 0.5):
        animation = animate(rod, run, tmp_path / f"rod_{speed}.gif", size=SIZE, fps=10, speed=speed,
                            progress=False)
        image = Image.open(animation.path)
        total = 0
        for k in range(image.n_frames):
            image.seek(k)
            total += image.info["duration"]
        assert animation.interval == pytest.approx(0.1 * speed)
        # the frames span the run, each shown interval / speed: 2 s of motion take 2 / speed s
        assert total == pytest.approx(animation.frames * animation.interval / speed * 1000, abs=10)
        assert animation.times[-1] == pytest.approx(2.0)


def test_webp_and_a_shown_observable(tmp_path):
    pi = scenes.pi_collisions(1, speed=0.1, spacing=0.3)
    run = rbody.simulate(pi, dt=pi.t_end / 200)
    animation = animate(pi, run, tmp_path / "pi.webp", size=SIZE, fps=10, speed=pi.t_end / 4, show="collisions",
                        progress=False)
    image = Image.open(animation.path)
    assert image.format == "WEBP" and image.n_frames == animation.frames == 41


def test_mp4_frames_reach_ffmpeg(tmp_path, monkeypatch):
    # a stand-in for ffmpeg that writes the number of bytes it was given into the output file
    fake = tmp_path / "bin" / "ffmpeg"
    fake.parent.mkdir()
    fake.write_text("#!/bin/sh\nfor last; do :; done\nwc -c | tr -d ' ' > \"$last\"\n")
    fake.chmod(fake.stat().st_mode | stat.S_IEXEC)
    monkeypatch.setenv("PATH", f"{fake.parent}{os.pathsep}{os.environ['PATH']}")
    rod = scenes.swinging_rod(1.0, theta0=1.0, t_end=1.0)
    run = rbody.simulate(rod, dt=1e-3)
    animation = animate(rod, run, tmp_path / "rod.mp4", size=SIZE, fps=10, progress=False)
    assert int(animation.path.read_text()) == animation.frames * SIZE[0] * SIZE[1] * 3
