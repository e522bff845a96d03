"""Compiled kernels for one pose at a time and for blocks of configurations (numba).

Imported only by ``kinematics.fast``, which loads this module on first use and falls back to
the numpy code when numba is missing or switched off. Each kernel mirrors a batched numpy
function of the library (named in its docstring) and the tests hold the two to 1e-9.

The chain layout (built by ``kinematics.fast.chain_of``): every model, whatever its
convention, is written as ``T_world_tool = C[0] M_0(x_0) C[1] M_1(x_1) ... M_{n-1} C[n]``
with constant rigid ``C[k]`` (the upper ``(3, 4)`` rows) and ``x_i = q_i + offset_i``; the
joint motion ``M_i`` is ``RotZ(x_i)`` for a revolute joint and ``TransZ(x_i)`` for a
prismatic one. Joint ``i`` moves about the z axis of the frame just before ``M_i``.

A pose being built is kept as the rows of a ``(3, 4)`` (or the upper rows of a ``(4, 4)``)
array; ``T @ A`` only mixes the entries of one row, so products are done in place row by row.
All kernels are compiled with numpy's error model (a division by zero gives inf or NaN, as in
numpy) and ``cache=True`` (compiled once per machine, then loaded from ``__pycache__``).
"""

from __future__ import annotations

import math

import numpy as np
from numba import njit

_JIT = {"cache": True, "nogil": True, "error_model": "numpy", "boundscheck": False}

#: Residuals below which a closed-form branch counts (``ik.result.BRANCH_*_TOL``).
BRANCH_POSITION_TOL = 1e-4
BRANCH_ROTATION_TOL = 1e-7
#: ``ik._wrist.WRIST_SINGULAR_TOL``.
WRIST_SINGULAR_TOL = 1e-9
#: ``ik.numeric.WEIGHT_OFF_COST``.
WEIGHT_OFF_COST = 1e-6
#: ``ik.pile_driver.SINGULAR_SWEEP``.
SINGULAR_SWEEP = 360


# ---- chain --------------------------------------------------------------------------------
@njit(**_JIT)
def _set_rows(T, C, k):
    for r in range(3):
        for c in range(4):
            T[r, c] = C[k, r, c]


@njit(**_JIT)
def _move(T, prismatic, x):
    """``T = T @ M(x)``: RotZ(x) or TransZ(x)."""
    if prismatic:
        for r in range(3):
            T[r, 3] += x * T[r, 2]
    else:
        c = math.cos(x)
        s = math.sin(x)
        for r in range(3):
            a = T[r, 0]
            b = T[r, 1]
            T[r, 0] = c * a + s * b
            T[r, 1] = c * b - s * a


@njit(**_JIT)
def _times(T, C, k):
    """``T = T @ C[k]`` in place (each row of the product needs only its own row)."""
    for r in range(3):
        x = T[r, 0]
        y = T[r, 1]
        z = T[r, 2]
        p = T[r, 3]
        for c in range(3):
            T[r, c] = x * C[k, 0, c] + y * C[k, 1, c] + z * C[k, 2, c]
        T[r, 3] = x * C[k, 0, 3] + y * C[k, 1, 3] + z * C[k, 2, 3] + p


@njit(**_JIT)
def _last_row(T):
    T[3, 0] = 0.0
    T[3, 1] = 0.0
    T[3, 2] = 0.0
    T[3, 3] = 1.0


@njit(**_JIT)
def fk_pose(C, prismatic, offset, q, out):
    """``fk`` of one configuration ``q (n,)`` into ``out (4, 4)``."""
    _set_rows(out, C, 0)
    for i in range(q.shape[0]):
        _move(out, prismatic[i], q[i] + offset[i])
        _times(out, C, i + 1)
    _last_row(out)


@njit(**_JIT)
def fk_rows(C, prismatic, offset, Q, out):
    """``fk`` of ``Q (N, n)`` into ``out (N, 4, 4)``, one configuration at a time."""
    for k in range(Q.shape[0]):
        fk_pose(C, prismatic, offset, Q[k], out[k])


@njit(**_JIT)
def _turn_pass(co, si, X, Y, Z, P, a):
    """One row of the block: ``[X Y Z P] = [X Y Z P] @ RotZ @ A`` for every configuration."""
    a00, a01, a02, a03 = a[0, 0], a[0, 1], a[0, 2], a[0, 3]
    a10, a11, a12, a13 = a[1, 0], a[1, 1], a[1, 2], a[1, 3]
    a20, a21, a22, a23 = a[2, 0], a[2, 1], a[2, 2], a[2, 3]
    for k in range(X.shape[0]):
        c = co[k]
        s = si[k]
        x0 = X[k]
        y0 = Y[k]
        x = c * x0 + s * y0
        y = c * y0 - s * x0
        z = Z[k]
        X[k] = x * a00 + y * a10 + z * a20
        Y[k] = x * a01 + y * a11 + z * a21
        Z[k] = x * a02 + y * a12 + z * a22
        P[k] = x * a03 + y * a13 + z * a23 + P[k]


