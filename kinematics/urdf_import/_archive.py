"""Reading an upload: a bare URDF, or a zip / tar.gz / tar archive, held in memory.

Nothing is ever written to disk: member names are keys to look files up by, normalised to
``a/b/c`` (backslashes as slashes, ``.`` and empty parts dropped); a name that climbs out of
the archive with ``..`` is skipped, as are folders, symbolic and hard links, devices, macOS
resource forks (``__MACOSX/``, ``._name``) and every member after the first of a name.

Caps (``ImportLimits``): the upload's size, the number of entries, and the total of unpacked
bytes, counted on the bytes actually produced (declared sizes can lie): zip members are
unpacked only when read, a tar stream is decompressed once under the cap and only the files
an import can use (URDF, SRDF, meshes) are kept.
"""

from __future__ import annotations

import gzip
import io
import lzma
import stat
import tarfile
import zipfile
import zlib
from collections import defaultdict

from ..errors import FieldError
from ._limits import ImportLimits

__all__ = ["Upload", "open_upload", "join_inside", "URDF_SUFFIXES", "SRDF_SUFFIXES"]

URDF_SUFFIXES = (".urdf",)
SRDF_SUFFIXES = (".srdf",)
#: Files a tar archive keeps in memory (by suffix); others are listed only.
_KEPT_SUFFIXES = (".urdf", ".srdf", ".stl", ".obj", ".ply", ".dae")
_LOC = ("file",)
_READ_ERRORS = (zipfile.BadZipFile, tarfile.TarError, zlib.error, lzma.LZMAError, EOFError,
                OSError, NotImplementedError, RuntimeError, ValueError)


def normalise(name: str) -> str | None:
    """A member name as a lookup key, or None when it is unusable (empty, climbs out with
    ``..``, or a macOS resource fork)."""
    parts = []
    for part in name.replace("\\", "/").split("/"):
        if part in ("", "."):
            continue
        if part == ".." or part == "__MACOSX":
            return None
        parts.append(part)
    if not parts or parts[-1].startswith("._"):
        return None
    return "/".join(parts)


def join_inside(folder: str, relative: str) -> str | None:
    """``folder/relative`` with ``.`` and ``..`` resolved; None if it leaves the archive."""
    parts = folder.split("/") if folder else []
    for part in relative.replace("\\", "/").split("/"):
        if part in ("", "."):
            continue
        if part == "..":
            if not parts:
                return None
            parts.pop()
        else:
            parts.append(part)
    return "/".join(parts) if parts else None


class Upload:
    """The files of an upload by normalised name; ``read`` returns their bytes."""

    def __init__(self, kind: str, limits: ImportLimits):
        self.kind = kind  # "urdf", "zip" or "tar"
        self.limits = limits
        self._data: dict[str, bytes] = {}
        self._zip: zipfile.ZipFile | None = None
        self._infos: dict[str, zipfile.ZipInfo] = {}
        self._names: list[str] = []
        self._index: dict[str, int] = {}
        self._folded_map: dict[str, list[str]] | None = None
        self._folders: dict[str, list[str]] = {}
        self._unpacked = 0

    # ---- listing --------------------------------------------------------------------------
    @property
    def names(self) -> list[str]:
        """Every usable file name, in archive order."""
        return list(self._names)

    def _add(self, name: str) -> bool:
        if name in self._index:
            return False
        self._index[name] = len(self._names)
        self._names.append(name)
        self._folded_map = None
        self._folders.clear()
        return True

    def with_suffix(self, suffixes: tuple[str, ...]) -> list[str]:
        return [n for n in self._names if n.lower().endswith(suffixes)]

    def find(self, path: str | None) -> str | None:
        """The member named ``path``; else the only one whose name matches it ignoring case
        (archives made on case-insensitive file systems); else None."""
        if path is None:
            return None
        if path in self._index:
            return path
        hits = self._folded.get(path.lower(), [])
        return hits[0] if len(hits) == 1 else None

    @property
    def _folded(self) -> dict[str, list[str]]:
        if self._folded_map is None:
            folded: dict[str, list[str]] = defaultdict(list)
            for n in self._names:
                folded[n.lower()].append(n)
            self._folded_map = dict(folded)
        return self._folded_map

    def folders_named(self, name: str) -> list[str]:
        """Folders whose last part is ``name``, shallowest first, then by path."""
        if name in self._folders:
            return self._folders[name]
        found = set()
        for member in self._names:
            parts = member.split("/")[:-1]
            for k, part in enumerate(parts):
                if part == name:
                    found.add("/".join(parts[:k + 1]))
        self._folders[name] = sorted(found, key=lambda p: (p.count("/"), p))
        return self._folders[name]

    # ---- reading --------------------------------------------------------------------------
    def read(self, name: str) -> bytes:
        """The bytes of member ``name`` (a name from ``names``)."""
        if name in self._data:
            return self._data[name]
        if self._zip is None or name not in self._infos:
            raise FieldError(_LOC, f"'{name}' in the archive cannot be read (only URDF, SRDF "
                                   f"and mesh files are kept from a tar archive)")
        info = self._infos[name]
        if info.flag_bits & 0x1:
            raise FieldError(_LOC, f"'{name}' in the archive is encrypted")
        chunks = []
        try:
            with self._zip.open(info) as member:
                while chunk := member.read(1 << 20):
                    self._count(len(chunk))
                    chunks.append(chunk)
        except FieldError:
            raise
        except _READ_ERRORS as exc:
            raise FieldError(_LOC, f"'{name}' in the archive cannot be read: {exc}") from None
        data = b"".join(chunks)
        self._data[name] = data
        return data

    def _count(self, n: int) -> None:
        self._unpacked += n
        if self._unpacked > self.limits.max_unpacked_bytes:
            raise FieldError(_LOC, f"the archive unpacks to more than "
                                   f"{self.limits.max_unpacked_bytes:,} bytes")


