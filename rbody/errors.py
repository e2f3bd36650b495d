"""Errors rbody raises beyond ValueError for bad input."""


class SimulationError(RuntimeError):
    """A run could not produce a trustworthy result: a step gave a non-finite state, the step is
    beyond the method's stability limit, or the method cannot run the scene. The message names the
    scene, the time, the step and what to try."""


class MethodNotApplicable(SimulationError, ValueError):
    """The chosen method does not apply to this scene (raised before any work); also a ValueError."""
