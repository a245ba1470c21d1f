"""Every array layout shared by the model, the force kernel and the world (column indices).

One home for the indices: :meth:`omni_gym.physics.model.SimModel.kernel_params` writes ``sp``/``wp``,
:mod:`omni_gym.physics.kernel` reads them and reads/writes ``wheels``, and
:class:`omni_gym.physics.world.World` and the environments read single fields by these names, never
by literal offsets. Units are those of the field: SI (kg, kg·m², m, s, rad, N), body frame for
positions and directions.
"""

from __future__ import annotations

# Per-robot scalar parameter vector ``sp`` (B, N_SP), written by SimModel.kernel_params:
# mass [kg], inertia [kg·m²], friction stiffness k [s/m], kinetic/static ratio, Stribeck speed v_s
# [m/s], roller pitch [rad], gap width [rad], centre of mass x, y [m] (body frame), motor lag tau [s],
SP_MASS, SP_INERTIA, SP_K, SP_KIN_RATIO, SP_VS, SP_PITCH, SP_GAP, SP_CX, SP_CY, SP_TAU = range(10)
# actuation mode (index in ACTUATIONS), servo kp, ki, torque limit [N·m], wheel inertia [kg·m²].
SP_MODE, SP_KP, SP_KI, SP_TMAX, SP_JW = range(10, 15)
N_SP = 15
# Per-wheel parameter rows ``wp`` (B, n, N_WP): position x, y [m] and drive direction (body frame),
# radius [m], friction coefficients along the roller axis u and the free direction f (for an omni
# wheel: drive and transverse), gap coefficients, roller phase [rad],
WP_PX, WP_PY, WP_DX, WP_DY, WP_R, WP_MUW, WP_MUT, WP_GAPW, WP_GAPT, WP_PHASE = range(10)
# cos γ and sin γ of the roller angle γ (1 and 0 for an omni wheel; u = cos γ d + sin γ z × d).
WP_COSG, WP_SING = 10, 11
N_WP = 12
# Per-wheel state rows ``wheels`` (B, n, N_WH): angle [rad], speed [rad/s], command [rad/s],
# servo integral [rad], normal load [N], and the kernel's memo of the rigid-material measure: the
# roller angle θ + phase [rad] at the end of the last substep and the rigid angle [rad] swept from 0
# to it (NaN angle: no memo). The next substep starts at that same angle, so it reuses the value
# instead of recomputing it (same input, same bits).
WH_ANGLE, WH_SPEED, WH_CMD, WH_INT, WH_LOAD, WH_GAP_AT, WH_GAP_MEASURE = range(7)
N_WH = 7
# Columns of ``BodyBatch.c_table`` (int64, :mod:`omni_gym.physics.pymunk_batch`): the space, the C
# functions cpSpaceEachBody and cpSpaceStep, pymunk's batched get/set iterators and their requests,
# the addresses of the three int32 element counts to reset before each batched call, the float count
# of a full write, and the addresses of the float64 arrays behind ``BodyBatch.states``/``forces``.
(C_SPACE, C_EACH_BODY, C_STEP, C_GET_ITER, C_GET_REQ, C_SET_ITER, C_SET_REQ, C_GET_NUM, C_GET_INT_NUM,
 C_SET_NUM, C_N_SET, C_STATES, C_FORCES) = range(13)
N_C = 13
