"""The fast path: compiled kernels for one configuration or one pose per call, and for big
FK batches.

numpy pays a fixed cost of about a microsecond per call, and FK of one configuration makes
about a hundred calls; numeric IK makes that many per iteration. For one configuration (and
for small batches), ``fk``, ``jacobian_and_pose``, ``solve_ik`` and the closed forms hand the
work to the kernels of ``kinematics._kernels``, compiled by numba; big FK batches go through
them in cache-sized blocks. Everything else (and everything, when the kernels are off) is the
batched numpy code, which the tests hold the kernels to (1e-9).

Switches: the kernels are used when numba imports and ``ENABLED`` is true; the environment
variable ``KINOPLAN_JIT=0`` (read at import) or setting ``kinematics.fast.ENABLED = False``
turns them off. numba and the compiled kernels are loaded on first use (numba's import takes
about 0.3 s); a service calls ``warm_up()`` at start-up so that no request pays for it, or
``start_warm_up()`` to prepare them in the background while the numpy path serves.
Kernels are compiled with ``cache=True``: the first process on a machine compiles them
(seconds) and stores them next to ``_kernels.py`` (or in numba's user cache directory);
later processes load them.

Chain layout shared by the kernels: every model is written as
``T_world_tool = C[0] M_0(x_0) C[1] ... M_{n-1}(x_{n-1}) C[n]`` with constant rigid ``C[k]``,
``x_i = q_i + offset_i`` and ``M_i = RotZ(x_i)`` (revolute) or ``TransZ(x_i)`` (prismatic).
For D-H models the link constants and the joint's fixed parts (``d`` of a revolute joint,
``theta`` of a prismatic one) fold into the ``C[k]``; a screw ``exp([S_i] x)`` is
``F_i M(x) F_i^-1`` for a frame ``F_i`` whose z axis is the screw axis through its point.
"""

from __future__ import annotations

import importlib
import math
import os
import threading
import time
from dataclasses import dataclass
from functools import lru_cache
from types import ModuleType

import numpy as np

from .model import RobotModel
from .transforms import invert_pose, rot_x, rot_z, trans

__all__ = [
    "ENABLED",
    "FK_BLOCK",
    "SMALL_BATCH",
    "Chain",
    "WarmUpReport",
    "c_array",
    "chain_of",
    "fk_rows",
    "jacobian_rows",
    "kernels",
    "pile_data",
    "start_warm_up",
    "warm_up",
    "wrist_data",
]

#: Whether the compiled kernels may be used (``KINOPLAN_JIT=0`` turns them off at import).
ENABLED: bool = os.environ.get("KINOPLAN_JIT", "1").strip().lower() not in {
    "0", "false", "no", "off"}
#: Batches up to this size go one configuration at a time through the scalar kernels; bigger
#: FK batches go through the block kernel.
SMALL_BATCH = 24
#: Configurations per FK block: the block's working set (12 rows of it plus the angles) stays
#: in the L2 cache whatever the batch size, so the time per configuration stays flat.
FK_BLOCK = 2048

_K: ModuleType | None = None
_unavailable = False
_warming = False  # a background warm-up is running: the numpy path serves until it is done
_lock = threading.Lock()


def kernels() -> ModuleType | None:
    """The compiled kernels (``kinematics._kernels``), or None when they are switched off,
    numba is not installed, or ``start_warm_up`` is still preparing them. The first call
    (without a warm-up) imports numba and loads the kernels it uses."""
    if not ENABLED:
        return None
    if _K is not None or _unavailable or _warming:
        return _K
    return _load()


def _import_kernels() -> ModuleType | None:
    global _unavailable
    try:
        return importlib.import_module("._kernels", __package__)
    except ImportError:
        _unavailable = True
        return None


def _load() -> ModuleType | None:
    global _K
    with _lock:
        if _K is None and not _unavailable:
            _K = _import_kernels()
    return _K


