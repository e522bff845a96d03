"""PNG plots for reports: joint trajectories (position, velocity, acceleration, jerk, and for
hydraulic arms cylinder speeds and pump flow) and tool tracking runs (paper 003 Figure 7:
joint angles, joint speeds, error per axis, error)."""

from __future__ import annotations

import io
from typing import Any

import numpy as np

from planning.trajectories.trajectory import Samples

__all__ = ["trajectory_png", "tracking_png"]

_ROWS = (
    ("q", "position"),
    ("qd", "velocity"),
    ("qdd", "acceleration"),
    ("qddd", "jerk"),
)


def trajectory_png(
    samples: Samples,
    joint_names: list[str],
    joint_units: list[str],
    title: str = "",
    breaks: np.ndarray | None = None,
    hydraulic: dict | None = None,
) -> bytes:
    """Four stacked panels (position, velocity, acceleration, jerk) of every joint; dashed
    vertical lines at the segment joins ``breaks``. Units per joint: 'rad' or 'mm'.

    ``hydraulic`` (robots with cylinders) adds a cylinder-speed panel and, when ``flow`` is
    given, a pump-flow panel: ``{"names": [C], "speeds": (S, C) mm/s, "max_extension",
    "max_retraction": (C,) mm/s (inf: none), "flow": (S,) L/min or None, "pump_flow": L/min
    or None}``; limits are drawn dashed in each cylinder's colour."""
    unit = "/".join(sorted(set(joint_units))) or "rad"
    extra = 0 if hydraulic is None else 1 + (hydraulic.get("flow") is not None)
    rows = 4 + extra
    from matplotlib.figure import Figure  # on first use: a second of every start otherwise

    fig = Figure(figsize=(8.0, 9.0 + 2.0 * extra), dpi=100)  # no pyplot: thread-safe
    axes = fig.subplots(rows, 1, sharex=True)
    for ax, (attr, label) in zip(axes, _ROWS):
        values = getattr(samples, attr)
        for j, name in enumerate(joint_names):
            ax.plot(samples.t, values[:, j], label=f"{name} [{joint_units[j]}]", linewidth=1.2)
        suffix = {"q": "", "qd": "/s", "qdd": "/s²", "qddd": "/s³"}[attr]
        ax.set_ylabel(f"{label}\n[{unit}{suffix}]")
    if hydraulic is not None:
        _hydraulic_panels(axes[4:], samples.t, hydraulic)
    for ax in axes:
        ax.grid(True, alpha=0.3)
        if breaks is not None:
            for b in breaks[1:-1]:
                ax.axvline(b, color="0.5", linestyle="--", linewidth=0.8)
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1].set_xlabel("time [s]")
    return _png(fig, title)


def _hydraulic_panels(axes, t: np.ndarray, hydraulic: dict) -> None:
    """Cylinder speeds with their extension (+) and retraction (-) limits; pump flow."""
    ax = axes[0]
    speeds = np.asarray(hydraulic["speeds"])
    for c, name in enumerate(hydraulic["names"]):
        (line,) = ax.plot(t, speeds[:, c], label=name, linewidth=1.2)
        for lim, sign in ((hydraulic["max_extension"][c], 1.0),
                          (hydraulic["max_retraction"][c], -1.0)):
            if np.isfinite(lim):
                ax.axhline(sign * lim, color=line.get_color(), linestyle=":", linewidth=0.8)
    ax.set_ylabel("cylinder speed\n[mm/s]")
    ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    if len(axes) > 1:
        ax = axes[1]
        ax.plot(t, hydraulic["flow"], color="k", linewidth=1.2, label="flow")
        if hydraulic.get("pump_flow") is not None:
            ax.axhline(hydraulic["pump_flow"], color="0.4", linestyle="--", linewidth=0.8,
                       label=f"pump {hydraulic['pump_flow']:.3g} L/min")
        ax.set_ylabel("pump flow\n[L/min]")
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)


def tracking_png(
    t: np.ndarray,
    q: np.ndarray,
    x_desired: np.ndarray,
    x_actual: np.ndarray,
    joint_names: list[str],
    title: str = "",
    speed_limits: np.ndarray | None = None,
) -> bytes:
    """A tracking run in the four panels of paper 003's Figure 7: joint angles ``q (S, dof)``
    rad, joint speeds (differences of ``q`` over ``t (S,)`` s, with the limits dashed), the
    error desired - actual per axis and its norm (mm) from ``x_desired``, ``x_actual (S, 3)``.
    """
    t, q = np.asarray(t, dtype=float), np.asarray(q, dtype=float)
    e = np.asarray(x_desired, dtype=float) - np.asarray(x_actual, dtype=float)
    qd = np.diff(q, axis=0) / np.diff(t)[:, None]
    from matplotlib.figure import Figure

    fig = Figure(figsize=(8.0, 9.0), dpi=100)  # no pyplot: no global state, thread-safe
    axes = fig.subplots(4, 1, sharex=True)
    for j, name in enumerate(joint_names):
        axes[0].plot(t, q[:, j], label=name, linewidth=1.2)
        axes[1].step(t[:-1], qd[:, j], where="post", linewidth=1.2)
    if speed_limits is not None and np.all(np.isfinite(speed_limits)):
        for v in (float(np.min(speed_limits)), -float(np.min(speed_limits))):
            axes[1].axhline(v, color="0.4", linestyle="--", linewidth=0.8)
    for k, axis in enumerate("xyz"):
        axes[2].plot(t, e[:, k], label=axis, linewidth=1.2)
    norm = np.linalg.norm(e, axis=1)
    axes[3].plot(t, norm, color="k", linewidth=1.2, label="|error|")
    axes[3].axhline(float(norm.mean()), color="0.4", linestyle="--", linewidth=0.8,
                    label=f"mean {norm.mean():.3g} mm")
    for ax, label in zip(axes, ("joint angle\n[rad]", "joint speed\n[rad/s]",
                                "error per axis\n[mm]", "tool error\n[mm]")):
        ax.set_ylabel(label)
        ax.grid(True, alpha=0.3)
    for ax in (axes[0], axes[2], axes[3]):
        ax.legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1].set_xlabel("time [s]")
    return _png(fig, title)


def _png(fig: Any, title: str) -> bytes:
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    return buf.getvalue()
