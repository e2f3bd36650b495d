"""rbody's native engine: minimal coordinates, compiled loops, exact events.

Layers, each importing only those below it: native (the NativeModel record) -> spatial, memory ->
multibody, planar (the tree's algorithms) -> integrators -> methods (one record per method) -> stability,
runner -> distributed. The scene layer (rbody.scene) builds NativeModels; simulate (rbody.simulation) runs them.
"""

from rbody.engine.methods import METHODS, METHOD_ORDER

__all__ = ["METHODS", "METHOD_ORDER"]