@njit(**_JIT)
def _slide_pass(d, X, Y, Z, P, a):
    """One row of the block: ``[X Y Z P] = [X Y Z P] @ TransZ(d) @ A``."""
    a00, a01, a02, a03 = a[0, 0], a[0, 1], a[0, 2], a[0, 3]
    a10, a11, a12, a13 = a[1, 0], a[1, 1], a[1, 2], a[1, 3]
    a20, a21, a22, a23 = a[2, 0], a[2, 1], a[2, 2], a[2, 3]
    for k in range(X.shape[0]):
        x = X[k]
        y = Y[k]
        z = Z[k]
        p = P[k] + d[k] * z
        X[k] = x * a00 + y * a10 + z * a20
        Y[k] = x * a01 + y * a11 + z * a21
        Z[k] = x * a02 + y * a12 + z * a22
        P[k] = x * a03 + y * a13 + z * a23 + p


@njit(**_JIT)
def _half_angle(t, co, si):
    """cos and sin from ``t = tan(x / 2)``, as ``fk.cos_sin`` (vectorised loop)."""
    for k in range(t.shape[0]):
        tk = t[k]
        t2 = tk * tk
        inv = 1.0 / (1.0 + t2)
        co[k] = (1.0 - t2) * inv
        si[k] = 2.0 * tk * inv


@njit(**_JIT)
def fk_block(C, prismatic, x, t, out, start, S, co, si):
    """``fk`` of a block of ``B`` configurations, structure of arrays.

    ``x (n, B)``: joint motions ``q + offset``; ``t (n, B)``: ``tan(x / 2)`` (numpy's SIMD
    ``tan``; only read for revolute joints); rows ``start .. start + B`` of ``out (N, 4, 4)``
    are written. ``S (12, >= B)``, ``co``, ``si (>= B)``: scratch. Every joint is a few
    contiguous passes over the block, which the compiler vectorises.
    """
    n = x.shape[0]
    B = x.shape[1]
    for r in range(3):
        for c in range(4):
            v = C[0, r, c]
            row = S[4 * r + c]
            for k in range(B):
                row[k] = v
    for i in range(n):
        A = C[i + 1]
        if prismatic[i]:
            for r in range(3):
                _slide_pass(x[i], S[4 * r, :B], S[4 * r + 1, :B], S[4 * r + 2, :B],
                            S[4 * r + 3, :B], A)
        else:
            _half_angle(t[i], co, si)
            for r in range(3):
                _turn_pass(co, si, S[4 * r, :B], S[4 * r + 1, :B], S[4 * r + 2, :B],
                           S[4 * r + 3, :B], A)
    flat = out.reshape(out.shape[0], 16)
    for k in range(B):
        o = flat[start + k]
        for j in range(12):
            o[j] = S[j, k]
        o[12] = 0.0
        o[13] = 0.0
        o[14] = 0.0
        o[15] = 1.0


@njit(**_JIT)
def jacobian_pose(C, prismatic, offset, q, J, T):
    """``jacobian_and_pose`` of one configuration: ``J (6, n)`` (rows v then ω, world
    frame) and the tool pose ``T (4, 4)``."""
    n = q.shape[0]
    _set_rows(T, C, 0)
    for i in range(n):
        # The frame before joint i's motion: z is its axis, the origin a point on it (held
        # in J until the tool point is known).
        for r in range(3):
            J[3 + r, i] = T[r, 2]
            J[r, i] = T[r, 3]
        _move(T, prismatic[i], q[i] + offset[i])
        _times(T, C, i + 1)
    _last_row(T)
    px, py, pz = T[0, 3], T[1, 3], T[2, 3]
    for i in range(n):
        zx, zy, zz = J[3, i], J[4, i], J[5, i]
        if prismatic[i]:
            J[0, i], J[1, i], J[2, i] = zx, zy, zz
            J[3, i], J[4, i], J[5, i] = 0.0, 0.0, 0.0
        else:
            rx = px - J[0, i]
            ry = py - J[1, i]
            rz = pz - J[2, i]
            J[0, i] = zy * rz - zz * ry
            J[1, i] = zz * rx - zx * rz
            J[2, i] = zx * ry - zy * rx


@njit(**_JIT)
def jacobian_rows(C, prismatic, offset, Q, J, T):
    """``jacobian_and_pose`` of ``Q (N, n)``: ``J (N, 6, n)``, ``T (N, 4, 4)``."""
    for k in range(Q.shape[0]):
        jacobian_pose(C, prismatic, offset, Q[k], J[k], T[k])


# ---- rotations ----------------------------------------------------------------------------
@njit(**_JIT)
def _angle_of(R):
    """``transforms.rotation_angle`` of a ``(>= 3, >= 3)`` rotation."""
    wx = R[2, 1] - R[1, 2]
    wy = R[0, 2] - R[2, 0]
    wz = R[1, 0] - R[0, 1]
    cos = (R[0, 0] + R[1, 1] + R[2, 2] - 1.0) / 2.0
    return math.atan2(math.sqrt(wx * wx + wy * wy + wz * wz) / 2.0, cos)


