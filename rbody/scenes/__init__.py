"""The chapter's experiments: each a Scene factory whose scene carries its exact solution."""

from rbody.scenes.pendulum import compound_pendulum, swinging_rod
from rbody.scenes.chain import pendulum_chain
from rbody.scenes.rolling import rolling, rolling_race
from rbody.scenes.collisions import line_collisions, pi_collisions
from rbody.scenes.variable_mass import avalanche, rocket
from rbody.scenes.two_body import two_body
from rbody.scenes.particles import particles
from rbody.scenes.free_rotation import free_rotation
from rbody.scenes.stacked_balls import stacked_balls
from rbody.scenes.scattering import scattering

__all__ = ["compound_pendulum", "swinging_rod", "pendulum_chain", "rolling", "rolling_race", "line_collisions", "pi_collisions",
           "rocket", "avalanche", "two_body", "particles", "free_rotation",
           "stacked_balls", "scattering"]
