"""The classes of the constraint table's unit kinds (rbody.engine.constraints.table's codes), compiled for the
kernels that walk the units: a unit whose rows are held at g = 0 always, a coordinate's limit or dry friction, one
unilateral row, one row on one dof, rows along a tendon. table.py holds no compiled code (it builds the table's
records in Python); these sit beside its codes for the kernels of jacobians.py, dynamics.py and stepping.py, which
import one another in that order."""

from __future__ import annotations

from numba import njit

from rbody.engine.constraints.table import (CONE, CONNECT, COUPLING, FRICTION, LOWER, TENDON_EQUALITY,
                                            TENDON_FRICTION, TENDON_LOWER, TENDON_UPPER, UPPER, WELD)


@njit(cache=True, inline="always")
def is_equality_kind(kind):
    """An equality unit: its rows held at g = 0 always (bilateral, unbounded impulses)."""
    return kind == CONNECT or kind == WELD or kind == COUPLING or kind == TENDON_EQUALITY


@njit(cache=True, inline="always")
def is_limit_kind(kind):
    """A joint's or a tendon's limit: one unilateral row on a coordinate (a dof's or a tendon's length)."""
    return kind == LOWER or kind == UPPER or kind == TENDON_LOWER or kind == TENDON_UPPER


@njit(cache=True, inline="always")
def is_friction_kind(kind):
    """A joint's or a tendon's dry friction: one row on a coordinate, its impulse within +-frictionloss h."""
    return kind == FRICTION or kind == TENDON_FRICTION


@njit(cache=True, inline="always")
def is_stop_kind(kind):
    """A unit of one unilateral row (g >= 0, impulse >= 0): a joint's or a tendon's limit, a ball's cone."""
    return is_limit_kind(kind) or kind == CONE


@njit(cache=True, inline="always")
def is_dof_kind(kind):
    """A unit of one row on one dof: a joint's stop (LOWER, UPPER) or dry friction (FRICTION)."""
    return kind == LOWER or kind == UPPER or kind == FRICTION


@njit(cache=True, inline="always")
def is_tendon_kind(kind):
    """A unit whose rows act along a tendon: its limits, its dry friction, a tendon equality."""
    return kind == TENDON_LOWER or kind == TENDON_UPPER or kind == TENDON_FRICTION or kind == TENDON_EQUALITY


__all__ = ["is_equality_kind", "is_limit_kind", "is_friction_kind", "is_stop_kind", "is_dof_kind",
           "is_tendon_kind"]