@njit(**_JIT)
def _log_of(R, out, k):
    """``transforms.rotation_log`` of ``R`` into ``out[k : k + 3]``."""
    wx = 0.5 * (R[2, 1] - R[1, 2])
    wy = 0.5 * (R[0, 2] - R[2, 0])
    wz = 0.5 * (R[1, 0] - R[0, 1])
    angle = _angle_of(R)
    s = math.sin(angle)
    scale = 1.0 + angle * angle / 6.0 if s < 1e-9 else angle / s
    out[k] = wx * scale
    out[k + 1] = wy * scale
    out[k + 2] = wz * scale
    if angle > math.pi - 1e-6:
        # Near pi the antisymmetric part vanishes: the axis comes from the symmetric part.
        col = 0
        for j in (1, 2):
            if R[j, j] > R[col, col]:
                col = j
        ax = np.empty(3)
        for r in range(3):
            ax[r] = (R[r, col] + (1.0 if r == col else 0.0)) / 2.0
        norm = math.sqrt(ax[0] * ax[0] + ax[1] * ax[1] + ax[2] * ax[2])
        dot = (ax[0] * wx + ax[1] * wy + ax[2] * wz) / norm
        sign = -1.0 if dot < 0.0 else 1.0
        for r in range(3):
            out[k + r] = ax[r] / norm * (sign * angle)


@njit(**_JIT)
def _pose_errors(T, G, M):
    """``transforms.pose_errors(T, G)``: position (mm) and rotation (rad) errors. ``M``:
    scratch ``(3, 3)``."""
    dx = T[0, 3] - G[0, 3]
    dy = T[1, 3] - G[1, 3]
    dz = T[2, 3] - G[2, 3]
    for r in range(3):
        for c in range(3):
            M[r, c] = T[0, r] * G[0, c] + T[1, r] * G[1, c] + T[2, r] * G[2, c]
    return math.sqrt(dx * dx + dy * dy + dz * dz), _angle_of(M)


# ---- numeric IK ---------------------------------------------------------------------------
@njit(**_JIT)
def _task_error(T, G, L, e, M):
    """``ik.numeric._error``: ``e (6,)`` = position error / L, then ``log(R_G R_T^T)``."""
    for r in range(3):
        e[r] = (G[r, 3] - T[r, 3]) / L
    for r in range(3):
        for c in range(3):
            M[r, c] = G[r, 0] * T[c, 0] + G[r, 1] * T[c, 1] + G[r, 2] * T[c, 2]
    _log_of(M, e, 3)
    s = 0.0
    for r in range(6):
        s += e[r] * e[r]
    return s


@njit(**_JIT)
def _solve6(A, b, y):
    """``y = A^-1 b`` for ``A (6, 6)`` (overwritten) by LU with partial pivoting, as
    ``numpy.linalg.solve``; a zero pivot gives NaN (the step is then rejected)."""
    m = 6
    for r in range(m):
        y[r] = b[r]
    for c in range(m):
        p = c
        big = abs(A[c, c])
        for r in range(c + 1, m):
            if abs(A[r, c]) > big:
                big = abs(A[r, c])
                p = r
        if p != c:
            for k in range(m):
                A[c, k], A[p, k] = A[p, k], A[c, k]
            y[c], y[p] = y[p], y[c]
        piv = A[c, c]
        for r in range(c + 1, m):
            f = A[r, c] / piv
            if f != 0.0:
                for k in range(c + 1, m):
                    A[r, k] -= f * A[c, k]
                y[r] -= f * y[c]
    for r in range(m - 1, -1, -1):
        s = y[r]
        for k in range(r + 1, m):
            s -= A[r, k] * y[k]
        y[r] = s / A[r, r]


@njit(**_JIT)
def _dls_step(Jn, winv, e, lam, dq, A, y):
    """``ik.numeric._step``: ``dq = W^-1 J^T (J W^-1 J^T + lam I)^-1 e``."""
    n = Jn.shape[1]
    for r in range(6):
        for c in range(r, 6):
            s = 0.0
            for k in range(n):
                s += Jn[r, k] * winv[k] * Jn[c, k]
            A[r, c] = s
            A[c, r] = s
        A[r, r] += lam
    _solve6(A, e, y)
    for k in range(n):
        s = 0.0
        for r in range(6):
            s += Jn[r, k] * y[r]
        dq[k] = winv[k] * s


@njit(**_JIT)
def _limit_gradient_abs(q, lower, upper, out):
    """``|ik.numeric.limit_gradient(q)|`` per joint."""
    n = q.shape[0]
    for i in range(n):
        span = upper[i] - lower[i]
        g = (span * span * (2.0 * q[i] - upper[i] - lower[i])) / (
            n * (upper[i] - q[i]) ** 2 * (q[i] - lower[i]) ** 2
        )
        out[i] = abs(g)


