"""Raw memory for the compiled kernels: a buffer on the stack of an evaluation, the address of an element.

An evaluation of a tree's right-hand side runs millions of times per simulation; an array allocated in it
(np.empty: the allocator, reference counting) would cost more than the arithmetic of a small tree. These numba
intrinsics let a kernel work in memory it never allocates on the heap (stack_floats), read arrays through raw
pointers (address, data) or through views numba does not count (unowned), and keep an array of its own alive while
it reads it through one (keep_alive).
"""

from __future__ import annotations

from numba import carray, njit, types
from numba.extending import intrinsic

F64P = types.CPointer(types.float64)


@intrinsic
def stack_floats(typingctx, count):
    """float64* to `count` uninitialised doubles on the stack of the calling function (an LLVM alloca, freed
    when that function returns: call it in the function that uses the memory, never in a helper that returns
    it; where LLVM inlines the caller into a loop it brackets the alloca with stacksave/stackrestore)."""
    if not isinstance(count, types.Integer):
        return None

    def codegen(context, builder, signature, args):
        size = context.cast(builder, args[0], signature.args[0], types.intp)
        return builder.alloca(context.get_value_type(types.float64), size=size)
    return F64P(count), codegen


@intrinsic
def address(typingctx, array, offset):
    """A pointer to array[offset] of a contiguous 1-D array of numbers (float64* for float64; no view is formed)."""
    if not (isinstance(array, types.Array) and isinstance(array.dtype, types.Number) and array.ndim == 1
            and array.layout == "C" and isinstance(offset, types.Integer)):
        return None

    def codegen(context, builder, signature, args):
        data = context.make_array(signature.args[0])(context, builder, args[0]).data
        return builder.gep(data, [context.cast(builder, args[1], signature.args[1], types.intp)])
    return types.CPointer(array.dtype)(array, offset), codegen


@intrinsic
def data(typingctx, array):
    """A pointer to the first element of a C-contiguous array of numbers of any rank (its data pointer; float64*
    for float64)."""
    if not (isinstance(array, types.Array) and isinstance(array.dtype, types.Number) and array.layout == "C"):
        return None

    def codegen(context, builder, signature, args):
        return context.make_array(signature.args[0])(context, builder, args[0]).data
    return types.CPointer(array.dtype)(array), codegen


@intrinsic
def keep_alive(typingctx, array):
    """Nothing at run time; a use of `array` by name. numba frees a function's own array after the last statement
    that names it, and a raw pointer taken from it (address, data) does not count: a kernel that works in an
    array of its own through such a pointer calls keep_alive(array) after its last access, or it writes into
    freed memory (a workspace on the heap, beyond malloc's mmap threshold, is unmapped: a segmentation fault)."""
    if not isinstance(array, types.Array):
        return None

    def codegen(context, builder, signature, args):
        return context.get_dummy_value()
    return types.none(array), codegen


@njit(cache=True, inline="always")
def unowned(array):
    """The C-contiguous array of numbers `array` (any rank and number type) as a view numba does not reference-count.
    numba counts the references to an array's memory with an atomic add wherever a function receives it, binds a
    view of it or hands it on (about 6 ns each, twice: increment and decrement); a view over raw memory has no count,
    and each of those is a test of a null pointer. For a kernel that hands the same arrays to many small helpers per
    item (a step's near contacts); the array itself must outlive the view (an argument does; an array of the
    kernel's own needs keep_alive after its last use)."""
    return carray(data(array), array.shape)


@njit(cache=True, inline="always")
def cut(arena, at, shape):
    """arena[at:at + prod(shape)] (a C-contiguous 1-D array of numbers) as an array of that shape (an int or a
    tuple), a view numba does not reference-count (unowned): one allocation carved into the many arrays of a
    kernel. The arena must outlive the view, and views cut from it must not overlap."""
    return carray(address(arena, at), shape)
