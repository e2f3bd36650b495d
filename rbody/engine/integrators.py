"""The integration methods, as compiled loops over a batch of states.

Every loop has the same shape: for each batch element b (chunks of the batch in parallel), copy
y0[b], take `nsteps` steps of size dt, store every `save_every`-th state into out[s, b], and record
the first step whose state is not finite (-1 when none; gauss6 also fails a step whose stage
equations do not converge), freezing that element there. The scene supplies

    rhs(y, p, out)    y' = f(y)            (every general method)
    accel(q, p, out)  q'' = a(q), y = (q, q')  (the symplectic methods: the Hamiltonian is separable)

Methods (order in brackets; each method's facts are one record in rbody.engine.methods):
    euler [1]             y += dt f(y)
    symplectic_euler [1]  v += dt a(q); q += dt v
    verlet [2]            velocity Verlet (kick-drift-kick), symmetric and symplectic
    rk4 [4]               classical Runge-Kutta
    yoshida6 [6]          Yoshida's 7-stage symmetric composition of verlet (solution A)
    gauss6 [6]            3-stage Gauss-Legendre collocation, implicit, symmetric and symplectic for
                          any Hamiltonian; solved by fixed-point iteration to round-off
    splitting [2]         the scene's own symmetric splitting into exact flows (free rotation)
    reference             scipy DOP853 at rtol 1e-13: for checks only, never for speed

The compiled loops take the scene's functions as C function pointers (a numba cfunc around each,
made once per process): a loop typed by a plain signature is compiled once and then loaded from
numba's on-disk cache in every later process, whereas a loop specialised on each jitted function
(a numba Dispatcher argument) is compiled again in every process, seconds per method and scene.
The indirect call costs nothing measurable (25 ns per verlet step of the pendulum either way).
"""

from __future__ import annotations

from types import FunctionType
from typing import Any

import numpy as np
from numba import carray, cfunc, get_num_threads, njit, prange, types
from numba.core import cgutils
from numba.extending import intrinsic

from rbody.engine import pointers
from rbody.engine.memory import address
from rbody.engine.simd import WIDTH as LANES


# Yoshida (1990), 6th order, solution A: weights w3 w2 w1 w0 w1 w2 w3 of the symmetric base step.
_W1, _W2, _W3 = -1.17767998417887, 0.235573213359357, 0.784513610477560
YOSHIDA6 = np.array([_W3, _W2, _W1, 1.0 - 2.0 * (_W1 + _W2 + _W3), _W1, _W2, _W3])

# Gauss-Legendre, 3 stages (Butcher tableau).
_S15 = np.sqrt(15.0)
GAUSS6_A = np.array([
    [5 / 36, 2 / 9 - _S15 / 15, 5 / 36 - _S15 / 30],
    [5 / 36 + _S15 / 24, 2 / 9, 5 / 36 - _S15 / 24],
    [5 / 36 + _S15 / 30, 2 / 9 + _S15 / 15, 5 / 36],
])
GAUSS6_B = np.array([5 / 18, 4 / 9, 5 / 18])
GAUSS6_MAX_ITERATIONS = 60
GAUSS6_TOLERANCE = 2e-16  # relative size of the last correction of the stage slopes
# A correction that no longer shrinks (rate >= 0.9) and is below this (relative) is the round-off of f
# itself, which for an ill-conditioned f (the solve with a long chain's mass matrix) lies far above
# 1e-16; a real contraction that slow could not have come down this far within the iterations allowed.
GAUSS6_NOISE = 1e-8


# ----- the scene's functions as C function pointers ---------------------------------------------

_F64P = types.CPointer(types.float64)
# f(y, p, out) and a(q, p, out): (y, p, out, len(y), len(p)); a scene's own step(y, p, h): (y, p, h, len(y), len(p))
RHS_SIGNATURE = types.void(_F64P, _F64P, _F64P, types.intp, types.intp)
STEP_SIGNATURE = types.void(_F64P, _F64P, types.float64, types.intp, types.intp)
# finish(y, p) after every whole step (a tree's rotation vectors folded into its quaternions): (y, p, len(y), len(p))
FINISH_SIGNATURE = types.void(_F64P, _F64P, types.intp, types.intp)
_POINTER_FUNCTIONS: dict[tuple[int, str], tuple[Any, Any]] = {}


def _function_at(function_type):
    """An intrinsic turning an address (int) into a callable of `function_type`: the loops take the scene's C
    function pointers as plain integers, because a C callback object passed as an argument is unboxed by numba at
    every call (~2.5 us each, most of the fixed cost of a one-step run) where an integer costs nothing."""
    @intrinsic
    def function_at(typingctx, address):
        if not isinstance(address, types.Integer):
            return None

        def codegen(context, builder, signature, args):
            function = cgutils.create_struct_proxy(function_type)(context, builder)
            void_pointer = context.get_value_type(types.voidptr)
            function.c_addr = builder.inttoptr(args[0], void_pointer)
            function.py_addr = context.get_constant_null(types.voidptr)
            function.jit_addr = context.get_constant_null(types.voidptr)
            return function._getvalue()
        return function_type(address), codegen
    return function_at