@njit(**_JIT)
def _lm(C, prismatic, offset, lower, upper, lo, hi, L, G, q, tol_p, tol_r, max_iterations,
        lambda0, weighted):
    """``ik.numeric._run`` for one start ``q (n,)`` (updated in place) towards ``G (4, 4)``.

    Same steps, damping schedule and stopping rules: weighted damped least squares, the
    limit weights switched off near the answer and for one more go after a weighted stall,
    joints pinned at a limit and pushed outwards taken out of the step. Returns the final
    position (mm) and rotation (rad) errors.
    """
    n = q.shape[0]
    J = np.empty((6, n))
    Jn = np.empty((6, n))
    T = np.empty((4, 4))
    T_new = np.empty((4, 4))
    e = np.empty(6)
    e_new = np.empty(6)
    q_new = np.empty(n)
    grad = np.empty(n)
    grad_prev = np.empty(n)
    winv = np.empty(n)
    dq = np.empty(n)
    A = np.empty((6, 6))
    y = np.empty(6)
    M = np.empty((3, 3))
    for i in range(n):
        q[i] = min(max(q[i], lo[i]), hi[i])
    jacobian_pose(C, prismatic, offset, q, J, T)
    cost = _task_error(T, G, L, e, M)
    lam = lambda0
    _limit_gradient_abs(q, lower, upper, grad_prev)
    dp, dr = _pose_errors(T, G, M)
    if dp < tol_p and dr < tol_r:
        return dp, dr
    for _ in range(max_iterations):
        for r in range(6):
            s = 1.0 / L if r < 3 else 1.0
            for k in range(n):
                Jn[r, k] = J[r, k] * s
        _limit_gradient_abs(q, lower, upper, grad)
        # Near the answer the weights only slow the final Gauss-Newton steps: drop them there.
        use_w = weighted and cost > WEIGHT_OFF_COST
        for k in range(n):
            winv[k] = 1.0 / (1.0 + grad[k]) if (use_w and grad[k] >= grad_prev[k]) else 1.0
            grad_prev[k] = grad[k]
        _dls_step(Jn, winv, e, lam, dq, A, y)
        # A joint pinned at a limit and pushed further out leaves the step (projected step).
        blocked = False
        for k in range(n):
            if (q[k] <= lo[k] and dq[k] < 0.0) or (q[k] >= hi[k] and dq[k] > 0.0):
                blocked = True
        if blocked:
            for k in range(n):
                if (q[k] <= lo[k] and dq[k] < 0.0) or (q[k] >= hi[k] and dq[k] > 0.0):
                    winv[k] = 0.0
            _dls_step(Jn, winv, e, lam, dq, A, y)
        for k in range(n):
            q_new[k] = min(max(q[k] + dq[k], lo[k]), hi[k])
        jacobian_pose(C, prismatic, offset, q_new, Jn, T_new)
        cost_new = _task_error(T_new, G, L, e_new, M)
        if cost_new < cost:
            for k in range(n):
                q[k] = q_new[k]
                for r in range(6):
                    J[r, k] = Jn[r, k]
            for r in range(4):
                for c in range(4):
                    T[r, c] = T_new[r, c]
            for r in range(6):
                e[r] = e_new[r]
            cost = cost_new
            lam = max(lam * 0.2, 1e-12)
        else:
            lam *= 8.0
        dp, dr = _pose_errors(T, G, M)
        if dp < tol_p and dr < tol_r:
            break
        if lam > 1e6:
            if not weighted:
                break
            # The weights can hold a joint back from a solution close to its limit: one more
            # go without them.
            weighted = False
            lam = lambda0
    return dp, dr


@njit(**_JIT)
def ik_starts(C, prismatic, offset, lower, upper, lo, hi, L, G, starts, tol_p, tol_r,
              max_iterations, lambda0, weighted, stop_first, q_out, err_out):
    """Run ``_lm`` from each row of ``starts (S, n)`` in turn; final joints in ``q_out (S, n)``
    and errors in ``err_out (S, 2)`` (NaN for starts never run). Returns the index of the
    first start that converged (the run stops there if ``stop_first``), or -1."""
    first = -1
    for k in range(starts.shape[0]):
        err_out[k, 0] = np.nan
        err_out[k, 1] = np.nan
    for k in range(starts.shape[0]):
        for i in range(starts.shape[1]):
            q_out[k, i] = starts[k, i]
        dp, dr = _lm(C, prismatic, offset, lower, upper, lo, hi, L, G, q_out[k], tol_p, tol_r,
                     max_iterations, lambda0, weighted)
        err_out[k, 0] = dp
        err_out[k, 1] = dr
        if dp < tol_p and dr < tol_r and first < 0:
            first = k
            if stop_first:
                break
    return first


@njit(**_JIT)
def nearest_rows(table_f, G, L, weight, k):
    """Indices of the ``k`` rows of the seed-table features ``table_f (S, 12)`` nearest to
    the features of ``G`` (``ik.numeric._features``), nearest first."""
    f = np.empty(12)
    for r in range(3):
        f[r] = weight * G[r, 3] / L
    for r in range(3):
        for c in range(3):
            f[3 + 3 * r + c] = G[r, c]
    S = table_f.shape[0]
    best_d = np.full(k, np.inf)
    best_i = np.zeros(k, dtype=np.int64)
    for s in range(S):
        d = 0.0
        for j in range(3):
            t = table_f[s, j] - f[j]
            d += t * t
        if d >= best_d[k - 1]:  # the position part alone rules this sample out
            continue
        for j in range(3, 12):
            t = table_f[s, j] - f[j]
            d += t * t
        if d < best_d[k - 1]:
            m = k - 1
            while m > 0 and best_d[m - 1] > d:
                best_d[m] = best_d[m - 1]
                best_i[m] = best_i[m - 1]
                m -= 1
            best_d[m] = d
            best_i[m] = s
    return best_i


