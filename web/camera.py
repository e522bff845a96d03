"""Where the camera goes so that everything drawn is in view, beside the control panel.

``frame_bounds`` takes the world bounds of what is shown (metres) and a browser's view (its
vertical field of view and canvas size in pixels) and returns a camera position and look-at
point: looking from ``VIEW_DIRECTION`` (front left, above), far enough that the bounds' ball
fits in the part of the canvas the control panel leaves free, and panned so that this ball
sits in the middle of that part. viser's panel floats at the right edge (``PANEL_PX`` wide
with its margin); on a canvas too narrow to leave half of it free the panel is ignored.

Pinhole geometry: a point at depth ``d`` and lateral offset ``x`` projects at
``x / (d tan(fov_h / 2))`` in normalised device coordinates. The free part's centre is at
``-PANEL_PX / W`` (left of the canvas centre), so the camera and its target are moved by
``PANEL_PX d tan(fov_v / 2) / H`` along the camera's right axis (independent of ``W``).
"""

from __future__ import annotations

import math
from collections.abc import Iterable

import numpy as np

__all__ = ["VIEW_DIRECTION", "RIG_VIEW_DIRECTION", "PANEL_PX", "DEFAULT_FOV_RAD",
           "DEFAULT_CANVAS_PX", "MARGIN", "MIN_RADIUS_M", "View", "frame_bounds", "union_bounds"]

#: From the target towards the camera: front left, above (unit vector).
VIEW_DIRECTION = np.array([0.35, -0.8, 0.4]) / np.linalg.norm([0.35, -0.8, 0.4])
#: For a rig (a jumbo's booms drilling a face ahead of them along +x): from behind the rig,
#: a little left and above, so the face is seen face-on past the booms.
RIG_VIEW_DIRECTION = np.array([-0.85, -0.3, 0.45]) / np.linalg.norm([-0.85, -0.3, 0.45])
#: Width (px) the control panel covers at the canvas' right edge, margin included.
PANEL_PX = 340.0
#: viser's default vertical field of view, and a canvas size assumed before a browser says.
DEFAULT_FOV_RAD = math.radians(75.0)
DEFAULT_CANVAS_PX = (1280, 800)
#: The bounds' ball is fitted with this much room to spare (1: touching the edges).
MARGIN = 1.15
#: Smallest radius (m) framed, so a point-sized scene is not zoomed in to nothing.
MIN_RADIUS_M = 0.25

View = tuple[float, int, int]  # (vertical fov rad, canvas width px, canvas height px)


def union_bounds(bounds: Iterable[tuple[np.ndarray, np.ndarray] | None]
                 ) -> tuple[np.ndarray, np.ndarray] | None:
    """The box ``(lower (3,), upper (3,))`` around all given boxes (None entries skipped);
    None when there are none."""
    boxes = [(np.asarray(lo, float), np.asarray(hi, float)) for b in bounds if b is not None
             for lo, hi in [b] if np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))]
    if not boxes:
        return None
    return (np.min([lo for lo, _ in boxes], axis=0), np.max([hi for _, hi in boxes], axis=0))


def frame_bounds(lower, upper, view: View | None = None, *, panel_px: float = PANEL_PX,
                 direction=VIEW_DIRECTION, up=(0.0, 0.0, 1.0)) -> tuple[np.ndarray, np.ndarray]:
    """Camera ``(position (3,), look_at (3,))`` (m) showing the box ``lower``..``upper`` (m)
    whole in the canvas left of the panel. ``view`` = (vertical fov rad, width px, height px),
    default ``DEFAULT_FOV_RAD`` on ``DEFAULT_CANVAS_PX``."""
    fov, width, height = view or (DEFAULT_FOV_RAD, *DEFAULT_CANVAS_PX)
    width, height = max(int(width), 1), max(int(height), 1)
    if width - panel_px < 0.5 * width:
        panel_px = 0.0
    lo, hi = np.asarray(lower, dtype=float), np.asarray(upper, dtype=float)
    centre = 0.5 * (lo + hi)
    radius = max(0.5 * float(np.linalg.norm(hi - lo)), MIN_RADIUS_M)
    tan_v = math.tan(0.5 * fov)
    tan_free = tan_v * (width - panel_px) / height  # half-width of the free part at depth 1
    tan_half = min(tan_v, tan_free)
    distance = MARGIN * radius / math.sin(math.atan(tan_half))
    d = np.asarray(direction, dtype=float)
    d = d / np.linalg.norm(d)
    right = np.cross(-d, np.asarray(up, dtype=float))
    norm = np.linalg.norm(right)
    right = right / norm if norm > 1e-9 else np.array([1.0, 0.0, 0.0])
    shift = panel_px * distance * tan_v / height
    look_at = centre + shift * right
    return look_at + distance * d, look_at
