"""Where a robot description may point: its own folder and the package paths the user names.

Every file a description refers to (URDF ``<mesh filename>``, ``package://`` URIs, MJCF
``<include file>``, ``<compiler meshdir/assetdir/texturedir>`` and asset ``file=``) goes through
:func:`resolve_resource`, which returns a real path (symlinks resolved) under one of the
allowed roots, or raises :class:`PathEscape`. The roots are the folder of the description
(for a xacro file, the folder of the ``.xacro``), the folders of ``--package-path``
(``package_paths`` in Python) and of ``ROS_PACKAGE_PATH`` when it is set. ``package://pkg/rest``
is looked up as ``ROOT/pkg/rest`` (or ``ROOT/rest`` for a root named ``pkg``) in those package
folders only. Absolute paths and ``..`` that leave the roots are refused.

URDF meshes only feed the bounding ellipsoids: :func:`confine_urdf_meshes` drops a geometry
whose mesh is outside the roots or missing, and reports it (the ellipsoids' warning names each
file and the ellipsoid used instead). MJCF is parsed by MuJoCo/Pinocchio,
which may read what it names: :func:`check_mjcf_paths` refuses any escape with an error.
"""

from __future__ import annotations

import os
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Iterable, Sequence

from .errors import RobotModelError, RobotModelWarning
from .model_checks import read_xml

__all__ = ["PathEscape", "check_mjcf_paths", "confine_urdf_meshes", "package_roots", "resolve_resource"]

_HINT = "add its folder to `package_paths=DIR`"


class PathEscape(RobotModelError):
    """A file reference of a robot description that leaves the allowed folders."""


def package_roots(package_paths: Iterable[str | os.PathLike] = (), env: bool = True) -> tuple[Path, ...]:
    """The package folders: those given, then ``ROS_PACKAGE_PATH``'s (when ``env``), as real paths."""
    paths = [Path(p) for p in package_paths]
    if env and os.environ.get("ROS_PACKAGE_PATH"):
        paths += [Path(p) for p in os.environ["ROS_PACKAGE_PATH"].split(os.pathsep) if p]
    out: list[Path] = []
    for p in paths:
        real = Path(os.path.realpath(p))
        if real not in out:
            out.append(real)
    return tuple(out)


def _under(path: Path, roots: Sequence[Path]) -> bool:
    return any(path == r or r in path.parents for r in roots)


def resolve_resource(ref: str, base: str | os.PathLike, packages: Sequence[Path] = (), src: str = "") -> Path:
    """The real path of ``ref`` (a path relative to ``base``, an absolute path, ``file://`` or
    ``package://``) if it lies under ``base`` or a package folder; else :class:`PathEscape`."""
    base = Path(os.path.realpath(base))
    roots = (base, *[Path(os.path.realpath(p)) for p in packages])
    where = f"{src}: " if src else ""
    ref = ref.strip()
    if ref.startswith("package://"):
        pkg, _, rest = ref[len("package://"):].partition("/")
        if not pkg or not packages:
            raise PathEscape(f"{where}{ref!r} names a ROS package but no package folder is given; {_HINT}")
        candidates = [Path(p) / pkg / rest for p in packages] + [Path(p) / rest for p in packages if Path(p).name == pkg]
        found = next((c for c in candidates if c.exists()), candidates[0])
        real = Path(os.path.realpath(found))
        if not _under(real, roots):
            raise PathEscape(f"{where}{ref!r} leaves the package folders")
        if not found.exists():
            raise PathEscape(f"{where}{ref!r}: package '{pkg}' is not in the package folders "
                             f"{[str(p) for p in packages]}; {_HINT}")
        return real
    given = ref
    if ref.startswith("file://"):
        ref = ref[len("file://"):]
    elif "://" in ref:
        raise PathEscape(f"{where}{ref!r}: only relative paths, file:// and package:// are followed")
    real = Path(os.path.realpath(base / ref))  # an absolute ref replaces base
    if not _under(real, roots):
        kind = "an absolute path" if os.path.isabs(ref) else "a path"
        raise PathEscape(f"{where}{given!r} is {kind} outside the description's folder {base} and the package "
                         f"folders; {_HINT}")
    return real


def confine_urdf_meshes(text: str, base: str | os.PathLike, packages: Sequence[Path] = (), src: str = "",
                        dropped: list | None = None) -> str:
    """URDF ``text`` with each ``<mesh filename>`` replaced by its resolved real path; a visual or
    collision whose mesh leaves the roots (or is missing) is dropped: recorded in ``dropped``
    (``{"link", "kind", "file", "reason"}`` each) when a list is given, else one RobotModelWarning each."""
    root = ET.fromstring(text)
    for link in root.iter("link"):
        for kind in ("visual", "collision"):
            for geom in list(link.findall(kind)):
                mesh = geom.find("geometry/mesh")
                if mesh is None:
                    continue
                fn, real = mesh.get("filename", ""), None
                try:
                    real = resolve_resource(fn, base, packages, src)
                    if not real.is_file():
                        raise PathEscape(f"{src}: mesh {fn!r} not found ({real})")
                except PathEscape as exc:
                    if dropped is not None:  # the reason without the file, the source and the hint
                        why = (f"not found ({real})" if real is not None else
                               str(exc).removeprefix(f"{src}: " if src else "").removeprefix(repr(fn.strip()))
                               .replace(f"; {_HINT}", "").lstrip(": "))
                        dropped.append({"link": link.get("name"), "kind": kind, "file": fn, "reason": why})
                    else:
                        warnings.warn(f"{exc}; link '{link.get('name')}' {kind} mesh ignored (the bounding "
                                      "ellipsoid uses the other geometry and the joints)", RobotModelWarning,
                                      stacklevel=3)
                    link.remove(geom)
                    continue
                mesh.set("filename", str(real))
    return ET.tostring(root, encoding="unicode")


_DIRS = ("meshdir", "texturedir", "assetdir")


def check_mjcf_paths(path: str | os.PathLike, packages: Sequence[Path] = (), _depth: int = 0) -> None:
    """PathEscape (one line) if the MJCF file, or a file it includes, names an include, asset
    directory or asset file outside its folder and the package folders."""
    path = Path(path)
    base = path.parent
    root = read_xml(path)
    dirs = {}
    for comp in root.iter("compiler"):
        for key in _DIRS:
            if comp.get(key) is not None:
                dirs[key] = resolve_resource(comp.get(key), base, packages, f"{path}: <compiler {key}>")
    for el in root.iter():
        ref = el.get("file")
        if ref is None:
            continue
        if el.tag == "include":
            inc = resolve_resource(ref, base, packages, f"{path}: <include>")
            if _depth >= 8:
                raise RobotModelError(f"{path}: includes nested deeper than 8 levels")
            if inc.is_file():
                check_mjcf_paths(inc, (base, *packages), _depth + 1)
            continue
        folder = dirs.get("texturedir" if el.tag == "texture" else "meshdir") or dirs.get("assetdir") or base
        resolve_resource(str(Path(folder) / ref), base, packages, f"{path}: <{el.tag} file>")