# ---- targets ------------------------------------------------------------------------------
@njit(**_JIT)
def prepare_pose(T, far, out):
    """``ik.prepare_targets`` for one pose: returns -1.0 if ``T`` has a non-finite entry,
    -2.0 if a coordinate exceeds ``far``, else its rigidity error
    (``transforms.rigidity_error``), with the nearest rigid pose in ``out``
    (``transforms.project_to_rigid``; the polar factor by Newton's iteration, which for the
    near-rotations accepted here equals the SVD's answer)."""
    for r in range(4):
        for c in range(4):
            if not math.isfinite(T[r, c]):
                return -1.0
    for r in range(3):
        if abs(T[r, 3]) > far:
            return -2.0
    ortho = 0.0
    for r in range(3):
        for c in range(3):
            s = T[0, r] * T[0, c] + T[1, r] * T[1, c] + T[2, r] * T[2, c]
            ortho = max(ortho, abs(s - (1.0 if r == c else 0.0)))
    det = (T[0, 0] * (T[1, 1] * T[2, 2] - T[1, 2] * T[2, 1])
           - T[0, 1] * (T[1, 0] * T[2, 2] - T[1, 2] * T[2, 0])
           + T[0, 2] * (T[1, 0] * T[2, 1] - T[1, 1] * T[2, 0]))
    row = max(abs(T[3, 0]), abs(T[3, 1]), abs(T[3, 2]), abs(T[3, 3] - 1.0))
    err = max(ortho, abs(det - 1.0), row)
    X = np.empty((3, 3))
    Y = np.empty((3, 3))
    for r in range(3):
        for c in range(3):
            X[r, c] = T[r, c]
    if err > 0.0 and det > 0.0:
        # Newton's iteration for the polar factor: X <- (X + X^-T) / 2.
        for _ in range(30):
            d = (X[0, 0] * (X[1, 1] * X[2, 2] - X[1, 2] * X[2, 1])
                 - X[0, 1] * (X[1, 0] * X[2, 2] - X[1, 2] * X[2, 0])
                 + X[0, 2] * (X[1, 0] * X[2, 1] - X[1, 1] * X[2, 0]))
            # X^-T is the cofactor matrix over the determinant.
            change = 0.0
            for r in range(3):
                r1 = (r + 1) % 3
                r2 = (r + 2) % 3
                for c in range(3):
                    c1 = (c + 1) % 3
                    c2 = (c + 2) % 3
                    cof = X[r1, c1] * X[r2, c2] - X[r1, c2] * X[r2, c1]
                    Y[r, c] = 0.5 * (X[r, c] + cof / d)
            for r in range(3):
                for c in range(3):
                    change = max(change, abs(Y[r, c] - X[r, c]))
                    X[r, c] = Y[r, c]
            if change < 1e-15:
                break
    for r in range(3):
        for c in range(3):
            out[r, c] = X[r, c]
        out[r, 3] = T[r, 3]
    _last_row(out)
    return err


# ---- closed forms -------------------------------------------------------------------------
@njit(**_JIT)
def _reduce(pre_inv, T, tool_inv, G):
    """``ik._wrist.reduce_targets`` for one pose: ``G = (pre_inv @ T) @ tool_inv``."""
    H = np.empty((4, 4))
    for r in range(4):
        for c in range(4):
            H[r, c] = (pre_inv[r, 0] * T[0, c] + pre_inv[r, 1] * T[1, c]
                       + pre_inv[r, 2] * T[2, c] + pre_inv[r, 3] * T[3, c])
    for r in range(4):
        for c in range(4):
            G[r, c] = (H[r, 0] * tool_inv[0, c] + H[r, 1] * tool_inv[1, c]
                       + H[r, 2] * tool_inv[2, c] + H[r, 3] * tool_inv[3, c])


@njit(**_JIT)
def _less_offsets(rows, off):
    for r in range(rows.shape[0]):
        for i in range(rows.shape[1]):
            rows[r, i] -= off[i]


@njit(**_JIT)
def _mat3(A, B, out):
    for r in range(3):
        for c in range(3):
            out[r, c] = A[r, 0] * B[0, c] + A[r, 1] * B[1, c] + A[r, 2] * B[2, c]


@njit(**_JIT)
def _rz(theta, out):
    c = math.cos(theta)
    s = math.sin(theta)
    out[0, 0], out[0, 1], out[0, 2] = c, -s, 0.0
    out[1, 0], out[1, 1], out[1, 2] = s, c, 0.0
    out[2, 0], out[2, 1], out[2, 2] = 0.0, 0.0, 1.0


