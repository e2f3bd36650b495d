"""MJCF, MuJoCo's model format: rbody writes it (export.to_mjcf) and reads it (parse.from_mjcf).

See rbody.mjcf.export for what a written model holds, and rbody.mjcf.parse for what a read model may
contain (supported, ignored and refused elements).
"""

from rbody.mjcf.export import (CONTACT_SOLIMP, DEFAULT_TIMESTEP, EQUALITY_SOLIMP, INITIAL_KEY, MUJOCO_MIN_MASS,
                               MUJOCO_MIN_MOMENT, ExportedInertia, body_order, contact_parameters, exported_inertia, has_impacts,
                               impact_damping_ratio, initial_state, joint_order, pushing_restitution,
                               ROLL_SLIDE_SUFFIX, shape_inertia, to_mjcf)
from rbody.mjcf.document import MJCFError
from rbody.mjcf.parse import MJCFModel, MJCFScene, from_mjcf, layout_from_mjcf

__all__ = ["to_mjcf", "from_mjcf", "layout_from_mjcf", "MJCFError", "MJCFModel", "MJCFScene", "exported_inertia",
           "ExportedInertia", "contact_parameters", "initial_state", "body_order", "joint_order", "has_impacts",
           "shape_inertia", "impact_damping_ratio", "pushing_restitution", "DEFAULT_TIMESTEP", "INITIAL_KEY",
           "CONTACT_SOLIMP", "EQUALITY_SOLIMP", "ROLL_SLIDE_SUFFIX", "MUJOCO_MIN_MOMENT",
           "MUJOCO_MIN_MASS"]