_rhs_at = _function_at(types.FunctionType(RHS_SIGNATURE))
_step_at = _function_at(types.FunctionType(STEP_SIGNATURE))
_finish_at = _function_at(types.FunctionType(FINISH_SIGNATURE))


def pointer_function(function, kind: str = "rhs") -> int:
    """The address of the scene's jitted function(y, p, out) ("rhs", also accel; "lanes": the same over LANES states
    side by side, y and out of LANES len(y) numbers) or step(y, p, h) ("step") behind a C function pointer taking
    (address, address, address or h, len(y), len(p)); made once per function and kept alive here, so that the address
    stays valid."""
    key = (id(function), kind)
    if key not in _POINTER_FUNCTIONS:
        cached = pointers.wrapper(function, kind)  # the engine's kernels: a wrapper kept in numba's disk cache
        if cached is not None:
            _POINTER_FUNCTIONS[key] = (function, cached)
            return cached.address
        if kind == "rhs":
            @cfunc(RHS_SIGNATURE)
            def wrapper(y, p, out, n, m):
                function(carray(y, n), carray(p, m), carray(out, n))
        elif kind == "step":
            @cfunc(STEP_SIGNATURE)
            def wrapper(y, p, h, n, m):
                function(carray(y, n), carray(p, m), h)
        elif kind == "finish":
            @cfunc(FINISH_SIGNATURE)
            def wrapper(y, p, n, m):
                function(carray(y, n), carray(p, m))
        elif kind == "lanes":  # f over LANES states side by side: y, out (n LANES,) structures of arrays
            @cfunc(RHS_SIGNATURE)
            def wrapper(y, p, out, n, m):
                function(carray(y, n * LANES), carray(p, m), carray(out, n * LANES))
        else:
            raise ValueError(f"kind={kind!r}: expected 'rhs', 'step', 'finish' or 'lanes'")
        _POINTER_FUNCTIONS[key] = (function, wrapper)  # holding the function keeps its id unique
    return _POINTER_FUNCTIONS[key][1].address


@njit(cache=True)
def no_finish(y, p):
    """The finish hook of every scene that has none: nothing (the loops do not even call it)."""


def _no_finish_pointer():
    @cfunc(FINISH_SIGNATURE, cache=True)
    def no_finish_c(y, p, n, m):
        no_finish(carray(y, n), carray(p, m))
    return no_finish_c


pointers.register(no_finish, "finish", _no_finish_pointer)


def finish_pointer(finish):
    """(pointer, flag) the loops take: the scene's finish(y, p) behind a C pointer and True, or a no-op and
    False (the flag skips the call: scenes without a finish pay one predictable branch per step)."""
    return (pointer_function(no_finish, "finish"), False) if finish is None else (pointer_function(finish, "finish"), True)


@intrinsic
def _row(typingctx, array, index):
    """float64* to row `index` of a C-contiguous float64 array (data + index * strides[0]), without
    making a view of the row; passing the array keeps it alive across the call."""
    if not (isinstance(array, types.Array) and array.dtype == types.float64 and array.layout == "C"
            and isinstance(index, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0])
        stride = builder.extract_value(data.strides, 0)
        offset = builder.mul(context.cast(builder, args[1], signature.args[1], types.intp), stride)
        address = builder.add(builder.ptrtoint(data.data, context.get_value_type(types.intp)), offset)
        return builder.inttoptr(address, context.get_value_type(_F64P))
    return _F64P(array, index), codegen


@njit(cache=True, inline="always")
def _save(out, sample, row, y, b):
    """out[sample, row] = y[b], element by element: an array assignment would compile numba's broadcast checks and
    their error messages into every loop (over a second of a first run's compilation per loop)."""
    for j in range(y.shape[1]):
        out[sample, row, j] = y[b, j]


@njit(cache=True, inline="always")
def _finite_row(y, b):
    for j in range(y.shape[1]):
        if not np.isfinite(y[b, j]):
            return False
    return True


@njit(cache=True, inline="always")
def _unfailed(batch):
    """(batch,) int64 of -1 (no element failed yet): np.empty and a loop, whose compilation is a fraction of np.full's."""
    failed = np.empty(batch, dtype=np.int64)
    for b in range(batch):
        failed[b] = -1
    return failed


@njit(cache=True, inline="always")
def _rows_of(y0, lo, width):
    """A copy of y0[lo:lo + width] (element by element: no slicing and copying machinery to compile)."""
    y = np.empty((width, y0.shape[1]))
    for b in range(width):
        for j in range(y0.shape[1]):
            y[b, j] = y0[lo + b, j]
    return y