@njit(**_JIT)
def _clip_unit(x):
    """A cosine from a formula: NaN beyond 1 + 1e-12 in size, else clipped to [-1, 1]."""
    if math.isnan(x) or abs(x) > 1 + 1e-12:
        return np.nan
    return min(max(x, -1.0), 1.0)


@njit(**_JIT)
def _wrist_angles(M, rx_ab, sa, cb, hint, out, row):
    """``ik._wrist.wrist_angles`` for one ``M (3, 3)``: writes the two branches' three angles
    into ``out[row]`` and ``out[row + 1]`` (columns 3, 4, 5); returns whether singular.
    ``rx_ab = RotX(-(alpha_a + alpha_b))``."""
    Mp = np.empty((3, 3))
    _mat3(M, rx_ab, Mp)
    sb_abs = math.hypot(Mp[0, 2], Mp[1, 2])
    singular = sb_abs < WRIST_SINGULAR_TOL
    for j in range(2):
        sign = 1.0 if j == 0 else -1.0
        if singular:
            up = Mp[2, 2] > 0
            b = 0.0 if up else math.pi
            a = hint
            if up:
                c = math.atan2(Mp[1, 0], Mp[0, 0]) - hint
            else:
                c = hint - math.atan2(-Mp[1, 0], -Mp[0, 0])
        else:
            sb = sb_abs * sign
            b = math.atan2(sb, Mp[2, 2])
            a = math.atan2(Mp[1, 2] / sb, Mp[0, 2] / sb)
            c = math.atan2(Mp[2, 1] / sb, -Mp[2, 0] / sb)
        out[row + j, 3] = a
        out[row + j, 4] = -sa * b
        out[row + j, 5] = cb * c
    return singular


@njit(**_JIT)
def wrist_branches(p, rx_a1, rx_m3, rx_ab, pre_inv, tool_inv, off, T, hint0, hint3, diag):
    """``ik.spherical_wrist.solve``'s branches for one target: ``(8, 6)`` joint values
    (offsets ``off`` subtracted), NaN rows where a branch does not exist.

    ``p``: the model's constants (see ``kinematics.fast``); ``rx_*``: constant rotations.
    ``diag`` receives [singular, too_close, R_xy, all K NaN, |(X0, Y0)|].
    """
    sa1, a1, a2, d1, rho = p[0], p[1], p[2], p[3], p[4]
    psi, w3x, w3y, e = p[5], p[6], p[7], p[8]
    G = np.empty((4, 4))
    _reduce(pre_inv, T, tool_inv, G)
    Px, Py, Pz = G[0, 3], G[1, 3], G[2, 3]
    out = np.full((8, 6), np.nan)
    R_xy = math.hypot(Px, Py)
    on_axis = R_xy < 1e-9
    too_close = R_xy < abs(e) - 1e-9
    asin = math.asin(min(max(e / (1.0 if on_axis else R_xy), -1.0), 1.0))
    phi = math.atan2(Py, Px)
    t1s = (phi - asin, phi - math.pi + asin)
    singular = on_axis
    all_nan = True
    X0 = np.nan
    Y0 = np.nan
    R03 = np.empty((3, 3))
    W = np.empty((3, 3))
    V = np.empty((3, 3))
    Mw = np.empty((3, 3))
    for s in range(2):
        t1 = hint0 if on_axis else t1s[s]
        if too_close:
            t1 = np.nan
        X = math.cos(t1) * Px + math.sin(t1) * Py - a1
        Y = (Pz - d1) / sa1
        if s == 0:
            X0 = X
            Y0 = Y
        K = (X * X + Y * Y - a2 * a2 - rho * rho) / (2 * a2 * rho)
        K = _clip_unit(K)
        if not math.isnan(K):
            all_nan = False
        acK = math.acos(K) if not math.isnan(K) else np.nan
        for el in range(2):
            t3 = -psi + (1.0 if el == 0 else -1.0) * acK
            u = a2 + math.cos(t3) * w3x - math.sin(t3) * w3y
            v = math.sin(t3) * w3x + math.cos(t3) * w3y
            t2 = math.atan2(Y, X) - math.atan2(v, u)
            # R03 = Rz(t1) RotX(alpha1) Rz(t2 + t3); M = (RotX(-alpha3) R03^T) G_R.
            _rz(t1, W)
            _mat3(W, rx_a1, V)
            _rz(t2 + t3, W)
            _mat3(V, W, R03)
            for r in range(3):
                for c in range(3):
                    V[r, c] = R03[c, r]
            _mat3(rx_m3, V, W)
            _mat3(W, G, Mw)
            row = 4 * s + 2 * el
            if _wrist_angles(Mw, rx_ab, p[9], p[10], hint3, out, row):
                singular = True
            for j in range(2):
                out[row + j, 0] = t1
                out[row + j, 1] = t2
                out[row + j, 2] = t3
    diag[0] = 1.0 if singular else 0.0
    diag[1] = 1.0 if too_close else 0.0
    diag[2] = R_xy
    diag[3] = 1.0 if all_nan else 0.0
    diag[4] = math.hypot(X0, Y0)
    _less_offsets(out, off)
    return out


