"""Fuzzing every scene factory with bad and extreme parameters (issue 12): each call either builds a scene
whose exact solution is finite where it is asked, or raises a ValueError (never another exception, a
crash or a silent NaN). Hypothesis picks one parameter at a time and puts a bad or extreme value in it."""

from __future__ import annotations

import warnings

import numpy as np
import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

from rbody import Inertia, scenes

BODY = Inertia(2.0, np.zeros(3), np.diag([1.0, 2.0, 3.0]))

# factory, its valid keyword arguments (positional ones by name too)
FACTORIES = {
    "swinging_rod": (scenes.swinging_rod, dict(length=1.0, theta0=0.5, t_end=1.0)),
    "compound_pendulum": (scenes.compound_pendulum, dict(body=BODY, pivot=(0.0, 0.0, 0.5), theta0=0.5, t_end=1.0)),
    "pendulum_chain": (scenes.pendulum_chain, dict(links=2, theta0=(1.0, 0.5), t_end=1.0)),
    "rolling": (scenes.rolling, dict(body="disc", radius=0.1, incline=0.3, t_end=1.0)),
    "rolling_race": (scenes.rolling_race, dict(radius=0.1, incline=0.3, length=1.0)),
    "line_collisions": (scenes.line_collisions, dict(masses=(1.0, 2.0), positions=(1.0, 2.0), velocities=(0.0, -1.0))),
    "pi_collisions": (scenes.pi_collisions, dict(digits=2)),
    "rocket": (scenes.rocket, dict(m0=100.0, burn_rate=10.0, exhaust_speed=50.0, dry_mass=40.0, t_end=8.0)),
    "avalanche": (scenes.avalanche, dict(slope=0.5, t_end=1.0)),
    "two_body": (scenes.two_body, dict(m1=1.0, m2=2.0, separation=(1.0, 0.0, 0.0), relative_velocity=(0.0, 0.0, 1.9),
                                       t_end=1.0)),
    "particles": (scenes.particles, dict(n=4, seed=1, t_end=0.5)),
    "free_rotation": (scenes.free_rotation, dict(inertia=BODY, omega0=(0.05, 2.0, 0.05), t_end=1.0)),
    "stacked_balls": (scenes.stacked_balls, dict(M=1.0, m=0.05, drop_height=1.0)),
    "scattering": (scenes.scattering, dict(impact_parameter=0.1, radius=0.1)),
}

BAD_VALUES = [float("nan"), float("inf"), -float("inf"), -1.0, 0.0, 1e308, -1e308, 1e-308, 5e-324, 1e-300, 1e300,
              "x", None, (), (1.0, 2.0), ((1.0,),), True, -7, 10**40, complex(1, 1)]


def _call(name: str, replace: dict):
    factory, kwargs = FACTORIES[name]
    arguments = dict(kwargs, **replace)
    import inspect

    signature = inspect.signature(factory)
    positional = [p.name for p in signature.parameters.values() if p.kind is p.POSITIONAL_OR_KEYWORD]
    args = [arguments.pop(p) for p in positional if p in arguments]
    return factory(*args, **arguments)


@pytest.mark.parametrize("name", sorted(FACTORIES))
def test_the_valid_arguments_build_a_scene(name):
    assert _call(name, {}).t_end > 0


@pytest.mark.parametrize("name", sorted(FACTORIES))
@settings(max_examples=40, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(data=st.data())
def test_bad_or_extreme_parameter_is_a_value_error_or_a_finite_scene(name, data):
    _factory, kwargs = FACTORIES[name]
    parameter = data.draw(st.sampled_from(sorted(kwargs) + ["gravity", "t_end"]), label="parameter")
    value = data.draw(st.sampled_from(BAD_VALUES), label="value")
    if name in ("pi_collisions", "particles") and parameter in ("digits", "n") and isinstance(value, int) \
            and not isinstance(value, bool) and value > 20:
        value = 40  # a huge whole number: still refused, without building 10^40 of anything
    with warnings.catch_warnings():
        warnings.simplefilter("ignore", RuntimeWarning)  # judged by the result: a ValueError or finite values
        try:
            scene = _call(name, {parameter: value})
        except ValueError as error:
            assert str(error), "a ValueError must say what is wrong"
            assert len(str(error)) < 2000
            return
        except TypeError as error:  # a keyword the factory does not take (gravity, t_end on some)
            assert "argument" in str(error)
            return
        t = np.linspace(0.0, min(float(scene.t_end), 1e6), 3)
        try:
            exact = scene.exact(t)
        except (ValueError, NotImplementedError):
            return  # refusing to evaluate is allowed; a NaN is not
        for key, values in exact.items():
            values = np.asarray(values)
            if values.dtype.kind == "f" and key not in ("arrival_time", "arrival_times"):
                assert np.all(np.isfinite(values)), f"{name}({parameter}={value!r}): exact {key} not finite"
