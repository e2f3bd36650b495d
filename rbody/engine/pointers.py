"""The engine's own kernels as C function pointers compiled once and kept in numba's disk cache.

The integrator loops call a model's functions through C function pointers (rbody.engine.integrators.
pointer_function), each a numba cfunc wrapped around the jitted function. A wrapper made in the loop module
closes over the function it calls, which numba cannot cache: every process compiled it again (about 0.15 s each,
most of a warm start's cost). A module that defines a kernel registers here a maker for its wrapper, written in
that module (so that numba's cache entry is renewed when the kernel's source changes) around the kernel as a
global: pointer_function then takes the cached wrapper.

    register(function, kind, maker)   maker() -> a numba cfunc of the signature of `kind` (below)
    wrapper(function, kind)           the registered maker's cfunc, made once per process, or None

Kinds and their C signatures (y, p, out or h: float64 pointers; n = len(y), m = len(p)):
    "rhs"     f(y, p, out, n, m)       also accel
    "lanes"   f(y, p, out, n, m)       over WIDTH states side by side: y and out hold n WIDTH numbers
    "finish"  f(y, p, n, m)
"""

from __future__ import annotations

from typing import Any, Callable

from numba import types

_F64P = types.CPointer(types.float64)
RHS_SIGNATURE = types.void(_F64P, _F64P, _F64P, types.intp, types.intp)
FINISH_SIGNATURE = types.void(_F64P, _F64P, types.intp, types.intp)
SIGNATURES = {"rhs": RHS_SIGNATURE, "lanes": RHS_SIGNATURE, "finish": FINISH_SIGNATURE}

_MAKERS: dict[tuple[int, str], tuple[Any, Callable[[], Any]]] = {}
_MADE: dict[tuple[int, str], Any] = {}


def register(function: Any, kind: str, maker: Callable[[], Any]) -> None:
    """Register maker() -> the cached cfunc wrapping `function` for pointers of `kind` ("rhs", "lanes", "finish")."""
    if kind not in SIGNATURES:
        raise ValueError(f"kind={kind!r}: expected one of {tuple(SIGNATURES)}")
    _MAKERS[(id(function), kind)] = (function, maker)  # holding the function keeps its id unique


def wrapper(function: Any, kind: str) -> Any:
    """The registered cfunc wrapping `function` for `kind`, compiled or loaded from the cache on first use; None when
    no maker is registered."""
    key = (id(function), kind)
    if key not in _MADE:
        if key not in _MAKERS:
            return None
        _MADE[key] = _MAKERS[key][1]()
    return _MADE[key]
