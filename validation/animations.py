"""The chapter's scenes in motion, every engine side by side: the animations of the main command's report and
of the README (docs/make_animations.py), drawn by rbody.animate.

- the rolling race (disc, hoop, solid sphere, spherical shell) down one incline;
- the swinging rod released near the top (theta0 = pi - 1e-3: it lingers there, swings through, and climbs
  back to the top on the other side, a period of 9.37 s; pymunk's pivot loses energy and falls short);
- the pi collisions (N = 2: 314 impacts), with each engine's collision counter;
- Newton's cradle, where MuJoCo and pymunk resolve the two touching balls' impacts at once and all three move.

The main command passes its own runs (case name -> (case, {engine: Trajectory})); the rod near the top, which
the main command does not run, is run here at the rod case's settings (validation/cases.py), in every engine
the main command ran. Each animation keeps within its size budget (README_MAX_BYTES: the four stay under 10 MB).
"""

from __future__ import annotations

from dataclasses import dataclass, field, replace
from pathlib import Path
from typing import Any, Callable, Mapping

import numpy as np

from validation.backends import BACKENDS, get, supports

README_MAX_BYTES = 2_400_000  # each of the four; together under 10 MB
ROD_NEAR_TOP = np.pi - 1e-3   # [rad]: the hard case's first rod (validation/hard)
ROD_NEAR_TOP_T_END = 10.0     # [s]: one period (9.37 s) and a little


@dataclass(frozen=True)
class Movie:
    """One animation: its file stem, caption, the case it draws and how (rbody.animate's options)."""

    name: str
    caption: str
    case: str
    options: Mapping[str, Any] = field(default_factory=dict)
    seconds: float | None = None  # playback length [s] where the run's own time would be too long (speed set)


MOVIES = (
    Movie("rolling_race_motion", "The rolling race, side by side in each engine: solid sphere first, then the disc, "
          "the spherical shell and the hoop", "rolling_race",
          {"azimuth": -70.0, "elevation": 15.0, "speed": 0.5}),
    Movie("swinging_rod_motion", "The swinging rod released 1e-3 rad from the top: it lingers, swings through and "
          "climbs back to the top (pymunk's pivot loses energy and falls short)", "swinging_rod_near_top", {}),
    Movie("pi_collisions_motion", "The pi collisions (M/m = 100^2): 314 impacts, counted in each engine",
          "pi_collisions_2",
          {"show": ("collisions",), "legend": {"ball_0": "light ball m", "ball_1": "heavy ball 10^4 m"}}, seconds=20.0),
    Movie("newtons_cradle_motion", "Newton's cradle: rbody passes the momentum through the touching balls; "
          "MuJoCo and pymunk resolve both impacts at once and all three balls move", "newtons_cradle",
          {"show": ("collisions",), "speed": 0.5}),
)


def rod_near_top_case(quick: bool = False):
    """The main command's swinging rod case, released near the top and run one period (a short run: quick)."""
    from rbody import scenes
    from validation.cases import pendulum_cases

    rod = next(c for c in pendulum_cases(quick) if c.name == "swinging_rod")
    scene = scenes.swinging_rod(1.0, theta0=ROD_NEAR_TOP, t_end=6.0 if quick else ROD_NEAR_TOP_T_END)
    return replace(rod, name="swinging_rod_near_top", scene=scene)


def run_case(case, engines=BACKENDS) -> dict[str, Any]:
    """engine -> Trajectory of `case` in every engine that supports it and runs it without failing."""
    runs = {}
    for engine in engines:
        if not supports(case.scene, engine)[0]:
            continue
        try:
            runs[engine] = get(engine).run(case.scene, case.dt[engine], None, **case.settings.get(engine, {}))
        except Exception:  # a failed run is reported by the tables, not drawn
            continue
    return runs


def chapter_animations(out: Path, runs: Mapping[str, tuple[Any, Mapping[str, Any]]] | None = None, *,
                       engines=BACKENDS, quick: bool = False, suffix: str = ".gif",
                       max_bytes: float = README_MAX_BYTES, size: tuple[int, int] | None = None,
                       say: Callable[[str], None] | None = None) -> list[tuple[str, str]]:
    """Write the MOVIES into folder `out`; returns (caption, file name) of each written.

    runs:  the main command's runs, case name -> (case, {engine: Trajectory}): the MOVIES of the cases it ran
           (the rod near the top where it ran the swinging rod, which is run here at its start); None: every case
           is run here (validation.cases, in `engines`); quick: the main command's quick cases, small pictures
    say:   called with one line per animation (its summary: frames, stride, size, cost per frame)
    """
    from rbody import animate
    from validation.cases import default_cases

    given = runs is not None
    runs = dict(runs or {})
    cases = None
    written = []
    for movie in MOVIES:
        if movie.case in runs:
            case, by_engine = runs[movie.case]
        elif given and not (movie.case == "swinging_rod_near_top" and "swinging_rod" in runs):
            continue  # the main command did not run this case
        else:
            if movie.case == "swinging_rod_near_top":
                case = rod_near_top_case(quick)
            else:
                cases = cases or {c.name: c for c in default_cases(quick)}
                case = cases[movie.case]
            by_engine = run_case(case, engines)
        by_engine = {e: by_engine[e] for e in engines if e in by_engine}
        if not by_engine:
            continue
        options = dict(movie.options)
        if movie.case == "rolling_race":
            options["legend"] = {f"body_{i}": label.replace("_", " ") for i, label in enumerate(case.scene.labels)}
        if movie.seconds is not None:
            options["speed"] = case.scene.t_end / (movie.seconds / 2 if quick else movie.seconds)
        height = 180 if quick else 300
        square = movie.case == "swinging_rod_near_top"  # the rod sweeps a circle
        panel = size or ((height, height) if square else (height * 4 // 3, height))
        animation = animate(case.scene, by_engine, Path(out) / f"{movie.name}{suffix}", size=panel,
                            fps=10.0 if quick else 25.0, max_bytes=max_bytes, progress=False, **options)
        if say is not None:
            say(animation.summary())
        written.append((movie.caption, animation.path.name))
    return written
