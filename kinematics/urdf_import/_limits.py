"""Caps on what an upload may hold, sized for real robots.

For scale: the UR5 + Robotiq 85 + FT300 description (27 mesh files, 11 MB unpacked, 6.3 MB
zipped with the Panda) references about 190,000 triangles, the largest mesh 43,473; the
Panda about 105,000, the largest 21,620.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = [
    "ImportLimits", "DEFAULT_LIMITS", "MAX_ARCHIVE_BYTES", "MAX_UNPACKED_BYTES",
    "MAX_ARCHIVE_MEMBERS", "MAX_XML_BYTES", "MAX_XML_DEPTH", "MAX_XML_ELEMENTS", "MAX_LINKS",
    "MAX_MESH_FILES", "MAX_MESH_TRIANGLES", "MAX_MESH_TRIANGLES_TOTAL",
]

MiB = 1 << 20
#: Largest upload (the URDF file or the archive as sent).
MAX_ARCHIVE_BYTES = 64 * MiB
#: Largest total of the bytes unpacked from an archive (zip members read; for a tar archive,
#: the decompressed tar stream): the zip-bomb guard.
MAX_UNPACKED_BYTES = 256 * MiB
#: Most entries (files, folders, links) an archive may list.
MAX_ARCHIVE_MEMBERS = 10_000
#: Largest URDF or SRDF text.
MAX_XML_BYTES = 8 * MiB
#: Deepest element nesting in a URDF or SRDF (real ones nest 5 deep).
MAX_XML_DEPTH = 32
#: Most elements in a URDF or SRDF.
MAX_XML_ELEMENTS = 200_000
#: Most links (and so joints) in a URDF.
MAX_LINKS = 500
#: Most distinct mesh files (with distinct scales) one robot may reference.
MAX_MESH_FILES = 500
#: Most triangles in one mesh.
MAX_MESH_TRIANGLES = 1_000_000
#: Most triangles over all meshes of a robot (each distinct mesh counted once).
MAX_MESH_TRIANGLES_TOTAL = 4_000_000


@dataclass(frozen=True)
class ImportLimits:
    """The caps ``import_robot`` applies; the defaults are the module constants."""

    max_archive_bytes: int = MAX_ARCHIVE_BYTES
    max_unpacked_bytes: int = MAX_UNPACKED_BYTES
    max_archive_members: int = MAX_ARCHIVE_MEMBERS
    max_xml_bytes: int = MAX_XML_BYTES
    max_xml_depth: int = MAX_XML_DEPTH
    max_xml_elements: int = MAX_XML_ELEMENTS
    max_links: int = MAX_LINKS
    max_mesh_files: int = MAX_MESH_FILES
    max_mesh_triangles: int = MAX_MESH_TRIANGLES
    max_mesh_triangles_total: int = MAX_MESH_TRIANGLES_TOTAL


DEFAULT_LIMITS = ImportLimits()
