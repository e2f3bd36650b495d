"""Errors rbody raises beyond ValueError for bad input."""


class SimulationError(RuntimeError):
    """A run could not produce a trustworthy result: a step gave a non-finite state, the step is
    beyond the method's stability limit, or the method cannot run the scene. The message names the
    scene, the time, the step and what to try."""


class MethodNotApplicable(SimulationError, ValueError):
    """The chosen method does not apply to this scene (raised before any work); also a ValueError."""


class AccuracyWarning(UserWarning):
    """A run that is stable but resolves its fastest motion poorly: h * w beyond the method's accuracy threshold
    (rbody.engine.accuracy), where one period of the fastest linear mode is carried with more than 1 % error.
    The message gives h * w, the threshold and the step that meets it. Silence it with the warnings module, or ask
    for an error estimate beside the run (simulate(..., error_estimate=True))."""
