"""Helpers every loop uses: borrowed arrays, rows as raw pointers, the RMS norm, compensated
summation, the sign-change test of events, and array copies.

A loop works on *borrowed* arrays (``_borrowed``): views that hold no reference. A loop's
helpers are inlined into it (``inline="always"``), and numba counts a reference for each array
bound to a helper's parameter; around the calls a helper makes (the model's functions, the
stages) numba cannot prune those counts, which cost an atomic increment and decrement per
array, helper and step. A borrowed array has no reference to count, so the helpers cost
nothing. A loop borrows only arrays its caller holds for the whole call: its arguments, and
scratch arrays its entry point allocates and passes on (``erk._erk_work``,
``radau.radau15_advance``, ``fixed.gauss_advance``, ``fixed.composition_advance``)."""

import math

from numba import njit, types
from numba.core import cgutils
from numba.extending import intrinsic


@intrinsic
def _row(typingctx, a, i):  # type: ignore[no-untyped-def]
    """``a[i].ctypes`` of a C-contiguous 2-D float64 array without making the view ``a[i]``:
    a view costs an atomic reference-count increment and decrement, and a DOP853 step passes
    twelve rows to the kernel."""
    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        zero = context.get_constant(types.intp, 0)
        return cgutils.get_item_pointer(context, builder, sig.args[0], ary, [args[1], zero])
    return types.CPointer(types.float64)(a, types.intp), codegen


@intrinsic
def _item(typingctx, a, i):  # type: ignore[no-untyped-def]
    """A pointer to ``a[i]`` of a 1-D float64 array (with ``numba.carray``: a view of part of
    ``a`` of any shape that holds no reference, valid only while the caller holds ``a``)."""
    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        ary = context.make_array(sig.args[0])(context, builder, args[0])
        return cgutils.get_item_pointer(context, builder, sig.args[0], ary, [args[1]])
    return types.CPointer(types.float64)(a, types.intp), codegen


@intrinsic
def _borrowed(typingctx, a):  # type: ignore[no-untyped-def]
    """A view of array ``a`` (its data, shape and strides) that holds no reference: valid
    only while the caller holds ``a`` (see the module docstring)."""
    def codegen(context, builder, sig, args):  # type: ignore[no-untyped-def]
        src = context.make_array(sig.args[0])(context, builder, args[0])
        dst = context.make_array(sig.return_type)(context, builder)
        dst.meminfo = cgutils.get_null_value(dst.meminfo.type)
        dst.parent = cgutils.get_null_value(dst.parent.type)
        dst.nitems = src.nitems
        dst.itemsize = src.itemsize
        dst.data = src.data
        dst.shape = src.shape
        dst.strides = src.strides
        return dst._getvalue()
    return a(a), codegen


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _rms_norm(x, scale):
    s = 0.0
    for i in range(x.size):
        z = x[i] / scale[i]
        s += z * z
    return math.sqrt(s / x.size)


@njit(inline="always")
def _kahan(x, comp, i, inc):
    """x[i] += inc, with the low-order bits lost kept in comp[i] and added next time."""
    d = inc + comp[i]
    xn = x[i] + d
    comp[i] = d - (xn - x[i])
    x[i] = xn


@njit(cache=True, nogil=True, error_model="numpy")  # 1/0 is inf, caught as non-finite
def _add_compensated(x, inc, comp, lo, hi):
    """x[lo:hi] += inc[lo:hi] with Kahan compensation carried in comp[lo:hi]."""
    for i in range(lo, hi):
        d = inc[i] + comp[i]
        xn = x[i] + d
        comp[i] = d - (xn - x[i])
        x[i] = xn


@njit(inline="always")
def _crossed(g0, g1, direction):
    """A sign change from g0 to g1 in ``direction`` (+1 rising, -1 falling, 0 either)."""
    if direction >= 0 and g0 < 0.0 <= g1:
        return True
    return direction <= 0 and g0 > 0.0 >= g1


@njit(inline="always")
def _copy(dst, src):
    """dst[:] = src (1-D)."""
    for i in range(src.size):
        dst[i] = src[i]


@njit(inline="always")
def _copy_row(Y, k, y):
    """Y[k, :] = y."""
    for i in range(y.size):
        Y[k, i] = y[i]


@njit(inline="always")
def _copy_matrix(dst, src):
    """dst[:, :] = src (2-D)."""
    for i in range(src.shape[0]):
        for j in range(src.shape[1]):
            dst[i, j] = src[i, j]


@njit(inline="always")
def _zero(x):
    """x[:] = 0 (1-D)."""
    for i in range(x.size):
        x[i] = 0


@njit(inline="always")
def _zero_matrix(x):
    """x[:, :] = 0 (2-D)."""
    for i in range(x.shape[0]):
        for j in range(x.shape[1]):
            x[i, j] = 0.0


@njit(inline="always")
def _finite_row(a, r, n):
    """Whether a[r, :n] is finite."""
    finite = True
    for j in range(n):
        finite = finite and math.isfinite(a[r, j])
    return finite


@njit(inline="always")
def _any_crossed(g_old, g_new, ev_dir):
    """Whether an event function changed sign in its direction."""
    crossed = False
    for i in range(ev_dir.size):
        crossed = crossed or _crossed(g_old[i], g_new[i], ev_dir[i])
    return crossed