# ---- chains -------------------------------------------------------------------------------
@dataclass(frozen=True, eq=False)
class Chain:
    """A model in the kernels' layout (module docstring). Arrays are C-contiguous float64
    (``prismatic`` bool): ``C (n + 1, 3, 4)``, per joint ``(n,)`` the rest. ``lo``/``hi`` are
    the limits pulled in by 1e-9 of the range, where numeric IK keeps its iterates."""

    C: np.ndarray
    prismatic: np.ndarray
    offset: np.ndarray
    lower: np.ndarray
    upper: np.ndarray
    lo: np.ndarray
    hi: np.ndarray
    length_scale: float


def _snap(A: np.ndarray) -> np.ndarray:
    """Round-off such as cos(pi/2) = 6e-17 snapped to 0 and ±1 (as ``fk._link_constants``)."""
    for v in (0.0, 1.0, -1.0):
        A[np.abs(A - v) < 1e-15] = v
    return A


def _dh_constants(model: RobotModel) -> list[np.ndarray]:
    mdh = model.convention == "mdh"
    out = []
    left = np.array(model.base, dtype=float)
    for j in model.joints:
        A = _snap(rot_x(j.alpha) @ trans(j.a) if mdh else trans(j.a) @ rot_x(j.alpha))
        if mdh:
            left = left @ A
        if j.revolute:  # RotZ(q + offset) TransZ(d): TransZ(d) joins the next constant
            out.append(left)
            left = trans(0.0, 0.0, j.d)
        else:  # RotZ(theta) TransZ(q + offset): RotZ(theta) joins this one
            out.append(left @ _snap(rot_z(j.theta)))
            left = np.eye(4)
        if not mdh:
            left = left @ A
    out.append(left @ model.tool)
    return out


