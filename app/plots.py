"""PNG plots for reports: joint position, velocity, acceleration and jerk against time."""

from __future__ import annotations

import io

import matplotlib

matplotlib.use("Agg")  # no display: render to memory only

import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from planning.trajectory import Samples  # noqa: E402

__all__ = ["trajectory_png"]

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
) -> bytes:
    """Four stacked panels (position, velocity, acceleration, jerk) of every joint; dashed
    vertical lines at the segment joins ``breaks``. Units per joint: 'rad' or 'mm'."""
    unit = "/".join(sorted(set(joint_units))) or "rad"
    fig, axes = plt.subplots(4, 1, figsize=(8.0, 9.0), sharex=True, dpi=100)
    for ax, (attr, label) in zip(axes, _ROWS):
        values = getattr(samples, attr)
        for j, name in enumerate(joint_names):
            ax.plot(samples.t, values[:, j], label=f"{name} [{joint_units[j]}]", linewidth=1.2)
        suffix = {"q": "", "qd": "/s", "qdd": "/s²", "qddd": "/s³"}[attr]
        ax.set_ylabel(f"{label}\n[{unit}{suffix}]")
        ax.grid(True, alpha=0.3)
        if breaks is not None:
            for b in breaks[1:-1]:
                ax.axvline(b, color="0.5", linestyle="--", linewidth=0.8)
    axes[0].legend(loc="upper left", bbox_to_anchor=(1.01, 1.0), fontsize=8)
    axes[-1].set_xlabel("time [s]")
    if title:
        fig.suptitle(title)
    fig.tight_layout()
    buf = io.BytesIO()
    fig.savefig(buf, format="png")
    plt.close(fig)
    return buf.getvalue()
