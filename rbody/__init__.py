"""rbody: rigid-body mechanics from first principles, every scene with its exact solution.

Units are SI throughout; z is up; quaternions are (w, x, y, z); inertia tensors are about the
centre of mass with products of inertia carrying the minus sign (I_ab = sum m (|x|^2 d_ab - x_a x_b)).
"""

from rbody.inertia import Inertia
from rbody.motion import RigidMotion, point_velocity
from rbody.particles import Particles, reduced_mass, two_body
from rbody.layout import Actuator, Body, Contact, Equality, Joint, Layout, Shape, Tendon
from rbody.scene import Scene
from rbody.trajectory import Trajectory
from rbody.errors import AccuracyWarning, MethodNotApplicable, SimulationError
from rbody.engine import METHODS, METHOD_ORDER, stability
from rbody.simulation import PreparedRun, prepare, simulate
from rbody.engine.system import Multibody
from rbody.mjcf import from_mjcf, to_mjcf
from rbody.urdf import from_urdf
from rbody import scenes
from rbody.animation import Animation, animate

__all__ = [
    "Inertia", "RigidMotion", "point_velocity", "Particles", "reduced_mass", "two_body",
    "Actuator", "Body", "Contact", "Equality", "Joint", "Layout", "Scene", "Shape", "Tendon", "Trajectory",
    "SimulationError", "MethodNotApplicable", "AccuracyWarning", "METHODS", "METHOD_ORDER", "simulate", "prepare", "PreparedRun", "scenes",
    "to_mjcf", "from_mjcf", "from_urdf", "Multibody", "stability", "animate", "Animation",
]
