"""Eight float64 lanes as a numba value: explicit SIMD for the compiled kernels.

numba leaves LLVM's straight-line (SLP) vectoriser off and vectorises only loops, so the 6 x 6 algebra of the
3-D engine and the side-by-side evaluation of a batch's elements would otherwise run one number at a time.
`Lanes` is a numba type whose LLVM value is a vector <8 x double> (one AVX-512 register; two AVX2 registers
elsewhere: LLVM splits what the machine lacks), held in local variables like a float:

    a = load(ptr, at)            # ptr[at:at + 8] (ptr: a float64 pointer, rbody.engine.memory.address)
    b = load6(ptr, at)           # ptr[at:at + 6], lanes 6 and 7 zero (reads and writes nothing beyond)
    c = a * b + a * 2.0          # lane by lane, each lane exactly the scalar operation; a number acts on every lane
    store(ptr, at, c); store6(ptr, at, c)
    x = lane(c, 3); s = total(c) # one lane; the sum of the lanes (a balanced tree: reproducible)
    splat(x), lanes(x0, ..., x7) # every lane x; the lanes given
    greater(a, b)                # 1.0 where a > b (ordered: false for NaN), else 0.0
    where(m, a, b)               # a where m != 0, else b
    abs(a), maximum(a, b)        # |a|; numba's max(a, b) lane by lane (b where b > a, else a)
    sin_cos(a)                   # (sin, cos) lane by lane as rbody.engine.spatial.sin_cos (|a| < REDUCED_RANGE)

Each lane of a result has the bits the same operations give one float64 (IEEE arithmetic, no fused
multiply-add): a kernel written once for floats and once for lanes gives each lane the scalar kernel's bits.
Every operation is inlined where it is used; nothing allocates.
"""

from __future__ import annotations

import operator

from llvmlite import ir
from numba import types
from numba.core import cgutils
from numba import njit
from numba.extending import intrinsic, models, overload, register_model

import numpy as np

from rbody.engine.spatial import (_C1, _C2, _C3, _C4, _C5, _C6, _PIO2_1, _PIO2_2, _PIO2_3, _ROUND, _S1, _S2, _S3, _S4,
                                  _S5, _S6, _TWO_OVER_PI, REDUCED_RANGE)
from rbody.engine.spatial import sin_cos as scalar_sin_cos

WIDTH = 8
_DOUBLE = ir.DoubleType()
_VECTOR = ir.VectorType(_DOUBLE, WIDTH)
_I32 = ir.IntType(32)
_I1 = ir.IntType(1)
_FLAGS = ()  # plain IEEE operations, lane by lane as the same scalar operation: no fusing of a product and a sum
_F64P = types.CPointer(types.float64)


class LanesType(types.Type):
    """Eight float64 lanes (LLVM <8 x double>)."""

    def __init__(self) -> None:
        super().__init__(name="Lanes")


Lanes = LanesType()


@register_model(LanesType)
class _LanesModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _VECTOR)


def _pointer(builder, context, signature, args):
    at = context.cast(builder, args[1], signature.args[1], types.intp)
    return builder.bitcast(builder.gep(args[0], [at]), _VECTOR.as_pointer())


def _mask6():
    return ir.Constant(ir.VectorType(_I1, WIDTH), [1] * 6 + [0] * 2)


def _splat(builder, x):
    v = builder.insert_element(ir.Constant(_VECTOR, ir.Undefined), x, ir.Constant(_I32, 0))
    return builder.shuffle_vector(v, ir.Constant(_VECTOR, ir.Undefined), ir.Constant(ir.VectorType(_I32, WIDTH),
                                                                                      [0] * WIDTH))


def _is_number(t) -> bool:
    return isinstance(t, (types.Float, types.Integer))


def _as_vector(context, builder, value, t):
    return value if t == Lanes else _splat(builder, context.cast(builder, value, t, types.float64))


