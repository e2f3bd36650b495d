"""URDF, the robot description format of ROS, Pinocchio, Drake and PyBullet: rbody reads it (parse.from_urdf).

See rbody.urdf.parse for what a read robot holds: which elements are read, recorded, ignored or refused, how
fixed and massless links are merged, and the joint order.
"""

from rbody.urdf.document import URDFError
from rbody.urdf.parse import ROOT_JOINT, URDFModel, URDFScene, from_urdf, layout_from_urdf

__all__ = ["from_urdf", "layout_from_urdf", "URDFError", "URDFModel", "URDFScene", "ROOT_JOINT"]
