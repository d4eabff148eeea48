"""Views into a flat float64 buffer, made inside compiled code without a reshape.

A circuit device keeps all its per-side arrays (states, parameters, work and scratch rows,
the phase state, the profile, the coupling outputs) in one flat float64 buffer, so that the
compiled calls of a coupled MuJoCo step take two array arguments instead of a dozen
(:func:`afo_mj.circuits.stepper.device_views`). Cutting that buffer into 2-D and 3-D arrays
with ``buf[a:b].reshape(...)`` costs ~25 ns per view in numba 0.68 (the general reshape path
with its checks), nine views twice a step; ``numpy.lib.stride_tricks.as_strided`` is free but
types its result as a non-contiguous (``"A"``) array, which makes numba compile every stepper
function a second time (for the ``"C"`` arrays Python passes in) and each circuit's cold
compile ~2.5 s longer. :func:`view2` and :func:`view3` build the C-contiguous array directly:
the buffer's data pointer advanced by ``offset`` elements, the given shape, C strides, and the
buffer's reference (the view keeps it alive, as a numpy view would).

No bounds check: the caller guarantees ``offset + prod(shape) <= buf.size`` (the device's
layout is sized to hold every block). Example, inside an ``@njit`` function:
``Y = view2(buf, 0, 2, 6)`` is ``buf[0:12].reshape((2, 6))``.
"""

from __future__ import annotations

from numba.core import types
from numba.core.imputils import impl_ret_borrowed
from numba.extending import intrinsic
from numba.np.arrayobj import make_array, populate_array


def _view(context, builder, buf_type, buf_value, offset, dims, ret_type):
    src = make_array(buf_type)(context, builder, buf_value)
    out = make_array(ret_type)(context, builder)
    item = context.get_constant(types.intp, context.get_abi_sizeof(
        context.get_data_type(buf_type.dtype)))
    dims = [context.cast(builder, d, t, types.intp) for d, t in dims]
    strides = []
    acc = item
    for d in reversed(dims):
        strides.insert(0, acc)
        acc = builder.mul(acc, d)
    data = builder.gep(src.data, [context.cast(builder, offset[0], offset[1], types.intp)])
    populate_array(out, data=data,
                   shape=context.make_tuple(builder, types.UniTuple(types.intp, len(dims)),
                                            dims),
                   strides=context.make_tuple(builder, types.UniTuple(types.intp, len(dims)),
                                              strides),
                   itemsize=item, meminfo=src.meminfo, parent=src.parent)
    return impl_ret_borrowed(context, builder, ret_type, out._getvalue())


def _check(buf):
    if not (isinstance(buf, types.Array) and buf.ndim == 1 and buf.layout == "C"):
        raise TypeError(f"buffer view: the buffer must be a 1-D C-contiguous array, got {buf}")


@intrinsic
def view2(typingctx, buf, offset, n0, n1):
    """``buf[offset:offset + n0*n1].reshape((n0, n1))`` as a C-contiguous view."""
    _check(buf)
    ret = types.Array(buf.dtype, 2, "C")

    def codegen(context, builder, sig, args):
        return _view(context, builder, sig.args[0], args[0], (args[1], sig.args[1]),
                     [(args[2], sig.args[2]), (args[3], sig.args[3])], ret)
    return ret(buf, offset, n0, n1), codegen


@intrinsic
def view3(typingctx, buf, offset, n0, n1, n2):
    """``buf[offset:offset + n0*n1*n2].reshape((n0, n1, n2))`` as a C-contiguous view."""
    _check(buf)
    ret = types.Array(buf.dtype, 3, "C")

    def codegen(context, builder, sig, args):
        return _view(context, builder, sig.args[0], args[0], (args[1], sig.args[1]),
                     [(args[2], sig.args[2]), (args[3], sig.args[3]),
                      (args[4], sig.args[4])], ret)
    return ret(buf, offset, n0, n1, n2), codegen


__all__ = ["view2", "view3"]
