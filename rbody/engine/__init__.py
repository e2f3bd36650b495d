"""rbody's native engine: minimal coordinates, compiled loops, exact events."""

from rbody.engine.methods import METHODS, METHOD_ORDER
from rbody.engine.simulate import simulate

__all__ = ["METHODS", "METHOD_ORDER", "simulate"]
