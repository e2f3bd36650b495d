"""benchmarks/contact_step.py: the contact step's cost and its heap allocations, measured on the sweep's scenes.

The step cuts its arrays (W, M^-1/2 J^T, the impulses and their bounds among them) from memory the loop allocates
once (stepping.step_arena), and its helpers keep their scratch on the stack: a step of the sphere rolling on its
plane allocated 64 arrays before (numba's runtime counters, the benchmark's run of 2026-12-01 over 2,000 steps), 7
since (LAPACK's factor of M and the cone solver's copies of its impulses; more in its first 19 steps, while it
slides), 6 since M is factored along the tree in the step's arena; a step of the stack of five boxes 123, 6 and 5
(the box pairs' edge search allocated nine arrays a pair)."""

import importlib.util
import math
import sys
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[2]
sys.path.insert(0, str(ROOT / "benchmarks"))
sys.path.append(str(ROOT / "tests" / "rbody" / "engine"))
spec = importlib.util.spec_from_file_location("contact_step", ROOT / "benchmarks" / "contact_step.py")
contact_step = importlib.util.module_from_spec(spec)
spec.loader.exec_module(contact_step)


@pytest.mark.parametrize("scene", ["sphere", "stack"])
def test_a_contact_step_allocates_a_few_arrays_whatever_its_rows(scene):
    """300 steps (the sphere rolls from its 20th), twice: finite positive times, and fewer than 12 allocations a
    step (9.5 and 6.6, the runs' own arrays and the sphere's sliding steps included; 64 and 123 before the arena):
    the stack's 228 rows cost no more allocations than the sphere's 3."""
    result = contact_step.rbody_costs(300, 2, scenes=(scene,))[scene]
    assert len(result["seconds"]) == 2
    assert all(math.isfinite(s) and s > 0.0 for s in result["seconds"])
    assert result["allocations"] < 12.0


def test_bad_counts_are_refused():
    with pytest.raises(ValueError, match="repeats=0"):
        contact_step.main(["--repeats", "0"])
    with pytest.raises(ValueError, match="not a checkout of rbody"):
        contact_step.main(["--other", str(ROOT / "docs")])
