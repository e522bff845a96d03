"""Robots imported from URDF (with meshes and an optional SRDF).

``import_robot(data, filename, robot_id=...)`` reads a ``.urdf`` file or a ``.zip`` /
``.tar.gz`` / ``.tgz`` / ``.tar`` archive holding the URDF and its meshes, and returns an
``ImportedRobot``: the chain between two links as a product-of-exponentials ``RobotModel``,
every link with its collision and visual geometry riding on a chain frame, the adjacent and
SRDF-disabled link pairs, and the meshes (mm).

Rules:

* **Which URDF**: the upload itself, or the archive's only ``.urdf`` file; ``urdf`` names one
  (by path inside the archive or by file name) when there are several.
* **Which SRDF**: ``srdf`` when given; else the archive's ``.srdf`` named like the URDF
  (``robot.srdf`` for ``robot.urdf``, any folder); else its only ``.srdf`` when the archive
  holds a single URDF; else none.
* **Which chain**: ``group`` names an SRDF group with one ``<chain base_link tip_link>``
  (not together with ``base_link``/``tip_link``). Without ``group``, ``base_link`` and
  ``tip_link``, an SRDF with exactly one group that has a chain gives the chain. Otherwise
  ``base_link`` defaults to the URDF root and ``tip_link`` to the child link of the last
  movable joint, when the movable non-mimic joints below the base form a single chain (a
  ``FieldError`` at ``("tip_link",)`` lists the candidate ends when they branch).
* **Joints**: revolute, continuous (limits ±2π on the chain), prismatic (m -> mm, m/s ->
  mm/s) and fixed. A URDF speed limit of 0, or of 1e6 and more, means none. Floating and
  planar joints cannot be on the chain; off the chain they are held at identity (their origin
  applies). Mimic joints on the chain are refused; off it they follow their master (a chain
  joint: ``Link.mimic``; a joint off the chain: its held value), as ``multiplier * master +
  offset``; chains of mimic joints are refused. Movable joints off the chain are held at 0, or
  at ``fixed_joints[name]`` (rad, or mm for prismatic joints; within the joint's limits).
* **Frames**: the world frame is the URDF root link; the fixed transforms from it to the
  chain's base are the model's ``base``; ``home`` is the tip link's pose at q = 0 and
  ``tool`` the identity, so ``fk(model, q)`` is the tip link's pose. Lengths in mm.
* **Meshes**: ``package://``, ``model://``, ``file://``, absolute and relative references
  are looked up inside the archive only (rules in ``kinematics.urdf_import._meshes``); STL,
  OBJ, PLY and DAE (pycollada) load with trimesh. A bare URDF with mesh references is an
  error naming the link and the file.
* **Errors** name the element: ``("file", "joint[elbow_joint]", "axis", "xyz")`` (scheme in
  ``kinematics.urdf_import._parse``); caps in ``ImportLimits``.

Persistence: ``ImportedRobot.to_dict()`` / ``ImportedRobot.from_dict(d, meshes)`` and
``mesh_to_bytes`` / ``mesh_from_bytes`` (lossless ``.npz``). Export back to URDF:
``kinematics.urdf.imported_to_urdf``.
"""

from __future__ import annotations

from ._build import CONTINUOUS_LIMIT as CONTINUOUS_LIMIT
from ._build import import_robot as import_robot
from ._limits import DEFAULT_LIMITS as DEFAULT_LIMITS
from ._limits import MAX_ARCHIVE_BYTES as MAX_ARCHIVE_BYTES
from ._limits import MAX_ARCHIVE_MEMBERS as MAX_ARCHIVE_MEMBERS
from ._limits import MAX_LINKS as MAX_LINKS
from ._limits import MAX_MESH_FILES as MAX_MESH_FILES
from ._limits import MAX_MESH_TRIANGLES as MAX_MESH_TRIANGLES
from ._limits import MAX_MESH_TRIANGLES_TOTAL as MAX_MESH_TRIANGLES_TOTAL
from ._limits import MAX_UNPACKED_BYTES as MAX_UNPACKED_BYTES
from ._limits import MAX_XML_BYTES as MAX_XML_BYTES
from ._limits import MAX_XML_DEPTH as MAX_XML_DEPTH
from ._limits import MAX_XML_ELEMENTS as MAX_XML_ELEMENTS
from ._limits import ImportLimits as ImportLimits
from ._meshes import MESH_SUFFIXES as MESH_SUFFIXES
from ._meshes import mesh_from_bytes as mesh_from_bytes
from ._meshes import mesh_to_bytes as mesh_to_bytes
from ._robot import MESH_KEY_PATTERN as MESH_KEY_PATTERN
from ._robot import Geometry as Geometry
from ._robot import ImportedRobot as ImportedRobot
from ._robot import Link as Link
from ._robot import MeshData as MeshData
from ._robot import MimicStep as MimicStep

__all__ = [
    "CONTINUOUS_LIMIT",
    "DEFAULT_LIMITS",
    "Geometry",
    "ImportLimits",
    "ImportedRobot",
    "Link",
    "MAX_ARCHIVE_BYTES",
    "MAX_ARCHIVE_MEMBERS",
    "MAX_LINKS",
    "MAX_MESH_FILES",
    "MAX_MESH_TRIANGLES",
    "MAX_MESH_TRIANGLES_TOTAL",
    "MAX_UNPACKED_BYTES",
    "MAX_XML_BYTES",
    "MAX_XML_DEPTH",
    "MAX_XML_ELEMENTS",
    "MESH_KEY_PATTERN",
    "MESH_SUFFIXES",
    "MeshData",
    "MimicStep",
    "import_robot",
    "mesh_from_bytes",
    "mesh_to_bytes",
]
