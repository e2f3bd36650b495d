"""MuJoCo on rbody's rolling reduction (validation.bench.reduced): the slide+hinge variant is rbody.to_mjcf of
the scene's rolling tree (one roll joint per body), the slide variant a slide with armature I / R^2.

Measured (mujoco 4.0, RK4, disc a = 0.1 m on 0.5 rad, 1 s): slide+hinge distance error 4.20e-8 m at
dt = 1e-3 and 4.20e-10 m at 1e-4 (the soft equality, dt^2), slip 2.3e-5 and 2.3e-6 m/s (dt); slide 1.6e-15 m.
The same figures, to 1e-17 m, as the hand-written model this variant replaced.
"""

from __future__ import annotations

import numpy as np
import pytest

mujoco = pytest.importorskip("mujoco")

from rbody.mjcf import EQUALITY_SOLIMP  # noqa: E402
from rbody.scenes import rolling, rolling_race  # noqa: E402
from validation.bench import reduced  # noqa: E402

pytestmark = pytest.mark.crosssim


def test_slide_and_hinge_variant_is_the_exported_rolling_tree():
    race = rolling_race(("disc", "solid_sphere"), radius=0.1, incline=0.3, length=1.0)
    xml = reduced.reduced_mjcf(race, "slide+hinge", 1e-3, "RK4")
    model = mujoco.MjModel.from_xml_string(xml)
    names = [model.joint(j).name for j in range(model.njnt)]
    assert names == ["roll_0_slide", "roll_0", "roll_1_slide", "roll_1"]
    assert model.neq == 2
    np.testing.assert_allclose(model.eq_solimp[:, :3], [EQUALITY_SOLIMP] * 2, rtol=1e-15)
    np.testing.assert_allclose(model.eq_data[:, 1], [0.1, 0.1], rtol=1e-15)


@pytest.mark.parametrize("variant, bound", [("slide", 1e-13), ("slide+hinge", 1e-7)])
def test_reduced_runs_follow_the_closed_form(variant, bound):
    scene = rolling("disc", radius=0.1, incline=0.5, t_end=1.0)
    run = reduced.run(scene, 1e-3, variant=variant)
    exact = scene.exact(run.t)
    assert np.max(np.abs(run["distance"] - exact["distance"])) <= bound
    race = rolling_race(("disc", "hollow_cylinder"), radius=0.1, incline=0.3, length=1.0)
    run = reduced.run(race, 1e-3, variant=variant)
    assert run["distance"].shape == (run.t.size, 2)
    np.testing.assert_allclose(run["arrival_time"][-1], race.arrival_time, rtol=1e-5)
