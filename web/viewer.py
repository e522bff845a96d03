"""The 3D viewer: a viser scene showing robots in the configurations the API is told to show.

The scene is in metres (viser's camera defaults suit metres); the API's millimetres are
divided by 1000 at this edge only.
"""

from __future__ import annotations

import threading

import numpy as np

from kinematics.fk import fk_frames
from kinematics.model import RobotModel

__all__ = ["Viewer", "MM_TO_M", "wxyz_from_matrix"]

MM_TO_M = 1e-3
LINK_COLOR = (230, 120, 20)
JOINT_COLOR = (60, 60, 70)


def wxyz_from_matrix(R: np.ndarray) -> np.ndarray:
    """Unit quaternion (w, x, y, z) of a rotation matrix ``(3, 3)``."""
    R = np.asarray(R, dtype=float)
    w = np.sqrt(max(0.0, 1.0 + R[0, 0] + R[1, 1] + R[2, 2])) / 2.0
    x = np.copysign(np.sqrt(max(0.0, 1.0 + R[0, 0] - R[1, 1] - R[2, 2])) / 2.0, R[2, 1] - R[1, 2])
    y = np.copysign(np.sqrt(max(0.0, 1.0 - R[0, 0] + R[1, 1] - R[2, 2])) / 2.0, R[0, 2] - R[2, 0])
    z = np.copysign(np.sqrt(max(0.0, 1.0 - R[0, 0] - R[1, 1] + R[2, 2])) / 2.0, R[1, 0] - R[0, 1])
    q = np.array([w, x, y, z])
    return q / np.linalg.norm(q)


class Viewer:
    """A running viser server and what it currently shows."""

    def __init__(self, server) -> None:
        self.server = server
        self._lock = threading.Lock()
        self.current: dict | None = None
        server.scene.add_grid("/ground", width=6.0, height=6.0, cell_size=0.25, section_size=1.0)

    @classmethod
    def start(cls, host: str, port: int, state=None) -> Viewer:
        """A viser server on ``host:port`` (port 0: any free port). ``state`` is the
        service's app state (robots, jobs), kept for what the viewer shows."""
        import viser

        return cls(viser.ViserServer(host=host, port=port, label="kinoplan", verbose=False))

    def show_robot(self, model: RobotModel, q: np.ndarray) -> None:
        """Draw ``model`` at configuration ``q (dof,)``: links, joints and the tool frame."""
        frames = fk_frames(model, np.asarray(q, dtype=float))
        origins = frames[:, :3, 3] * MM_TO_M
        segments = np.stack([origins[:-1], origins[1:]], axis=1)
        scene = self.server.scene
        with self._lock:
            scene.add_line_segments(
                "/robot/links", segments, LINK_COLOR, thickness=0.03, thickness_units="world"
            )
            for i, p in enumerate(origins[:-1]):
                scene.add_icosphere(f"/robot/joint_{i}", radius=0.03, color=JOINT_COLOR,
                                    position=tuple(p))
            T_tool = frames[-1]
            scene.add_frame(
                "/robot/tool", axes_length=0.15, axes_radius=0.008,
                wxyz=tuple(wxyz_from_matrix(T_tool[:3, :3])), position=tuple(origins[-1]),
            )
            self.current = {"robot": model.id, "q": np.asarray(q, dtype=float).tolist()}

    def stop(self) -> None:
        self.server.stop()