@intrinsic
def load(typingctx, ptr, at):
    """ptr[at:at + 8] as lanes (ptr: float64 pointer, at: integer)."""
    if ptr != _F64P or not isinstance(at, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.load(_pointer(builder, context, signature, args), align=8)
    return Lanes(ptr, at), codegen


@intrinsic
def store(typingctx, ptr, at, value):
    """ptr[at:at + 8] = value."""
    if ptr != _F64P or not isinstance(at, types.Integer) or value != Lanes:
        return None

    def codegen(context, builder, signature, args):
        builder.store(args[2], _pointer(builder, context, signature, args), align=8)
        return context.get_dummy_value()
    return types.none(ptr, at, value), codegen


@intrinsic
def load6(typingctx, ptr, at):
    """ptr[at:at + 6] in lanes 0-5, lanes 6 and 7 zero; nothing beyond ptr[at + 5] is read."""
    if ptr != _F64P or not isinstance(at, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        function = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(_VECTOR, [_VECTOR.as_pointer(), _I32, ir.VectorType(_I1, WIDTH), _VECTOR]),
            "llvm.masked.load.v8f64.p0v8f64")
        return builder.call(function, [_pointer(builder, context, signature, args), ir.Constant(_I32, 8), _mask6(),
                                       ir.Constant(_VECTOR, [0.0] * WIDTH)])
    return Lanes(ptr, at), codegen


@intrinsic
def store6(typingctx, ptr, at, value):
    """ptr[at:at + 6] = lanes 0-5 of value; nothing beyond ptr[at + 5] is written."""
    if ptr != _F64P or not isinstance(at, types.Integer) or value != Lanes:
        return None

    def codegen(context, builder, signature, args):
        function = cgutils.get_or_insert_function(
            builder.module, ir.FunctionType(ir.VoidType(), [_VECTOR, _VECTOR.as_pointer(), _I32,
                                                           ir.VectorType(_I1, WIDTH)]),
            "llvm.masked.store.v8f64.p0v8f64")
        builder.call(function, [args[2], _pointer(builder, context, signature, args), ir.Constant(_I32, 8), _mask6()])
        return context.get_dummy_value()
    return types.none(ptr, at, value), codegen


@intrinsic
def splat(typingctx, x):
    """Every lane x."""
    if not _is_number(x):
        return None

    def codegen(context, builder, signature, args):
        return _as_vector(context, builder, args[0], signature.args[0])
    return Lanes(x), codegen


@intrinsic
def lanes(typingctx, x0, x1, x2, x3, x4, x5, x6, x7):
    """The lanes (x0, ..., x7)."""
    if not all(_is_number(t) for t in (x0, x1, x2, x3, x4, x5, x6, x7)):
        return None

    def codegen(context, builder, signature, args):
        v = ir.Constant(_VECTOR, ir.Undefined)
        for k, (value, t) in enumerate(zip(args, signature.args)):
            v = builder.insert_element(v, context.cast(builder, value, t, types.float64), ir.Constant(_I32, k))
        return v
    return Lanes(x0, x1, x2, x3, x4, x5, x6, x7), codegen


@intrinsic
def lane(typingctx, v, k):
    """Lane k of v (a float)."""
    if v != Lanes or not isinstance(k, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        return builder.extract_element(args[0], context.cast(builder, args[1], signature.args[1], types.int32))
    return types.float64(v, k), codegen


@intrinsic
def total(typingctx, v):
    """The sum of the lanes, halving: ((0 + 4) + (2 + 6)) + ((1 + 5) + (3 + 7)) (a fixed order: reproducible)."""
    if v != Lanes:
        return None

    def codegen(context, builder, signature, args):
        x, undefined = args[0], ir.Constant(_VECTOR, ir.Undefined)
        for half in (4, 2, 1):
            moved = builder.shuffle_vector(x, undefined, ir.Constant(ir.VectorType(_I32, WIDTH),
                                                                     [(k + half) % WIDTH for k in range(WIDTH)]))
            x = builder.fadd(x, moved, flags=_FLAGS)
        return builder.extract_element(x, ir.Constant(_I32, 0))
    return types.float64(v), codegen


@intrinsic
def broadcast(typingctx, v, k):
    """Every lane equal to lane k of v (k a constant integer)."""
    if v != Lanes or not isinstance(k, types.IntegerLiteral):
        return None
    index = k.literal_value

    def codegen(context, builder, signature, args):
        return builder.shuffle_vector(args[0], ir.Constant(_VECTOR, ir.Undefined),
                                      ir.Constant(ir.VectorType(_I32, WIDTH), [index] * WIDTH))
    return Lanes(v, k), codegen


def _binary(name: str, operation):
    @intrinsic
    def binary(typingctx, a, b):
        if not ((a == Lanes and (b == Lanes or _is_number(b))) or (_is_number(a) and b == Lanes)):
            return None

        def codegen(context, builder, signature, args):
            x = _as_vector(context, builder, args[0], signature.args[0])
            y = _as_vector(context, builder, args[1], signature.args[1])
            return getattr(builder, operation)(x, y, flags=_FLAGS)
        return Lanes(a, b), codegen
    binary.__name__ = name
    return binary


_add, _sub, _mul, _div = (_binary(n, op) for n, op in (("add", "fadd"), ("sub", "fsub"), ("mul", "fmul"),
                                                        ("div", "fdiv")))


def _operator(function, operation):
    @overload(function, inline="always")
    def implementation(a, b):
        if (a == Lanes and (b == Lanes or _is_number(b))) or (_is_number(a) and b == Lanes):
            return lambda a, b: operation(a, b)
    return implementation


for _function, _operation in ((operator.add, _add), (operator.sub, _sub), (operator.mul, _mul),
                              (operator.truediv, _div), (operator.iadd, _add), (operator.isub, _sub),
                              (operator.imul, _mul), (operator.itruediv, _div)):
    _operator(_function, _operation)


@intrinsic
def _negative(typingctx, a):
    if a != Lanes:
        return None

    def codegen(context, builder, signature, args):
        return builder.fneg(args[0])
    return Lanes(a), codegen


@overload(operator.neg, inline="always")
def _neg(a):
    if a == Lanes:
        return lambda a: _negative(a)


@intrinsic
def greater(typingctx, a, b):
    """1.0 where a > b (an ordered comparison: 0.0 where either is NaN), else 0.0."""
    if not ((a == Lanes and (b == Lanes or _is_number(b))) or (_is_number(a) and b == Lanes)):
        return None

    def codegen(context, builder, signature, args):
        x = _as_vector(context, builder, args[0], signature.args[0])
        y = _as_vector(context, builder, args[1], signature.args[1])
        return builder.uitofp(builder.fcmp_ordered(">", x, y), _VECTOR)
    return Lanes(a, b), codegen


@intrinsic
def where(typingctx, mask, a, b):
    """a where mask != 0, else b (a, b lanes or numbers)."""
    if mask != Lanes or not all(t == Lanes or _is_number(t) for t in (a, b)):
        return None

    def codegen(context, builder, signature, args):
        chosen = builder.fcmp_unordered("!=", args[0], ir.Constant(_VECTOR, [0.0] * WIDTH))
        x = _as_vector(context, builder, args[1], signature.args[1])
        y = _as_vector(context, builder, args[2], signature.args[2])
        return builder.select(chosen, x, y)
    return Lanes(mask, a, b), codegen


@intrinsic
def _fabs(typingctx, a):
    if a != Lanes:
        return None

    def codegen(context, builder, signature, args):
        function = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VECTOR, [_VECTOR]), "llvm.fabs.v8f64")
        return builder.call(function, [args[0]])
    return Lanes(a), codegen


