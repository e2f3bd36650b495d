"""The constraint layer's closed forms as hard cases for MuJoCo (validation.hard.constraints): the same file in both
engines at dt = 1 ms (MuJoCo: RK4, its default softness), each run measured against the closed form.

rbody must meet each closed form to the bounds below (its tests in tests/rbody/engine/test_constraint_closed_forms.py
bound them tighter); MuJoCo's divergence is a finding, measured and asserted as such (it is larger than rbody's by
orders of magnitude), never hidden by a tolerance. The values measured on this machine (MuJoCo 3.x, dt = 1 ms):

    limit_pendulum       passes its stop by 0.024 rad, comes back 7.6 ms late, swings 0.032 rad beyond 0.5
    elastic_limit        (solreflimit "-1e5 0") passes its stop by 0.0099 rad, rebounds 9.9 ms late, 5.6e-4 rad low
    friction_oscillator  stops 9.8e-4 m off, and creeps 1.0e-3 m in the last second (rbody: 0, exactly)
    friction_pendulum    stops 8.4e-3 rad off, and creeps 1.0e-3 rad in the last second
    four_bar             loop open by 1.7e-4 m, period off by 4e-5 s
    coupling             the 1:1 coupling is off by 3.5e-4 rad
    limbs                joints 0.17 rad past their stops after t = 0, still 6.3e-3 rad past at 1 s
"""

from __future__ import annotations

import pytest

from validation.hard.constraints import CASES, divergence

pytestmark = pytest.mark.crosssim

# rbody's bounds (what the closed form allows at dt = 1 ms, the measure's own resolution included)
RBODY = {
    "limit_pendulum": {"past the stop [rad]": 1e-15, "rebound time [s]": 1e-10, "swing after [rad]": 1e-10},
    "elastic_limit": {"past the stop [rad]": 1e-15, "rebound time [s]": 1e-10, "rebound height [rad]": 1e-10},
    "friction_oscillator": {"stop [m]": 1e-11, "creep in the last second [m]": 0.0},
    "friction_pendulum": {"stop [rad]": 1e-10, "creep in the last second [rad]": 0.0},
    "four_bar": {"loop error [m]": 1e-14, "period [s]": 1e-9},
    "coupling": {"coupling error [rad]": 1e-14},
    "limbs": {"past a stop after t = 0 [rad]": 1e-12, "past a stop at the end [rad]": 1e-12},
}
# MuJoCo's divergence found (each at least this large: a finding, not a tolerance)
MUJOCO_FOUND = {
    "limit_pendulum": {"past the stop [rad]": 1e-2, "rebound time [s]": 1e-3, "swing after [rad]": 1e-2},
    "elastic_limit": {"past the stop [rad]": 1e-3, "rebound time [s]": 1e-3, "rebound height [rad]": 1e-4},
    "friction_oscillator": {"stop [m]": 1e-4, "creep in the last second [m]": 1e-4},
    "friction_pendulum": {"stop [rad]": 1e-3, "creep in the last second [rad]": 1e-4},
    "four_bar": {"loop error [m]": 1e-5, "period [s]": 1e-6},
    "coupling": {"coupling error [rad]": 1e-5},
    "limbs": {"past a stop after t = 0 [rad]": 1e-2, "past a stop at the end [rad]": 1e-3},
}


@pytest.mark.parametrize("name", list(CASES))
def test_rbody_meets_the_closed_form_and_mujoco_diverges_from_the_rigid_limit(name):
    dt = 2e-3 if name == "limbs" else 1e-3
    ours = divergence(name, "rbody", dt)
    theirs = divergence(name, "mujoco", dt)
    for metric, bound in RBODY[name].items():
        assert ours[metric] <= bound, (name, metric, ours[metric])
    for metric, found in MUJOCO_FOUND[name].items():
        assert theirs[metric] >= found, (name, metric, theirs[metric])  # a finding: MuJoCo's soft constraints