class _Capped(io.RawIOBase):
    """A read-only stream that fails once more than ``upload``'s unpacked cap is read."""

    def __init__(self, inner, upload: Upload):
        self.inner = inner
        self.upload = upload

    def readable(self) -> bool:
        return True

    def read(self, n: int = -1) -> bytes:
        if n is None or n < 0:
            n = 1 << 20
        data = self.inner.read(n)
        self.upload._count(len(data))
        return data

    def readinto(self, buffer) -> int:
        data = self.read(len(buffer))
        buffer[:len(data)] = data
        return len(data)


def _kind(data: bytes, filename: str) -> str:
    lower = filename.lower()
    if lower.endswith(URDF_SUFFIXES):
        return "urdf"
    if lower.endswith(".zip"):
        if not data.startswith(b"PK"):
            raise FieldError(_LOC, f"'{filename}' is not a zip archive")
        return "zip"
    if lower.endswith((".tar.gz", ".tgz")):
        if not data.startswith(b"\x1f\x8b"):
            raise FieldError(_LOC, f"'{filename}' is not a gzip-compressed tar archive")
        return "tgz"
    if lower.endswith(".tar"):
        return "tar"
    raise FieldError(_LOC, f"unsupported file '{filename}': upload a .urdf file, or a .zip, "
                           ".tar.gz (.tgz) or .tar archive holding the URDF and its meshes")


def open_upload(data: bytes, filename: str, limits: ImportLimits) -> Upload:
    """Open the upload ``data`` named ``filename``; ``FieldError(("file",), ...)`` when it is
    too large, of an unknown kind or not readable."""
    if not isinstance(data, bytes | bytearray | memoryview):
        raise FieldError(_LOC, "must be the bytes of the uploaded file")
    data = bytes(data)
    if len(data) > limits.max_archive_bytes:
        raise FieldError(_LOC, f"the upload is {len(data):,} bytes; at most "
                               f"{limits.max_archive_bytes:,} allowed")
    if not data:
        raise FieldError(_LOC, "the upload is empty")
    kind = _kind(data, filename)
    if kind == "urdf":
        upload = Upload("urdf", limits)
        name = normalise(filename) or "robot.urdf"
        name = name.rsplit("/", 1)[-1]
        upload._add(name)
        upload._data[name] = data
        return upload
    if kind == "zip":
        return _open_zip(data, limits)
    return _open_tar(data, limits, compressed=kind == "tgz")


def _open_zip(data: bytes, limits: ImportLimits) -> Upload:
    upload = Upload("zip", limits)
    try:
        zf = zipfile.ZipFile(io.BytesIO(data))
        infos = zf.infolist()
    except _READ_ERRORS as exc:
        raise FieldError(_LOC, f"not a readable zip archive: {exc}") from None
    if len(infos) > limits.max_archive_members:
        raise FieldError(_LOC, f"the archive lists {len(infos):,} entries; at most "
                               f"{limits.max_archive_members:,} allowed")
    declared = 0
    for info in infos:
        if info.is_dir():
            continue
        mode = stat.S_IFMT(info.external_attr >> 16)
        if mode and mode != stat.S_IFREG:  # symbolic links, devices, pipes
            continue
        name = normalise(info.filename)
        if name is None or not upload._add(name):
            continue
        upload._infos[name] = info
        declared += info.file_size
    if declared > limits.max_unpacked_bytes:
        raise FieldError(_LOC, f"the archive unpacks to {declared:,} bytes; at most "
                               f"{limits.max_unpacked_bytes:,} allowed")
    upload._zip = zf
    return upload


def _open_tar(data: bytes, limits: ImportLimits, *, compressed: bool) -> Upload:
    upload = Upload("tar", limits)
    raw = io.BytesIO(data)
    stream = _Capped(gzip.GzipFile(fileobj=raw) if compressed else raw, upload)
    try:
        with tarfile.open(fileobj=stream, mode="r|") as tf:
            for count, member in enumerate(tf, start=1):
                if count > limits.max_archive_members:
                    raise FieldError(_LOC, f"the archive lists more than "
                                           f"{limits.max_archive_members:,} entries")
                if not member.isreg():  # folders, links, devices
                    continue
                name = normalise(member.name)
                if name is None or not upload._add(name):
                    continue
                if member.size > limits.max_unpacked_bytes:
                    raise FieldError(_LOC, f"'{name}' is {member.size:,} bytes; at most "
                                           f"{limits.max_unpacked_bytes:,} allowed")
                if name.lower().endswith(_KEPT_SUFFIXES):
                    extracted = tf.extractfile(member)
                    upload._data[name] = extracted.read() if extracted is not None else b""
    except FieldError:
        raise
    except _READ_ERRORS as exc:
        raise FieldError(_LOC, f"not a readable tar archive: {exc}") from None
    return upload