@overload(abs, inline="always")
def _abs(a):
    if a == Lanes:
        return lambda a: _fabs(a)


@intrinsic
def maximum(typingctx, a, b):
    """numba's max(a, b) lane by lane: b where b > a, else a (so a NaN b gives a)."""
    if not ((a == Lanes and (b == Lanes or _is_number(b))) or (_is_number(a) and b == Lanes)):
        return None

    def codegen(context, builder, signature, args):
        x = _as_vector(context, builder, args[0], signature.args[0])
        y = _as_vector(context, builder, args[1], signature.args[1])
        return builder.select(builder.fcmp_ordered(">", y, x), y, x)
    return Lanes(a, b), codegen


@intrinsic
def _quadrant(typingctx, k, sine, cosine):
    """The last step of sin_cos: (sign (cos if odd else sin), sign (-sin if odd else cos)), n = int(k), odd = n & 1,
    sign = 1 - (n & 2), as rbody.engine.spatial.sin_cos computes it for one number."""
    if not (k == Lanes and sine == Lanes and cosine == Lanes):
        return None

    def codegen(context, builder, signature, args):
        i64 = ir.VectorType(ir.IntType(64), WIDTH)
        n = builder.fptosi(args[0], i64)
        odd = builder.icmp_signed("!=", builder.and_(n, ir.Constant(i64, [1] * WIDTH)), ir.Constant(i64, [0] * WIDTH))
        sign = builder.sitofp(builder.sub(ir.Constant(i64, [1] * WIDTH), builder.and_(n, ir.Constant(i64, [2] * WIDTH))),
                              _VECTOR)
        s, c = args[1], args[2]
        first = builder.fmul(sign, builder.select(odd, c, s))
        second = builder.fmul(sign, builder.select(odd, builder.fneg(s), c))
        return context.make_tuple(builder, signature.return_type, (first, second))
    return types.UniTuple(Lanes, 2)(k, sine, cosine), codegen


