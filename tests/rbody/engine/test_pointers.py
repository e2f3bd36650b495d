"""Every right-hand side a native model carries has its C wrapper registered (rbody.engine.pointers), so that a
process loads it from numba's disk cache instead of compiling it (a scene with contacts or force elements paid
about 12 s on its first simulate() in every process before its own was registered)."""

import pytest

from rbody.engine import integrators, pointers
from rbody.engine.constraints.dynamics import constrained_rhs
from rbody.engine.multibody import tree_rhs
from rbody.engine.planar import planar_rhs
from rbody.engine.system import system_rhs


@pytest.mark.parametrize("rhs", [tree_rhs, planar_rhs, system_rhs, constrained_rhs],
                         ids=["tree", "planar", "system", "constrained"])
def test_a_model_s_rhs_has_a_cached_wrapper(rhs):
    made = pointers.wrapper(rhs, "rhs")
    assert made is not None
    assert made._cache.__class__.__name__ != "NullCache"  # cfunc(cache=True): kept in numba's disk cache
    assert integrators.pointer_function(rhs) == made.address