def _screw_frame(axis, point) -> np.ndarray:
    """A frame whose z axis is ``axis`` and whose origin is ``point`` (or the base origin)."""
    w = np.asarray(axis, dtype=float)
    w = w / np.linalg.norm(w)
    a = np.array([1.0, 0.0, 0.0]) if abs(w[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    x = a - (a @ w) * w
    x /= np.linalg.norm(x)
    F = np.eye(4)
    F[:3, 0], F[:3, 1], F[:3, 2] = x, np.cross(w, x), w
    if point is not None:
        F[:3, 3] = point
    return F


def _poe_constants(model: RobotModel) -> list[np.ndarray]:
    frames = [_screw_frame(j.axis, j.point if j.revolute else None) for j in model.joints]
    out = [np.asarray(model.base) @ frames[0]]
    for prev, nxt in zip(frames[:-1], frames[1:]):
        out.append(invert_pose(prev) @ nxt)
    out.append(invert_pose(frames[-1]) @ np.asarray(model.home) @ np.asarray(model.tool))
    return out


@lru_cache(maxsize=256)
def chain_of(model: RobotModel) -> Chain:
    """``model`` in the kernels' layout (built once per model)."""
    consts = _poe_constants(model) if model.convention == "poe" else _dh_constants(model)
    C = np.ascontiguousarray(np.stack(consts)[:, :3, :], dtype=float)
    lower = np.array(model.lower, dtype=float)
    upper = np.array(model.upper, dtype=float)
    margin = 1e-9 * (upper - lower)
    return Chain(
        C=C,
        prismatic=np.array([not j.revolute for j in model.joints], dtype=bool),
        offset=np.array([j.offset for j in model.joints], dtype=float),
        lower=lower,
        upper=upper,
        lo=lower + margin,
        hi=upper - margin,
        length_scale=float(model.length_scale),
    )


# ---- FK and Jacobian for (N, dof) rows ----------------------------------------------------
def c_array(a) -> np.ndarray:
    """``a`` as a C-contiguous, writable float64 array (copied only if it is not one): the one
    array type the kernels are compiled for, so no call compiles a new variant."""
    a = np.asarray(a, dtype=float)
    if a.flags.c_contiguous and a.flags.writeable:
        return a
    return np.array(a, dtype=float, order="C")


def fk_rows(K: ModuleType, model: RobotModel, q2: np.ndarray) -> np.ndarray:
    """Tool poses ``(N, 4, 4)`` of ``q2 (N, dof)`` float64 by the kernels ``K``."""
    ch = chain_of(model)
    q2 = c_array(q2)
    n = q2.shape[0]
    if n == 1:
        out = np.empty((1, 4, 4))
        K.fk_pose(ch.C, ch.prismatic, ch.offset, q2[0], out[0])
        return out
    out = np.empty((n, 4, 4))
    if n <= SMALL_BATCH:
        K.fk_rows(ch.C, ch.prismatic, ch.offset, q2, out)
        return out
    width = min(n, FK_BLOCK)
    S, co, si = np.empty((12, width)), np.empty(width), np.empty(width)
    x = np.empty((model.dof, width))
    t = np.empty((model.dof, width))
    off = ch.offset[:, None]
    for start in range(0, n, width):
        block = q2[start:start + width]
        if block.shape[0] != width:  # the last, shorter block: arrays of its own size
            x = np.empty((model.dof, block.shape[0]))
            t = np.empty((model.dof, block.shape[0]))
        np.add(block.T, off, out=x)
        np.multiply(x, 0.5, out=t)
        np.tan(t, out=t)  # numpy's SIMD tan; the kernel turns it into cos and sin
        K.fk_block(ch.C, ch.prismatic, x, t, out, start, S, co, si)
    return out


def jacobian_rows(K: ModuleType, model: RobotModel,
                  q2: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Geometric Jacobians ``(N, 6, dof)`` and tool poses ``(N, 4, 4)`` of ``q2 (N, dof)``."""
    ch = chain_of(model)
    q2 = c_array(q2)
    n = q2.shape[0]
    J = np.empty((n, 6, model.dof))
    T = np.empty((n, 4, 4))
    if n == 1:
        K.jacobian_pose(ch.C, ch.prismatic, ch.offset, q2[0], J[0], T[0])
    else:
        K.jacobian_rows(ch.C, ch.prismatic, ch.offset, q2, J, T)
    return J, T


# ---- closed-form data ---------------------------------------------------------------------
def _rx3(angle: float) -> np.ndarray:
    return np.ascontiguousarray(rot_x(angle)[:3, :3])


def _pre_and_tool_inverse(model: RobotModel) -> tuple[np.ndarray, np.ndarray]:
    j1 = model.joints[0]
    pre = model.base @ rot_x(j1.alpha) @ trans(j1.a)
    return (np.ascontiguousarray(invert_pose(pre)),
            np.ascontiguousarray(invert_pose(model.tool)))


@lru_cache(maxsize=64)
def wrist_data(model: RobotModel) -> tuple[np.ndarray, ...]:
    """Constants of ``ik.spherical_wrist`` for ``_kernels.wrist_branches``: ``(p, RotX(alpha_1),
    RotX(-alpha_3), RotX(-(alpha_4 + alpha_5)), pre^-1, tool^-1, offsets)``."""
    j = model.joints
    w3x, w3y = j[3].a, -math.sin(j[3].alpha) * j[3].d
    sa1 = math.copysign(1.0, math.sin(j[1].alpha))
    p = np.array([
        sa1, j[1].a, j[2].a, j[0].d, math.hypot(w3x, w3y), math.atan2(w3y, w3x), w3x, w3y,
        -sa1 * (j[1].d + j[2].d),
        math.copysign(1.0, math.sin(j[4].alpha)), float(round(math.cos(j[4].alpha + j[5].alpha))),
    ])
    pre_inv, tool_inv = _pre_and_tool_inverse(model)
    off = np.array([jt.offset for jt in j], dtype=float)
    return (p, _rx3(j[1].alpha), _rx3(-j[3].alpha), _rx3(-(j[4].alpha + j[5].alpha)),
            pre_inv, tool_inv, off)


@lru_cache(maxsize=64)
def pile_data(model: RobotModel) -> tuple[np.ndarray, ...]:
    """Constants of ``ik.pile_driver`` for ``_kernels.pile_branches``: ``(p, RotX(-alpha_1),
    RotX(-(alpha_4 + alpha_5)), pre^-1, tool^-1, offsets)``."""
    j = model.joints
    p = np.array([
        math.copysign(1.0, math.sin(j[1].alpha)), j[1].a, j[2].a, j[3].a, j[0].d,
        j[4].a, -math.sin(j[4].alpha) * j[4].d, float(round(math.cos(j[4].alpha + j[5].alpha))),
        math.copysign(1.0, math.sin(j[4].alpha)),
    ])
    pre_inv, tool_inv = _pre_and_tool_inverse(model)
    off = np.array([jt.offset for jt in j], dtype=float)
    return (p, _rx3(-j[1].alpha), _rx3(-(j[4].alpha + j[5].alpha)), pre_inv, tool_inv, off)


# ---- start-up -----------------------------------------------------------------------------
@dataclass(frozen=True)
class WarmUpReport:
    """What ``warm_up`` did: ``enabled`` is False when the kernels are off or numba is
    missing (then nothing was loaded); times in seconds."""

    enabled: bool
    import_seconds: float
    kernel_seconds: float

    @property
    def total_seconds(self) -> float:
        return self.import_seconds + self.kernel_seconds


def warm_up() -> WarmUpReport:
    """Import numba and load (or, the first time on a machine, compile) every kernel, so
    that no request pays for it. Call once at service start-up; safe to call again.

    Every kernel is called once with the argument types the library's calls use (a test
    checks that the library then compiles nothing new).
    """
    t0 = time.perf_counter()
    K = kernels()
    t1 = time.perf_counter()
    if K is None:
        return WarmUpReport(False, t1 - t0, 0.0)
    _exercise(K)
    return WarmUpReport(True, t1 - t0, time.perf_counter() - t1)


def start_warm_up() -> threading.Thread | None:
    """``warm_up`` in a background thread, for a service that must answer at once even on
    a machine whose cache is cold (compiling every kernel takes tens of seconds there):
    until the kernels are ready every call takes the numpy path (same results, slower),
    then the kernels take over. Returns the thread (None when there is nothing to do)."""
    global _warming
    with _lock:
        if not ENABLED or _K is not None or _unavailable or _warming:
            return None
        _warming = True
    thread = threading.Thread(target=_warm_in_background, name="kinoplan-kernels",
                              daemon=True)
    thread.start()
    return thread


def _warm_in_background() -> None:
    global _K, _warming
    try:
        K = _import_kernels()
        if K is not None:
            _exercise(K)
            _K = K  # published only once every kernel is ready
    finally:
        _warming = False


def _exercise(K: ModuleType) -> None:
    """Call every kernel once with the argument types the library uses."""
    from .library import builtin_model

    for robot_id in ("glt_palletizer", "pile_driver"):
        model = builtin_model(robot_id)
        ch = chain_of(model)
        n = model.dof
        q = model.mid_configuration().copy()
        Q = np.tile(q, (SMALL_BATCH + 1, 1))
        fk_rows(K, model, Q[:1])
        fk_rows(K, model, Q[:2])
        fk_rows(K, model, Q)
        jacobian_rows(K, model, Q[:1])
        jacobian_rows(K, model, Q[:2])
        T = fk_rows(K, model, Q[:1])[0]
        out = np.empty((4, 4))
        K.prepare_pose(T, 1e9, out)
        starts = np.tile(q, (2, 1))
        K.ik_starts(ch.C, ch.prismatic, ch.offset, ch.lower, ch.upper, ch.lo, ch.hi,
                    ch.length_scale, T, starts, 1e-5, 1e-8, 2, 1e-2, True, True,
                    np.empty((2, n)), np.empty((2, 2)))
        K.nearest_rows(np.zeros((4, 12)), T, ch.length_scale, 3.0, 2)
        diag = np.zeros(5)
        if robot_id == "glt_palletizer":
            p, rx_a1, rx_m3, rx_ab, pre_inv, tool_inv, off = wrist_data(model)
            branches = K.wrist_branches(p, rx_a1, rx_m3, rx_ab, pre_inv, tool_inv, off, T,
                                        0.0, 0.0, diag)
        else:
            p, rx_m1, rx_ab, pre_inv, tool_inv, off = pile_data(model)
            branches = K.pile_branches(p, rx_m1, rx_ab, pre_inv, tool_inv, off, T, 0.0, 0.0,
                                       diag)
        K.finish_branches(ch.C, ch.prismatic, ch.offset, ch.lower, ch.upper, T, branches,
                          q, False)