@njit(cache=True, inline="always")
def sin_cos(x):
    """(sin x, cos x) lane by lane, each lane with the bits of rbody.engine.spatial.sin_cos (no fused multiply-add):
    valid where |x| < REDUCED_RANGE."""
    k = (x * _TWO_OVER_PI + _ROUND) - _ROUND
    r = ((x - k * _PIO2_1) - k * _PIO2_2) - k * _PIO2_3
    z = r * r
    sine = r + r * z * (_S1 + z * (_S2 + z * (_S3 + z * (_S4 + z * (_S5 + z * _S6)))))
    hz = 0.5 * z
    one = 1.0 - hz
    cosine = one + (((1.0 - one) - hz) + z * z * (_C1 + z * (_C2 + z * (_C3 + z * (_C4 + z * (_C5 + z * _C6))))))
    return _quadrant(k, sine, cosine)


@intrinsic
def largest_abs(typingctx, a):
    """The largest |lane|; NaN if a lane is NaN."""
    if a != Lanes:
        return None

    def codegen(context, builder, signature, args):
        function = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VECTOR, [_VECTOR]), "llvm.fabs.v8f64")
        x = builder.call(function, [args[0]])
        result = builder.extract_element(x, ir.Constant(_I32, 0))
        nan = builder.fcmp_unordered("uno", result, result)
        for k in range(1, WIDTH):
            y = builder.extract_element(x, ir.Constant(_I32, k))
            result = builder.select(builder.fcmp_ordered(">", y, result), y, result)
            nan = builder.or_(nan, builder.fcmp_unordered("uno", y, y))
        return builder.select(nan, ir.Constant(_DOUBLE, float("nan")), result)
    return types.float64(a), codegen


# ----- one kernel for numbers and for lanes ---------------------------------------------------------------------
# A LanePointer is a float64 pointer over a structure of arrays: p[k] is the lanes of entry k (p's memory
# [k WIDTH, (k + 1) WIDTH)), p[k] = x stores lanes (or a number in every lane). A kernel written with p[k] and the
# helpers below (number, choose, pivot_good) compiles for float64 pointers, one state, and for LanePointers, WIDTH
# states side by side, from the same source: each lane then does the scalar kernel's operations.

class LanePointerType(types.Type):
    """A float64 pointer indexed by entry: p[k] are the WIDTH lanes at p + k WIDTH."""

    def __init__(self) -> None:
        super().__init__(name="LanePointer")


LanePointer = LanePointerType()


@register_model(LanePointerType)
class _LanePointerModel(models.PrimitiveModel):
    def __init__(self, dmm, fe_type):
        super().__init__(dmm, fe_type, _DOUBLE.as_pointer())


@intrinsic
def lane_pointer(typingctx, ptr):
    """The LanePointer over the float64 pointer ptr (entry k at ptr[k WIDTH:(k + 1) WIDTH])."""
    if ptr != _F64P:
        return None

    def codegen(context, builder, signature, args):
        return args[0]
    return LanePointer(ptr), codegen


@intrinsic
def _raw(typingctx, pointer):
    if pointer != LanePointer:
        return None

    def codegen(context, builder, signature, args):
        return args[0]
    return _F64P(pointer), codegen


@overload(operator.getitem)
def _lane_getitem(pointer, k):
    if pointer == LanePointer and isinstance(k, types.Integer):
        return lambda pointer, k: load(_raw(pointer), k * WIDTH)


@overload(operator.setitem)
def _lane_setitem(pointer, k, value):
    if pointer == LanePointer and isinstance(k, types.Integer):
        if value == Lanes:
            return lambda pointer, k, value: store(_raw(pointer), k * WIDTH, value)
        if _is_number(value):
            return lambda pointer, k, value: store(_raw(pointer), k * WIDTH, splat(value))


def number(pointer, x):
    """x as a value of the kind `pointer` holds: the float x for a float64 pointer, x in every lane for a
    LanePointer (a kernel's constants, so that a variable is of one kind in every branch)."""


@overload(number)
def _number(pointer, x):
    if pointer == LanePointer and _is_number(x):
        return lambda pointer, x: splat(x)
    if pointer == _F64P and _is_number(x):
        return lambda pointer, x: float(x)


def choose(condition, a, b):
    """a where condition holds, else b: a bool and numbers (a if condition else b), or a Lanes mask (where)."""


@overload(choose)
def _choose(condition, a, b):
    if condition == Lanes:
        return lambda condition, a, b: where(condition, a, b)
    if isinstance(condition, types.Boolean):
        return lambda condition, a, b: _select(condition, a, b)