@njit(**_JIT)
def pile_branches(p, rx_m1, rx_ab, pre_inv, tool_inv, off, T, hint0, hint234, diag):
    """``ik.pile_driver.solve``'s branches for one target (see there), offsets ``off``
    subtracted; ``diag`` receives [singular, all c3 NaN, smallest stick-tip reach]."""
    sa1, L1, L2, L3, d1, w4x, w4y, cb = p[0], p[1], p[2], p[3], p[4], p[5], p[6], p[7]
    G = np.empty((4, 4))
    _reduce(pre_inv, T, tool_inv, G)
    px, py, pz = G[0, 3], G[1, 3], G[2, 3]
    on_axis = math.hypot(px, py) < 1e-9
    base = math.atan2(py, px)
    # Candidates (t1, t234, t5, t6): 2 shoulders x 2 wrist branches, then the sweep.
    wsing = np.zeros(2, dtype=np.bool_)
    cand0 = np.empty((4, 6))
    W = np.empty((3, 3))
    V = np.empty((3, 3))
    N = np.empty((3, 3))
    for s in range(2):
        t1 = hint0 if on_axis else base + (0.0 if s == 0 else math.pi)
        _rz(t1, W)
        for r in range(3):
            for c in range(3):
                V[r, c] = W[c, r]
        _mat3(rx_m1, V, W)
        _mat3(W, G, N)
        wsing[s] = _wrist_angles(N, rx_ab, p[8], cb, hint234, cand0, 2 * s)
        for j in range(2):
            cand0[2 * s + j, 0] = t1
    n_sing = 0
    for s in range(2):
        if wsing[s]:
            n_sing += 2
    n_cand = 4 + n_sing * (SINGULAR_SWEEP + 1)
    cand = np.empty((n_cand, 4))
    for k in range(4):
        cand[k, 0] = cand0[k, 0]
        cand[k, 1] = cand0[k, 3]
        cand[k, 2] = cand0[k, 4]
        cand[k, 3] = cand0[k, 5]
    m = 4
    for k in range(4):
        if not wsing[k // 2]:
            continue
        for j in range(SINGULAR_SWEEP + 1):
            shift = 0.0 if j == 0 else -math.pi + (j - 1) * (2 * math.pi / SINGULAR_SWEEP)
            cand[m, 0] = cand[k, 0]
            cand[m, 1] = cand[k, 1] + shift
            cand[m, 2] = cand[k, 2]
            cand[m, 3] = cand[k, 3] - cb * shift
            m += 1
    out = np.empty((2 * n_cand, 6))
    all_nan = True
    min_reach = np.inf
    for k in range(n_cand):
        c1 = math.cos(cand[k, 0])
        s1 = math.sin(cand[k, 0])
        c234 = math.cos(cand[k, 1])
        s234 = math.sin(cand[k, 1])
        k1 = c1 * px + s1 * py - L1 - (c234 * w4x - s234 * w4y)
        k2 = (pz - d1) / sa1 - (s234 * w4x + c234 * w4y)
        min_reach = min(min_reach, math.hypot(k1, k2))
        c3 = (k1 * k1 + k2 * k2 - L2 * L2 - L3 * L3) / (2 * L2 * L3)
        c3 = _clip_unit(c3)
        if not math.isnan(c3):
            all_nan = False
        root = math.sqrt(1.0 - c3 * c3)
        for el in range(2):
            s3 = root if el == 0 else -root
            t3 = math.atan2(s3, c3)
            t2 = math.atan2(k2, k1) - math.atan2(L3 * s3, L2 + L3 * c3)
            row = 2 * k + el
            out[row, 0] = cand[k, 0]
            out[row, 1] = t2
            out[row, 2] = t3
            out[row, 3] = cand[k, 1] - t2 - t3
            out[row, 4] = cand[k, 2]
            out[row, 5] = cand[k, 3]
    diag[0] = 1.0 if (on_axis or wsing[0] or wsing[1]) else 0.0
    diag[1] = 1.0 if all_nan else 0.0
    diag[2] = min_reach
    _less_offsets(out, off)
    return out


@njit(**_JIT)
def _lex_less(K, a, b):
    for j in range(K.shape[1]):
        if K[a, j] < K[b, j]:
            return True
        if K[a, j] > K[b, j]:
            return False
    return False


@njit(**_JIT)
def _merge_sort(idx, K):
    """Stable sort of ``idx`` by ``_lex_less`` on the rows of ``K``."""
    n = idx.shape[0]
    buf = np.empty_like(idx)
    width = 1
    while width < n:
        for lo in range(0, n, 2 * width):
            mid = min(lo + width, n)
            hi = min(lo + 2 * width, n)
            i, j, k = lo, mid, lo
            while i < mid and j < hi:
                if _lex_less(K, idx[j], idx[i]):
                    buf[k] = idx[j]
                    j += 1
                else:
                    buf[k] = idx[i]
                    i += 1
                k += 1
            while i < mid:
                buf[k] = idx[i]
                i += 1
                k += 1
            while j < hi:
                buf[k] = idx[j]
                j += 1
                k += 1
        idx, buf = buf, idx
        width *= 2
    return idx


@njit(**_JIT)
def finish_branches(C, prismatic, offset, lower, upper, T, branches, q0, has_q0):
    """``ik.result.finish_analytic`` for one target: keep the branches ``(R, n)`` that FK
    puts on ``T`` (within the branch tolerances), expand them over the whole turns the limits
    allow (``expand_turns``), drop repeats to 1e-9 and order them (within limits first, then
    nearest ``q0``, then as ``numpy.unique`` sorts). Returns ``(solutions (m, n), errors
    (m, 2), inside (m,))``."""
    n = branches.shape[1]
    R = branches.shape[0]
    two_pi = 2 * math.pi
    Tq = np.empty((4, 4))
    M = np.empty((3, 3))
    kept = np.empty(R, dtype=np.int64)
    err = np.empty((R, 2))
    n_keep = 0
    for k in range(R):
        finite = True
        for i in range(n):
            if not math.isfinite(branches[k, i]):
                finite = False
        if not finite:
            continue
        fk_pose(C, prismatic, offset, branches[k], Tq)
        dp, dr = _pose_errors(Tq, T, M)
        if dp < BRANCH_POSITION_TOL and dr < BRANCH_ROTATION_TOL:
            kept[n_keep] = k
            err[n_keep, 0] = dp
            err[n_keep, 1] = dr
            n_keep += 1
    # Whole turns (expand_turns): per row and revolute joint the turns k_lo .. k_hi that land
    # inside the limits; at the first joint that no turn brings inside, the row stops
    # expanding and is kept as it is from there on.
    k_lo = np.zeros((n_keep, n))
    k_count = np.ones((n_keep, n), dtype=np.int64)
    total = 0
    for r in range(n_keep):
        count = 1
        for i in range(n):
            if prismatic[i]:
                continue
            v = branches[kept[r], i]
            lo_i = math.ceil((lower[i] - v) / two_pi - 1e-12)
            hi_i = math.floor((upper[i] - v) / two_pi + 1e-12)
            if hi_i < lo_i:
                break
            k_lo[r, i] = lo_i
            k_count[r, i] = int(hi_i - lo_i + 1)
            count *= k_count[r, i]
        total += count
    allq = np.empty((total, n))
    all_src = np.empty(total, dtype=np.int64)
    digit = np.zeros(n, dtype=np.int64)
    m = 0
    for r in range(n_keep):
        row = branches[kept[r]]
        digit[:] = 0
        while True:  # every combination of the turns, as a mixed-radix counter
            for i in range(n):
                if k_count[r, i] == 1 and k_lo[r, i] == 0.0:
                    allq[m, i] = row[i]
                else:
                    allq[m, i] = row[i] + two_pi * (k_lo[r, i] + digit[i])
            all_src[m] = r
            m += 1
            i = n - 1
            while i >= 0:
                digit[i] += 1
                if digit[i] < k_count[r, i]:
                    break
                digit[i] = 0
                i -= 1
            if i < 0:
                break
    total = allq.shape[0]
    # numpy.unique(round(q, 9), axis=0): sort the rounded rows, keep the first of each run.
    keys = np.empty((total, n))
    for r in range(total):
        for i in range(n):
            keys[r, i] = np.rint(allq[r, i] * 1e9)
    idx = _merge_sort(np.arange(total), keys)
    uniq = np.empty(total, dtype=np.int64)
    m = 0
    for r in range(total):
        if m > 0:
            same = True
            for i in range(n):
                if keys[idx[r], i] != keys[uniq[m - 1], i]:
                    same = False
                    break
            if same:
                continue
        uniq[m] = idx[r]
        m += 1
    uniq = uniq[:m]
    # Order: within limits first, then nearest q0 (stable, as numpy.lexsort).
    order_keys = np.empty((m, 2))
    inside = np.empty(m, dtype=np.bool_)
    for r in range(m):
        q = allq[uniq[r]]
        ok = True
        d = 0.0
        for i in range(n):
            if not (lower[i] - 1e-9 <= q[i] <= upper[i] + 1e-9):
                ok = False
            if has_q0:
                d += (q[i] - q0[i]) ** 2
        inside[r] = ok
        order_keys[r, 0] = 0.0 if ok else 1.0
        # To 1e-9 (as ik.result): branches as near as each other (+pi and -pi from 0) keep
        # numpy.unique's order, not the last bit of a sum.
        order_keys[r, 1] = math.floor(math.sqrt(d) * 1e9 + 0.5) / 1e9
    order = _merge_sort(np.arange(m), order_keys)
    sols = np.empty((m, n))
    errs = np.empty((m, 2))
    ins = np.empty(m, dtype=np.bool_)
    for r in range(m):
        k = uniq[order[r]]
        sols[r] = allq[k]
        errs[r, 0] = err[all_src[k], 0]
        errs[r, 1] = err[all_src[k], 1]
        ins[r] = inside[order[r]]
    return sols, errs, ins
