"""Every use of pymunk's batch API and private internals, behind one checked version range.

The world reads all bodies' states and writes all forces once per physics substep. pymunk's public
``pymunk.batch`` functions cost more per call than the data they move for a few robots, so this
module builds the batch requests once and calls pymunk's cffi library (``pymunk.batch.lib``)
directly, through private attributes (``Space._space``, ``Buffer._float_arr``/``_int_arr``). Those
are not a stable API: a pymunk release outside :data:`SUPPORTED` fails at import with one message
instead of a wrong or crashing step. The same range is pinned in ``pyproject.toml``.
"""

from __future__ import annotations

import re

import numpy as np
import pymunk

from omni_gym.physics.layout import (
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
    N_C,
)

# [lower, upper) of the supported pymunk versions; keep equal to the pin in pyproject.toml.
SUPPORTED = ((7, 0), (8, 0))
SUPPORTED_TEXT = "pymunk>=7.0,<8"


def _parse(version: str) -> tuple[int, ...]:
    """(major, minor, ...) of a version string such as ``7.3.1`` (non-numeric tails ignored)."""
    return tuple(int(p) for p in re.findall(r"\d+", version.split("+")[0])[:3])


def check_version(version: str = pymunk.version) -> None:
    """Raise ImportError naming the installed and supported versions if ``version`` is outside."""
    parsed = _parse(version)
    if not parsed or not SUPPORTED[0] <= parsed < SUPPORTED[1]:
        raise ImportError(f"omni_gym needs {SUPPORTED_TEXT} (it calls pymunk's batch internals), "
                          f"but pymunk {version} is installed")


check_version()

from pymunk import batch as _pmbatch  # noqa: E402  (only once the version is known to fit)


class BodyBatch:
    """Batched state read and force write for the first ``n_bodies`` dynamic bodies of a space.

    :attr:`states` (n_bodies, 6): x, y [m] (world frame), angle [rad], ẋ, ẏ [m/s] (world frame),
    ω [rad/s] of each body's centre of gravity, filled by :meth:`read`. :attr:`forces`
    (n_bodies, 3): force x, y [N] (world frame) and torque [N·m], applied by :meth:`write`.
    Bodies come in insertion order; build this after every body has been added.
    """

    def __init__(self, space: pymunk.Space, n_bodies: int) -> None:
        fields = _pmbatch.BodyFields
        get_fields = fields.POSITION | fields.ANGLE | fields.VELOCITY | fields.ANGULAR_VELOCITY
        set_fields = fields.FORCE | fields.TORQUE
        self._get_buf = _pmbatch.Buffer()
        self._set_buf = _pmbatch.Buffer()
        _pmbatch.get_space_bodies(space, get_fields, self._get_buf)
        _pmbatch.get_space_bodies(space, set_fields, self._set_buf)
        # The space's static body is listed too (after the dynamic ones) once it carries shapes.
        states = np.frombuffer(self._get_buf.float_buf(), dtype=np.float64).reshape(-1, 6)
        forces = np.frombuffer(self._set_buf.float_buf(), dtype=np.float64).reshape(-1, 3)
        self.states = states[:n_bodies]
        self.forces = forces[:n_bodies]
        # Pre-built batch requests, called straight through pymunk's cffi library: the per-call
        # setup in pymunk.batch costs more than the data transfer for a few robots.
        ffi, lib = _pmbatch.ffi, _pmbatch.lib
        self._get_arr, self._get_int = self._get_buf._float_arr, self._get_buf._int_arr
        self._set_arr = self._set_buf._float_arr
        self._get_req = ffi.new("pmBatchedData *")
        self._get_req.fields = get_fields.value
        self._get_req.floatArray = self._get_arr
        self._get_req.intArray = self._get_int
        self._set_req = ffi.new("pmBatchedData *")
        self._set_req.fields = set_fields.value
        self._set_req.floatArray = self._set_arr
        self._set_req.intArray = self._set_buf._int_arr
        self._get_iter = ffi.addressof(lib, "pmSpaceBodyGetIteratorFuncBatched")
        self._set_iter = ffi.addressof(lib, "pmSpaceBodySetIteratorFuncBatched")
        self._n_set = self._set_arr.num
        self._cspace = space._space
        self._each_body = lib.cpSpaceEachBody
        self._space_step = lib.cpSpaceStep
        self._space = space

        def address(cdata) -> int:
            return int(ffi.cast("uintptr_t", cdata))

        # The same three calls as raw addresses, for the compiled substep loop (columns C_*); the
        # arrays never grow (the read and write counts are reset before each call), so the
        # addresses stay valid as long as this object (which keeps the space alive) lives.
        table = np.zeros(N_C, dtype=np.int64)
        table[C_SPACE] = address(self._cspace)
        table[C_EACH_BODY] = address(ffi.addressof(lib, "cpSpaceEachBody"))
        table[C_STEP] = address(ffi.addressof(lib, "cpSpaceStep"))
        table[C_GET_ITER] = address(self._get_iter)
        table[C_GET_REQ] = address(self._get_req)
        table[C_SET_ITER] = address(self._set_iter)
        table[C_SET_REQ] = address(self._set_req)
        table[C_GET_NUM] = address(ffi.addressof(self._get_arr[0], "num"))
        table[C_GET_INT_NUM] = address(ffi.addressof(self._get_int[0], "num"))
        table[C_SET_NUM] = address(ffi.addressof(self._set_arr[0], "num"))
        table[C_N_SET] = self._n_set
        table[C_STATES] = self.states.ctypes.data
        table[C_FORCES] = self.forces.ctypes.data
        table.setflags(write=False)
        self.c_table = table

    def check_new_bodies(self) -> None:
        """Let pymunk check bodies whose mass or moment changed (its ``Space.step`` does, and only it)
        before C steps; a no-op when none is pending."""
        if self._space._bodies_to_check:
            self._space.step(0.0)

    def read(self) -> None:
        """Fill :attr:`states` from the space."""
        self._get_arr.num = 0
        self._get_int.num = 0
        self._each_body(self._cspace, self._get_iter, self._get_req)

    def write(self) -> None:
        """Set every body's force and torque from :attr:`forces`."""
        self._set_arr.num = 0
        self._each_body(self._cspace, self._set_iter, self._set_req)
        self._set_arr.num = self._n_set

    def step(self, dt: float) -> None:
        """One pymunk step of ``dt`` [s] through the C call (the caller ran ``Space.step`` once
        after adding bodies, which lets pymunk check them)."""
        self._space_step(self._cspace, dt)