def positive_beyond(x, threshold):
    """x > threshold and x > 0 (false for NaN): a bool for numbers, a Lanes mask for lanes."""


@overload(positive_beyond)
def _positive_beyond(x, threshold):
    if x == Lanes:
        return lambda x, threshold: greater(x, threshold) * greater(x, 0.0)
    if isinstance(x, types.Float):
        return lambda x, threshold: (x > threshold) & (x > 0.0)


def equals(x, value):
    """x == value: a bool for numbers, a Lanes mask for lanes."""


@overload(equals)
def _equals(x, value):
    if x == Lanes:
        return lambda x, value: _equal_lanes(x, value)
    if isinstance(x, types.Float):
        return lambda x, value: x == value


@intrinsic
def _equal_lanes(typingctx, x, value):
    if x != Lanes or not _is_number(value):
        return None

    def codegen(context, builder, signature, args):
        y = _as_vector(context, builder, args[1], signature.args[1])
        return builder.uitofp(builder.fcmp_ordered("==", args[0], y), _VECTOR)
    return Lanes(x, value), codegen


def maximum_of(a, b):
    """numba's max(a, b) for numbers (b where b > a, else a), lane by lane for lanes (maximum)."""


@overload(maximum_of)
def _maximum_of(a, b):
    if a == Lanes or b == Lanes:
        return lambda a, b: maximum(a, b)
    if _is_number(a) and _is_number(b):
        return lambda a, b: max(a, b)


def sines_and_cosines(w, s, c, count, largest):
    """In place: w[s + j], w[c + j] = sin, cos of w[s + j] for j < count; largest, the largest |w[s + j]| (of each
    lane), decides as for one number: the polynomial (sin_cos) for every j when within REDUCED_RANGE, else np.sin and
    np.cos. Numbers: one loop without a call, which LLVM vectorises; lanes: lane by lane where needed."""


@njit(cache=True, inline="always")
def _scalar_sines_and_cosines(w, s, c, count, largest):
    if largest < REDUCED_RANGE:
        for j in range(count):
            w[s + j], w[c + j] = scalar_sin_cos(w[s + j])
    else:
        for j in range(count):
            x = w[s + j]
            w[s + j], w[c + j] = np.sin(x), np.cos(x)


@njit(cache=True)
def _lane_sines_and_cosines(w, s, c, count, largest):
    if largest_abs(largest) < REDUCED_RANGE:
        for j in range(count):
            w[s + j], w[c + j] = sin_cos(w[s + j])
        return
    ss = [0.0] * WIDTH
    cc = [0.0] * WIDTH
    for j in range(count):
        x = w[s + j]
        for k in range(WIDTH):
            y = lane(x, k)
            if lane(largest, k) < REDUCED_RANGE:
                ss[k], cc[k] = scalar_sin_cos(y)
            else:
                ss[k], cc[k] = np.sin(y), np.cos(y)
        w[s + j] = lanes(ss[0], ss[1], ss[2], ss[3], ss[4], ss[5], ss[6], ss[7])
        w[c + j] = lanes(cc[0], cc[1], cc[2], cc[3], cc[4], cc[5], cc[6], cc[7])


@overload(sines_and_cosines)
def _sines_and_cosines(w, s, c, count, largest):
    if w == LanePointer:
        return lambda w, s, c, count, largest: _lane_sines_and_cosines(w, s, c, count, largest)
    if w == _F64P:
        return lambda w, s, c, count, largest: _scalar_sines_and_cosines(w, s, c, count, largest)


@intrinsic
def _select(typingctx, condition, a, b):
    """a if condition else b, as one LLVM select (no branch)."""
    if not isinstance(condition, types.Boolean) or not (_is_number(a) and _is_number(b)):
        return None

    def codegen(context, builder, signature, args):
        x = context.cast(builder, args[1], signature.args[1], types.float64)
        y = context.cast(builder, args[2], signature.args[2], types.float64)
        return builder.select(args[0], x, y)
    return types.float64(condition, a, b), codegen


@intrinsic
def _vsqrt(typingctx, a):
    if a != Lanes:
        return None

    def codegen(context, builder, signature, args):
        function = cgutils.get_or_insert_function(builder.module, ir.FunctionType(_VECTOR, [_VECTOR]), "llvm.sqrt.v8f64")
        return builder.call(function, [args[0]])
    return Lanes(a), codegen


@overload(np.sqrt, inline="always")
def _sqrt(a):
    if a == Lanes:
        return lambda a: _vsqrt(a)
