"""Line segments whose colours change with the plan's time: a drill hole grey while planned,
bright while its boom drills it, dark once done.

``TimedSegments`` is pure data (part of a ``web.results.Plan``): segment ``k`` runs from
``points[k, 0]`` to ``points[k, 1]`` (mm) and changes colour at the times ``times[k]``
(non-decreasing; ``inf`` for a change that never comes). Its colour at time ``t`` is
``colors[k, j]`` with ``j`` the number of its change times at or before ``t``, so a segment
with ``M`` change times has ``M + 1`` colours. ``TimedNodes`` draws them (one line-segment node
per item, ``<plan root>/<name>``; the colours sent as linear values, which the browser shows
as the sRGB colours given) and recolours them as the viewer plays the plan; the viewer calls
it under its lock. Lengths mm, times s.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

import numpy as np

from .scene import MM_TO_M

__all__ = ["TimedSegments", "TimedNodes"]

#: A change time counts as reached this close before it (s), so a time set at a change shows
#: the colour that starts there.
TIME_EPS = 1e-9


@dataclass(frozen=True)
class TimedSegments:
    """Segments ``points (K, 2, 3)`` mm, each changing colour at ``times (K, M)`` s through
    ``colors (K, M + 1, 3)`` (0-255); ``width`` relative to the plan's lines."""

    name: str
    points: np.ndarray
    times: np.ndarray
    colors: np.ndarray
    width: float = 1.0

    def __post_init__(self) -> None:
        P = np.asarray(self.points, dtype=float).reshape(-1, 2, 3)
        K = len(P)
        T = np.asarray(self.times, dtype=float).reshape(K, -1)
        C = np.asarray(self.colors).reshape(K, -1, 3)
        if C.shape[1] != T.shape[1] + 1:
            raise ValueError(f"{self.name}: {T.shape[1]} change times need "
                             f"{T.shape[1] + 1} colours per segment, got {C.shape[1]}")
        if np.any(T[:, 1:] < T[:, :-1]):
            raise ValueError(f"{self.name}: change times must not decrease")
        object.__setattr__(self, "points", P)
        object.__setattr__(self, "times", T)
        object.__setattr__(self, "colors", np.clip(C, 0, 255).astype(np.uint8))

    def state_at(self, t: float) -> np.ndarray:
        """Index ``(K,)`` of each segment's colour at time ``t``: its change times passed."""
        return np.sum(self.times <= float(t) + TIME_EPS, axis=1)

    def colors_at(self, t: float) -> np.ndarray:
        """Colour ``(K, 3)`` uint8 of each segment at time ``t``."""
        return self.colors[np.arange(len(self.points)), self.state_at(t)]


def _vertex_colors(colors: np.ndarray) -> np.ndarray:
    """Per-vertex colours ``(K, 2, 3)`` uint8 of segments coloured ``colors (K, 3)`` (sRGB):
    the browser takes vertex colours as linear and brightens them on output, where a line's
    single colour is taken as sRGB; converting here makes both look alike."""
    c = np.asarray(colors, dtype=float) / 255.0
    linear = np.where(c <= 0.04045, c / 12.92, ((c + 0.055) / 1.055) ** 2.4)
    out = np.round(255.0 * linear).astype(np.uint8)
    return np.repeat(out[:, None, :], 2, axis=1)


class TimedNodes:
    """The nodes of a plan's ``TimedSegments`` under ``root`` (``<root>/<name>``), drawn as at
    time 0; ``update(t)`` recolours those whose colours changed. Not thread-safe by itself."""

    def __init__(self, scene: Any, root: str, items: Sequence[TimedSegments],
                 thickness_m: float) -> None:
        self.items = tuple(items)
        self.handles: dict[str, Any] = {}
        self._states: dict[str, np.ndarray] = {}
        for item in self.items:
            name = f"{root}/{item.name}"
            if not len(item.points):
                continue
            self.handles[name] = scene.add_line_segments(
                name, item.points * MM_TO_M, _vertex_colors(item.colors_at(0.0)),
                thickness=thickness_m * item.width, thickness_units="world")
            self._states[name] = item.state_at(0.0)

    def update(self, t: float) -> None:
        """Colour every segment as it is at time ``t``."""
        for item, (name, h) in zip((i for i in self.items if len(i.points)),
                                   self.handles.items(), strict=True):
            state = item.state_at(t)
            if np.array_equal(state, self._states[name]):
                continue
            self._states[name] = state
            h.colors = _vertex_colors(item.colors[np.arange(len(item.points)), state])