# ----- the compiled loops ------------------------------------------------------------------------------
# The batch is cut into chunks, one thread each (prange). A thread steps its chunk together: stage by
# stage, element by element, so that the evaluations of neighbouring elements, independent of each
# other, overlap in the processor (a single element's steps form one dependent chain, mostly waiting
# on sin and cos). Each element does exactly the arithmetic it would do alone: a batch gives the
# same bits as single runs. An element that fails is frozen and the others go on.

CHUNK = 32  # elements per chunk at most (their states stay in the first-level cache)
# A batch that forms one chunk (a single scene) runs the loop's serial twin (_serial_twin): no thread launch.


def chunk_size(batch: int) -> int:
    """Elements per chunk: at most CHUNK, and at least one chunk per thread."""
    return max(1, min(CHUNK, -(-batch // get_num_threads())))


@njit(cache=True, parallel=True)
def _euler_loop(rhs_address, finish_address, finishing, y0, params, dt, nsteps, save_every, out, size):
    rhs, finish = _rhs_at(rhs_address), _finish_at(finish_address)
    batch, n = y0.shape
    m = params.shape[1]
    failed = np.full(batch, -1, dtype=np.int64)
    for c in prange(-(-batch // size)):
        lo = c * size
        width = min(batch, lo + size) - lo
        y = y0[lo:lo + width].copy()
        k = np.empty((width, n))
        running = width
        for b in range(width):
            _save(out, 0, lo + b, y, b)
        for i in range(1, nsteps + 1):
            for b in range(width):
                if failed[lo + b] >= 0:
                    continue
                rhs(_row(y, b), _row(params, lo + b), _row(k, b), n, m)
                for j in range(n):
                    y[b, j] += dt * k[b, j]
                if finishing:
                    finish(_row(y, b), _row(params, lo + b), n, m)
                if not _finite_row(y, b):
                    failed[lo + b] = i
                    running -= 1
            if running == 0:
                break
            if i % save_every == 0:
                for b in range(width):
                    _save(out, i // save_every, lo + b, y, b)
    return failed


@njit(cache=True, parallel=True)
def _rk4_loop(rhs_address, finish_address, finishing, y0, params, dt, nsteps, save_every, out, size):
    rhs, finish = _rhs_at(rhs_address), _finish_at(finish_address)
    batch, n = y0.shape
    m = params.shape[1]
    failed = _unfailed(batch)
    for c in prange(-(-batch // size)):
        lo = c * size
        width = min(batch, lo + size) - lo
        y = _rows_of(y0, lo, width)
        k1, k2, k3, k4 = np.empty((width, n)), np.empty((width, n)), np.empty((width, n)), np.empty((width, n))
        tmp = np.empty((width, n))
        running = width
        for b in range(width):
            _save(out, 0, lo + b, y, b)
        for i in range(1, nsteps + 1):
            for b in range(width):
                if failed[lo + b] < 0:
                    rhs(_row(y, b), _row(params, lo + b), _row(k1, b), n, m)
            for b in range(width):
                if failed[lo + b] < 0:
                    for j in range(n):
                        tmp[b, j] = y[b, j] + 0.5 * dt * k1[b, j]
                    rhs(_row(tmp, b), _row(params, lo + b), _row(k2, b), n, m)
            for b in range(width):
                if failed[lo + b] < 0:
                    for j in range(n):
                        tmp[b, j] = y[b, j] + 0.5 * dt * k2[b, j]
                    rhs(_row(tmp, b), _row(params, lo + b), _row(k3, b), n, m)
            for b in range(width):
                if failed[lo + b] < 0:
                    for j in range(n):
                        tmp[b, j] = y[b, j] + dt * k3[b, j]
                    rhs(_row(tmp, b), _row(params, lo + b), _row(k4, b), n, m)
            for b in range(width):
                if failed[lo + b] < 0:
                    for j in range(n):
                        y[b, j] += dt / 6.0 * (k1[b, j] + 2.0 * k2[b, j] + 2.0 * k3[b, j] + k4[b, j])
                    if finishing:
                        finish(_row(y, b), _row(params, lo + b), n, m)
                    if not _finite_row(y, b):
                        failed[lo + b] = i
                        running -= 1
            if running == 0:
                break
            if i % save_every == 0:
                for b in range(width):
                    _save(out, i // save_every, lo + b, y, b)
    return failed


@njit(cache=True, parallel=True)
def _rk4_lanes_loop(rhs_address, y0, params, dt, nsteps, save_every, out, size):
    """rk4 as _rk4_loop, LANES elements at a time through the model's rhs over lanes (NativeModel.rhs_lanes), every
    element with the one parameter row params[0]; a chunk (size, a multiple of LANES) holds its states as a structure
    of arrays (entry j of lane l of group g at (g n + j) LANES + l), a last partial group repeating its last element.
    Each element does the arithmetic it does in _rk4_loop, so its bits are the same; an element that fails keeps its
    first non-finite state, as there (its lanes go on computing, unseen)."""
    rhs = _rhs_at(rhs_address)
    batch, n = y0.shape
    m = params.shape[1]
    failed = np.full(batch, -1, dtype=np.int64)
    for c in prange(-(-batch // size)):
        lo = c * size
        width = min(batch, lo + size) - lo
        groups = -(-width // LANES)
        block = n * LANES
        y = np.empty(groups * block)
        k1, k2, k3, k4, tmp = (np.empty(groups * block), np.empty(groups * block), np.empty(groups * block),
                               np.empty(groups * block), np.empty(groups * block))
        frozen = np.empty((width, n))
        for g in range(groups):
            for l in range(LANES):
                b = lo + min(g * LANES + l, width - 1)
                for j in range(n):
                    y[(g * n + j) * LANES + l] = y0[b, j]
        for b in range(width):
            _save(out, 0, lo + b, y0, lo + b)
        running = width
        for i in range(1, nsteps + 1):
            for g in range(groups):
                rhs(address(y, g * block), _row(params, 0), address(k1, g * block), n, m)
            for g in range(groups):
                for e in range(g * block, (g + 1) * block):
                    tmp[e] = y[e] + 0.5 * dt * k1[e]
                rhs(address(tmp, g * block), _row(params, 0), address(k2, g * block), n, m)
            for g in range(groups):
                for e in range(g * block, (g + 1) * block):
                    tmp[e] = y[e] + 0.5 * dt * k2[e]
                rhs(address(tmp, g * block), _row(params, 0), address(k3, g * block), n, m)
            for g in range(groups):
                for e in range(g * block, (g + 1) * block):
                    tmp[e] = y[e] + dt * k3[e]
                rhs(address(tmp, g * block), _row(params, 0), address(k4, g * block), n, m)
            for g in range(groups):
                for e in range(g * block, (g + 1) * block):
                    y[e] += dt / 6.0 * (k1[e] + 2.0 * k2[e] + 2.0 * k3[e] + k4[e])
            for b in range(width):
                if failed[lo + b] >= 0:
                    continue
                g, l = b // LANES, b % LANES
                finite = True
                for j in range(n):
                    if not np.isfinite(y[(g * n + j) * LANES + l]):
                        finite = False
                if not finite:
                    failed[lo + b] = i
                    running -= 1
                    for j in range(n):
                        frozen[b, j] = y[(g * n + j) * LANES + l]
            if running == 0:
                break
            if i % save_every == 0:
                for b in range(width):
                    g, l = b // LANES, b % LANES
                    for j in range(n):
                        out[i // save_every, lo + b, j] = frozen[b, j] if failed[lo + b] >= 0 else y[
                            (g * n + j) * LANES + l]
    return failed


@njit(cache=True, parallel=True)
def _symplectic_euler_loop(accel_address, y0, params, dt, nsteps, save_every, out, size):
    accel = _rhs_at(accel_address)
    batch, n = y0.shape
    half = n // 2
    m = params.shape[1]
    failed = np.full(batch, -1, dtype=np.int64)
    for c in prange(-(-batch // size)):
        lo = c * size
        width = min(batch, lo + size) - lo
        y = y0[lo:lo + width].copy()
        a = np.empty((width, half))
        running = width
        for b in range(width):
            _save(out, 0, lo + b, y, b)
        for i in range(1, nsteps + 1):
            for b in range(width):
                if failed[lo + b] >= 0:
                    continue
                accel(_row(y, b), _row(params, lo + b), _row(a, b), half, m)  # reads q = y[:half]
                for j in range(half):
                    y[b, half + j] += dt * a[b, j]
                    y[b, j] += dt * y[b, half + j]
                if not _finite_row(y, b):
                    failed[lo + b] = i
                    running -= 1
            if running == 0:
                break
            if i % save_every == 0:
                for b in range(width):
                    _save(out, i // save_every, lo + b, y, b)
    return failed


@njit(cache=True, parallel=True)
def _composed_verlet_loop(accel_address, weights, y0, params, dt, nsteps, save_every, out, size):
    accel = _rhs_at(accel_address)
    batch, n = y0.shape
    half = n // 2
    m = params.shape[1]
    failed = np.full(batch, -1, dtype=np.int64)
    for c in prange(-(-batch // size)):
        lo = c * size
        width = min(batch, lo + size) - lo
        y = y0[lo:lo + width].copy()
        a = np.empty((width, half))
        running = width
        for b in range(width):
            accel(_row(y, b), _row(params, lo + b), _row(a, b), half, m)  # reads q = y[:half]
            _save(out, 0, lo + b, y, b)
        for i in range(1, nsteps + 1):
            for w in weights:
                h = w * dt
                for b in range(width):
                    if failed[lo + b] >= 0:
                        continue
                    for j in range(half):
                        y[b, half + j] += 0.5 * h * a[b, j]
                        y[b, j] += h * y[b, half + j]
                    accel(_row(y, b), _row(params, lo + b), _row(a, b), half, m)
                    for j in range(half):
                        y[b, half + j] += 0.5 * h * a[b, j]
            for b in range(width):
                if failed[lo + b] < 0 and not _finite_row(y, b):
                    failed[lo + b] = i
                    running -= 1
            if running == 0:
                break
            if i % save_every == 0:
                for b in range(width):
                    _save(out, i // save_every, lo + b, y, b)
    return failed


@njit(cache=True, parallel=True)
def _gauss_loop(rhs_address, finish_address, finishing, A, weights, second, later, y0, params, dt, nsteps, save_every, out, size):
    rhs, finish = _rhs_at(rhs_address), _finish_at(finish_address)
    """second, later (s, 2s): the starting guess of step 2, and of every later step i, from the slopes of
    steps i-2 and i-1 (see run_gauss6)."""
    batch, n = y0.shape
    m = params.shape[1]
    stages = weights.size
    failed = np.full(batch, -1, dtype=np.int64)
    for c in prange(-(-batch // size)):
        lo = c * size
        width = min(batch, lo + size) - lo
        y = y0[lo:lo + width].copy()
        K = np.empty((width, stages, n))
        K_new = np.empty((width, stages, n))
        K_rows = K_new.reshape((width * stages, n))  # row b * stages + s is K_new[b, s]
        K_old = np.zeros((width, stages, n))  # the slopes of the step before the last
        tmp = np.empty((width, n))
        previous = np.empty(width)  # last correction of each element's iteration
        state = np.empty(width, dtype=np.int64)  # 0 iterating, 1 converged, 2 failed to converge
        running = width
        for b in range(width):
            _save(out, 0, lo + b, y, b)
            rhs(_row(y, b), _row(params, lo + b), _row(tmp, b), n, m)
            for s in range(stages):
                K[b, s] = tmp[b]
        for i in range(1, nsteps + 1):
            for b in range(width):
                state[b] = 0 if failed[lo + b] < 0 else 1
                previous[b] = np.inf
                if i > 1 and failed[lo + b] < 0:  # the last two steps' slopes -> this step's starting guess
                    extrapolation = second if i == 2 else later
                    for s in range(stages):
                        for j in range(n):
                            acc = 0.0
                            for r in range(stages):
                                acc += (extrapolation[s, r] * K_old[b, r, j]
                                        + extrapolation[s, stages + r] * K_new[b, r, j])
                            K[b, s, j] = acc
                    K_old[b] = K_new[b]
            for iteration in range(GAUSS6_MAX_ITERATIONS):
                iterating = 0
                for b in range(width):
                    if state[b] != 0:
                        continue
                    iterating += 1
                    for s in range(stages):
                        for j in range(n):
                            acc = 0.0
                            for r in range(stages):
                                acc += A[s, r] * K[b, r, j]
                            tmp[b, j] = y[b, j] + dt * acc
                        rhs(_row(tmp, b), _row(params, lo + b), _row(K_rows, b * stages + s), n, m)
                    change = 0.0
                    scale = 0.0
                    for s in range(stages):
                        for j in range(n):
                            change = max(change, abs(K_new[b, s, j] - K[b, s, j]))
                            scale = max(scale, abs(K_new[b, s, j]))
                            K[b, s, j] = K_new[b, s, j]
                    tolerance = GAUSS6_TOLERANCE * scale
                    rate = change / previous[b]
                    # done when this correction, or the next (this one times the contraction rate), is round-off
                    if change <= tolerance or (
                            iteration > 0 and rate < 1.0 and rate * change <= tolerance * (1.0 - rate)):
                        state[b] = 1
                    elif iteration > 0 and rate >= 0.9 and change <= GAUSS6_NOISE * scale:
                        state[b] = 1  # no longer contracting: the corrections are the round-off of f itself
                    elif not change < np.inf:
                        state[b] = 2  # NaN or inf: no point iterating
                    previous[b] = change
                if iterating == 0:
                    break
            for b in range(width):
                if failed[lo + b] >= 0:
                    continue
                for j in range(n):
                    acc = 0.0
                    for s in range(stages):
                        acc += weights[s] * K[b, s, j]
                    y[b, j] += dt * acc
                if finishing:
                    finish(_row(y, b), _row(params, lo + b), n, m)
                if state[b] != 1 or not _finite_row(y, b):
                    failed[lo + b] = i
                    running -= 1
            if running == 0:
                break
            if i % save_every == 0:
                for b in range(width):
                    _save(out, i // save_every, lo + b, y, b)
    return failed


@njit(cache=True, parallel=True)
def _composed_flow_loop(step_address, weights, y0, params, dt, nsteps, save_every, out, size):
    step = _step_at(step_address)
    batch, n = y0.shape
    m = params.shape[1]
    failed = np.full(batch, -1, dtype=np.int64)
    for c in prange(-(-batch // size)):
        lo = c * size
        width = min(batch, lo + size) - lo
        y = y0[lo:lo + width].copy()
        running = width
        for b in range(width):
            _save(out, 0, lo + b, y, b)
        for i in range(1, nsteps + 1):
            for w in weights:
                for b in range(width):
                    if failed[lo + b] < 0:
                        step(_row(y, b), _row(params, lo + b), w * dt, n, m)
            for b in range(width):
                if failed[lo + b] < 0 and not _finite_row(y, b):
                    failed[lo + b] = i
                    running -= 1
            if running == 0:
                break
            if i % save_every == 0:
                for b in range(width):
                    _save(out, i // save_every, lo + b, y, b)
    return failed


def _serial_twin(loop):
    """The same loop compiled without parallel=True (prange runs as range): a batch that forms a single chunk
    then runs on the calling thread, without waking and waiting for every numba thread (measured: 4 ms per
    call on a loaded machine against 0.2 ms). Same arithmetic, same bits. The twin gets its own __qualname__
    so that numba's on-disk cache, keyed by qualified name, line and bytecode, keeps it apart from the
    parallel loop (the same name would make the two overwrite each other's cache entry)."""
    f = loop.py_func
    twin = FunctionType(f.__code__, f.__globals__, f.__name__ + "_serial", f.__defaults__, f.__closure__)
    twin.__qualname__ = f.__qualname__ + "_serial"
    twin.__doc__ = f.__doc__
    return njit(cache=True)(twin)


_SERIAL = {loop: _serial_twin(loop) for loop in (_euler_loop, _rk4_loop, _rk4_lanes_loop, _symplectic_euler_loop,
                                                 _composed_verlet_loop, _gauss_loop, _composed_flow_loop)}


def _pick(loop, batch: int, size: int):
    """The parallel loop, or its serial twin when the batch forms one chunk."""
    return _SERIAL[loop] if batch <= size else loop


# The compiled entry point of each loop's overload, by the kinds of its arguments: numba's dispatcher types
# every argument on every call (~40 us per call, most of it the C function pointers), which is most of the
# fixed cost of a short simulate call; a call whose arguments are of kinds already typed skips it.
_ENTRY_POINTS: dict[tuple, Any] = {}


def _argument_kind(value) -> Any:
    """What numba's type of `value` depends on: an array's dtype, rank, layout and flags; a number's Python
    type; any other object (a C function pointer, made once per function and kept) itself, by id."""
    if isinstance(value, np.ndarray):
        flags = value.flags
        return (value.dtype.str, value.ndim, flags.c_contiguous, flags.f_contiguous, flags.writeable, flags.aligned)
    if isinstance(value, (bool, int, float, np.generic)):
        return type(value)
    return id(value)


def _launch(loop, *args):
    """loop(*args), through the kept entry point of the overload that typed arguments of the same kinds before."""
    key = (loop,) + tuple(_argument_kind(a) for a in args)
    entry = _ENTRY_POINTS.get(key)
    if entry is not None:
        return entry(*args)
    result = loop(*args)  # compiles or loads the loop, and types these arguments
    overload = loop.overloads.get(tuple(loop.typeof_pyval(a) for a in args))
    if overload is not None:
        _ENTRY_POINTS[key] = overload.entry_point
    return result


def _c(array: np.ndarray) -> np.ndarray:
    """C-contiguous float64 (the loops hand pointers to rows of y0 and params to the scene)."""
    return np.ascontiguousarray(array, dtype=np.float64)


# ----- the methods, as called by simulate -------------------------------------------------------------
# Each: the scene's jitted function(s), y0 (B, n), params (B, p), dt [s], nsteps, save_every,
# out (nsteps // save_every + 1, B, n) filled in place; returns failed (B,) int64: first failed step or -1.
# The compiled loops take the same, the functions as pointers, and last the chunk size.


class Bound:
    """loop(*head, y0, params, dt, nsteps, save_every, out, size) with all but (y0, params, out) fixed.

    launch(y0, params, out) types the arguments every time (_launch: any arrays); call(y0, params, out) keeps the
    compiled entry point of its first call and calls it directly after that, for a caller that always passes
    arrays of the kinds of its first call (C-contiguous, writable float64: a prepared run's own copies, and a new
    out), so that a short run costs what its loop costs."""

    __slots__ = ("loop", "head", "dt", "nsteps", "save_every", "size", "entry")

    def __init__(self, loop, head: tuple, dt: float, nsteps: int, save_every: int, batch: int) -> None:
        self.size = chunk_size(batch)
        self.loop = _pick(loop, batch, self.size)
        self.head, self.dt, self.nsteps, self.save_every = head, float(dt), int(nsteps), int(save_every)
        self.entry = None

    def launch(self, y0: np.ndarray, params: np.ndarray, out: np.ndarray) -> np.ndarray:
        return _launch(self.loop, *self.head, y0, params, self.dt, self.nsteps, self.save_every, out, self.size)

    def __call__(self, y0: np.ndarray, params: np.ndarray, out: np.ndarray) -> np.ndarray:
        if self.entry is not None:
            return self.entry(*self.head, y0, params, self.dt, self.nsteps, self.save_every, out, self.size)
        failed = self.launch(y0, params, out)
        args = self.head + (y0, params, self.dt, self.nsteps, self.save_every, out, self.size)
        self.entry = _ENTRY_POINTS.get((self.loop,) + tuple(_argument_kind(a) for a in args))
        return failed


def bind_euler(rhs, batch, dt, nsteps, save_every, finish=None) -> Bound:
    """y += dt f(y); then finish(y, p) when the scene has one (every method below: after each whole step)."""
    return Bound(_euler_loop, (pointer_function(rhs), *finish_pointer(finish)), dt, nsteps, save_every, batch)


def bind_rk4(rhs, batch, dt, nsteps, save_every, finish=None, lanes=None) -> Bound:
    """Classical Runge-Kutta. lanes: the model's rhs over LANES states side by side (NativeModel.rhs_lanes), used
    for a batch of at least LANES elements with no finish hook whose parameter rows are all one (LanesBound)."""
    scalar = Bound(_rk4_loop, (pointer_function(rhs), *finish_pointer(finish)), dt, nsteps, save_every, batch)
    if lanes is None or finish is not None or batch < LANES:
        return scalar
    return LanesBound(_rk4_lanes_loop, (pointer_function(lanes, "lanes"),), dt, nsteps, save_every, batch, scalar)


class LanesBound(Bound):
    """A Bound running a loop over lanes (one parameter row for every element) where the batch's parameter rows are
    all equal, and the scalar loop (`scalar`, a Bound) otherwise; chunks of a multiple of LANES elements."""

    __slots__ = ("scalar",)

    def __init__(self, loop, head: tuple, dt: float, nsteps: int, save_every: int, batch: int, scalar: Bound) -> None:
        super().__init__(loop, head, dt, nsteps, save_every, batch)
        self.size = LANES * max(1, min(CHUNK, -(-batch // (LANES * get_num_threads()))))
        self.loop = _pick(loop, batch, self.size)
        self.scalar = scalar

    def launch(self, y0: np.ndarray, params: np.ndarray, out: np.ndarray) -> np.ndarray:
        if not np.all(params == params[:1]):
            return self.scalar.launch(y0, params, out)
        return super().launch(y0, params, out)

    def __call__(self, y0: np.ndarray, params: np.ndarray, out: np.ndarray) -> np.ndarray:
        if not np.all(params == params[:1]):
            return self.scalar(y0, params, out)
        return super().__call__(y0, params, out)


def bind_symplectic_euler(accel, batch, dt, nsteps, save_every) -> Bound:
    """v += dt a(q); q += dt v."""
    return Bound(_symplectic_euler_loop, (pointer_function(accel),), dt, nsteps, save_every, batch)


def bind_composed_verlet(accel, weights, batch, dt, nsteps, save_every) -> Bound:
    """Velocity Verlet with step weights (weights = [1.0] is verlet itself; YOSHIDA6 its 6th-order
    composition). The acceleration at the end of one sub-step is reused at the start of the next."""
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    return Bound(_composed_verlet_loop, (pointer_function(accel), weights), dt, nsteps, save_every, batch)


def bind_gauss6(rhs, A, weights, batch, dt, nsteps, save_every, finish=None) -> Bound:
    """Gauss-Legendre collocation with tableau A (s, s) and weights (s,) (GAUSS6_A, GAUSS6_B).

    Stage slopes K_s = f(y + dt sum_r A_sr K_r) by fixed-point iteration, started from the last two
    steps' slopes extrapolated to this step's nodes; it stops once the next correction (the last one
    times the contraction rate) is below round-off. A step whose iteration does not converge (dt
    beyond the reach of fixed-point iteration, dt |df/dy| ~ 1) fails like a non-finite state."""
    A = np.ascontiguousarray(A, dtype=np.float64)
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    second, later = gauss_starting_guess(A)
    return Bound(_gauss_loop, (pointer_function(rhs), *finish_pointer(finish), A, weights, second, later), dt,
                 nsteps, save_every, batch)


def bind_composed_flow(step, weights, batch, dt, nsteps, save_every) -> Bound:
    """A scene's own symmetric one-step map step(y, p, h) composed with the given weights
    (weights = [1.0]: the map itself; YOSHIDA6: its 6th-order composition)."""
    weights = np.ascontiguousarray(weights, dtype=np.float64)
    return Bound(_composed_flow_loop, (pointer_function(step, "step"), weights), dt, nsteps, save_every, batch)


def run_euler(rhs, y0, params, dt, nsteps, save_every, out, finish=None):
    y0, params = _c(y0), _c(params)
    return bind_euler(rhs, y0.shape[0], dt, nsteps, save_every, finish).launch(y0, params, out)


def run_rk4(rhs, y0, params, dt, nsteps, save_every, out, finish=None, lanes=None):
    y0, params = _c(y0), _c(params)
    return bind_rk4(rhs, y0.shape[0], dt, nsteps, save_every, finish, lanes).launch(y0, params, out)


def run_symplectic_euler(accel, y0, params, dt, nsteps, save_every, out):
    y0, params = _c(y0), _c(params)
    return bind_symplectic_euler(accel, y0.shape[0], dt, nsteps, save_every).launch(y0, params, out)


def run_composed_verlet(accel, weights, y0, params, dt, nsteps, save_every, out):
    y0, params = _c(y0), _c(params)
    return bind_composed_verlet(accel, weights, y0.shape[0], dt, nsteps, save_every).launch(y0, params, out)


def run_gauss6(rhs, A, weights, y0, params, dt, nsteps, save_every, out, finish=None):
    y0, params = _c(y0), _c(params)
    return bind_gauss6(rhs, A, weights, y0.shape[0], dt, nsteps, save_every, finish).launch(y0, params, out)


def run_composed_flow(step, weights, y0, params, dt, nsteps, save_every, out):
    y0, params = _c(y0), _c(params)
    return bind_composed_flow(step, weights, y0.shape[0], dt, nsteps, save_every).launch(y0, params, out)


def gauss_starting_guess(A: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Weights (s, 2s) of the starting guess of step 2 and of every later step, from the stage slopes of
    the last two steps.

    The polynomial through the slopes of the last two steps (at nodes c_r - 2 and c_r - 1 of this
    step, c = A 1) extrapolated to this step's nodes c_s. Its error is O(dt^2s) (~1e-15 at w dt = 4e-3),
    so two iterations usually reach round-off where a guess from one step behind (error O(dt^s)) needs
    three and the constant f(y) (error O(dt)) five or six. Step 2 has only one step behind it: the
    first block of its weights is zero, the second that of one step.
    """
    nodes = np.asarray(A, dtype=np.float64).sum(axis=1)
    second = np.hstack([np.zeros((nodes.size, nodes.size)), _lagrange(nodes - 1, nodes)])
    later = _lagrange(np.concatenate([nodes - 2, nodes - 1]), nodes)
    return second, later


def _lagrange(nodes: np.ndarray, targets: np.ndarray) -> np.ndarray:
    """E (targets, nodes): the polynomial through values at `nodes` evaluated at `targets` is E @ values."""
    return np.array([[np.prod([(x - nodes[q]) / (nodes[r] - nodes[q]) for q in range(nodes.size) if q != r])
                      for r in range(nodes.size)] for x in targets])


def run_reference(rhs, y0: np.ndarray, params: np.ndarray, dt: float, nsteps: int, save_every: int,
                  out: np.ndarray, rtol: float = 1e-13, finish=None) -> np.ndarray:
    """scipy's DOP853 at rtol 1e-13, sampled at the same times as the fixed-step methods. With a finish hook
    (a tree's rotation vectors), from sample to sample, finish(y, p) applied at every sample."""
    if finish is not None:
        return _reference_in_legs(rhs, finish, y0, params, dt * save_every, out, rtol)
    from scipy.integrate import solve_ivp

    batch, n = y0.shape
    samples = np.arange(out.shape[0]) * save_every * dt
    failed = np.full(batch, -1, dtype=np.int64)
    for b in range(batch):
        p = params[b]

        def f(_t, y, p=p):
            k = np.empty(n)
            rhs(np.ascontiguousarray(y), p, k)
            return k

        scale = max(float(np.max(np.abs(y0[b]))), 1.0)
        solution = solve_ivp(f, (0.0, samples[-1]), y0[b], method="DOP853", t_eval=samples,
                             rtol=rtol, atol=rtol * 1e-2 * scale)
        if not solution.success:
            failed[b] = 1
            continue
        out[:, b] = solution.y.T
    return failed


def _reference_in_legs(rhs, finish, y0, params, interval, out, rtol):
    """DOP853 over each sampling interval [s], then finish(y, p) (phi folded into the quaternions, phi = 0)."""
    from scipy.integrate import solve_ivp

    batch, n = y0.shape
    failed = np.full(batch, -1, dtype=np.int64)
    for b in range(batch):
        p = np.ascontiguousarray(params[b])

        def f(_t, y, p=p):
            k = np.empty(n)
            rhs(np.ascontiguousarray(y), p, k)
            return k

        y = np.array(y0[b], dtype=np.float64)
        out[0, b] = y
        scale = max(float(np.max(np.abs(y))), 1.0)
        for s in range(1, out.shape[0]):
            solution = solve_ivp(f, (0.0, interval), y, method="DOP853", rtol=rtol, atol=rtol * 1e-2 * scale)
            if not solution.success:
                failed[b] = s
                break
            y = np.ascontiguousarray(solution.y[:, -1])
            finish(y, p)
            out[s, b] = y
    return failed
