"""The substep loop compiled: batched read, force kernel, batched write and pymunk step, without Python.

:meth:`omni_gym.physics.world.World.substeps` runs its substeps between contact switches through
:func:`run_substeps` (or :func:`run_substeps_parallel`, the threaded kernel). Each substep makes the
same calls, in the same order, as the Python loop it replaces (``BodyBatch.read``, the kernel,
``BodyBatch.write``, ``BodyBatch.step``), so results are bit-identical; only the cost of a Python
call per step is gone (about 4 µs per substep for one robot, more than the physics itself).

pymunk's C functions are called through their addresses (``BodyBatch.c_table``, columns ``C_*`` of
:mod:`omni_gym.physics.pymunk_batch`, the only module that knows pymunk's internals), by small
numba intrinsics that cast an integer to a function pointer. The loop holds the GIL, so pymunk's
collision callbacks (Python, through cffi) run as they did from the Python loop.
"""

from __future__ import annotations

import numba
from llvmlite import ir
from numba import types
from numba.extending import intrinsic

from omni_gym.physics.kernel import substep, substep_parallel
from omni_gym.physics.pymunk_batch import (
    C_EACH_BODY,
    C_FORCES,
    C_GET_INT_NUM,
    C_GET_ITER,
    C_GET_NUM,
    C_GET_REQ,
    C_N_SET,
    C_SET_ITER,
    C_SET_NUM,
    C_SET_REQ,
    C_SPACE,
    C_STATES,
    C_STEP,
)

_VOID_P = ir.IntType(8).as_pointer()


@intrinsic
def _each_body(typingctx, fn, space, func, data):
    """Call ``void cpSpaceEachBody(cpSpace *, void (*)(cpBody *, void *), void *)`` at address ``fn``."""
    sig = types.void(types.int64, types.int64, types.int64, types.int64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.VoidType(), [_VOID_P, _VOID_P, _VOID_P])
        target = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(target, [builder.inttoptr(a, _VOID_P) for a in args[1:]])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _space_step(typingctx, fn, space, dt):
    """Call ``void cpSpaceStep(cpSpace *, double)`` at address ``fn``."""
    sig = types.void(types.int64, types.int64, types.float64)

    def codegen(context, builder, signature, args):
        fnty = ir.FunctionType(ir.VoidType(), [_VOID_P, ir.DoubleType()])
        target = builder.inttoptr(args[0], fnty.as_pointer())
        builder.call(target, [builder.inttoptr(args[1], _VOID_P), args[2]])
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _store_int(typingctx, address, value):
    """Store ``value`` as a C ``int`` (int32) at ``address`` (the element count of a pymunk array)."""
    sig = types.void(types.int64, types.int64)

    def codegen(context, builder, signature, args):
        i32 = ir.IntType(32)
        ptr = builder.inttoptr(args[0], i32.as_pointer())
        builder.store(builder.trunc(args[1], i32), ptr)
        return context.get_dummy_value()

    return sig, codegen


@intrinsic
def _float_pointer(typingctx, address):
    """The float64 pointer at integer ``address`` (for ``numba.carray`` over a pymunk buffer)."""
    sig = types.CPointer(types.float64)(types.int64)

    def codegen(context, builder, signature, args):
        return builder.inttoptr(args[0], ir.DoubleType().as_pointer())

    return sig, codegen


@numba.njit(cache=True, inline="always")
def _read(c):
    _store_int(c[C_GET_NUM], 0)
    _store_int(c[C_GET_INT_NUM], 0)
    _each_body(c[C_EACH_BODY], c[C_SPACE], c[C_GET_ITER], c[C_GET_REQ])


@numba.njit(cache=True, inline="always")
def _write_and_step(c, dt):
    _store_int(c[C_SET_NUM], 0)
    _each_body(c[C_EACH_BODY], c[C_SPACE], c[C_SET_ITER], c[C_SET_REQ])
    _store_int(c[C_SET_NUM], c[C_N_SET])
    _space_step(c[C_STEP], c[C_SPACE], dt)


@numba.njit(cache=True)
def run_substeps(count, c, dt, state, wheels, sp, wp, ext, force, slip):
    """``count`` substeps of ``dt`` [s]: read the bodies into ``state``, run the serial kernel, write
    ``force`` and step the space (``c``: ``BodyBatch.c_table``; arrays as in ``kernel.substep``)."""
    for _ in range(count):
        _read(c)
        substep(dt, state, wheels, sp, wp, ext, force, slip)
        _write_and_step(c, dt)


@numba.njit(cache=True)
def run_substeps_parallel(count, c, dt, state, wheels, sp, wp, ext, force, slip):
    """:func:`run_substeps` with the threaded kernel (bit-identical results)."""
    for _ in range(count):
        _read(c)
        substep_parallel(dt, state, wheels, sp, wp, ext, force, slip)
        _write_and_step(c, dt)


@numba.njit(cache=True, parallel=True)
def run_substeps_spaces(count, tables, dt, bounds, state, wheels, sp, wp, ext, slip):
    """:func:`run_substeps` for robots split among pymunk spaces: space k (``tables[k]``, one
    ``BodyBatch.c_table`` each) holds robots ``bounds[k]`` to ``bounds[k + 1]``; each thread runs
    every substep of its spaces (read, serial kernel, write, step) with no join between substeps,
    then gathers its robots' final states into ``state`` (B, 6). Each robot's arithmetic is that of
    :func:`run_substeps`, so results are bit-identical whatever the split and the thread count."""
    for k in numba.prange(tables.shape[0]):
        c = tables[k]
        lo = bounds[k]
        hi = bounds[k + 1]
        own = numba.carray(_float_pointer(c[C_STATES]), (hi - lo, 6))
        force = numba.carray(_float_pointer(c[C_FORCES]), (hi - lo, 3))
        w, p, q, e, s = wheels[lo:hi], sp[lo:hi], wp[lo:hi], ext[lo:hi], slip[lo:hi]
        for _ in range(count):
            _read(c)
            substep(dt, own, w, p, q, e, force, s)
            _write_and_step(c, dt)
        _read(c)
        state[lo:hi] = own
