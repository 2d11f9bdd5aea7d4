"""MATLAB ``.mat`` files, read into a :class:`~sensorless.data.names.RawLog`.

* v7.3 (``save -v7.3``) is HDF5 behind a 512-byte MATLAB header, read with h5py (also when
  the file is named ``.h5``). MATLAB stores arrays column-major, so a dataset holds the MATLAB
  array with its dimensions reversed; they are reversed back, and both versions give the array
  MATLAB shows (:mod:`.orientation` then decides which axis is time).
* v4/v6/v7 are read with :func:`scipy.io.loadmat`.

Variables are addressed by path: a struct's fields are ``data/q`` (``--columns 'q=data/q'``),
and without ``--columns`` the recognised names are looked up in the last path component
(:data:`~sensorless.data.names.FIELD_NAMES`, shallowest first). Joint names (``joint_names``
or ``names``) may be a char matrix (one name per row, blank-padded) or a cell array of char
(``{'j1','j2'}``); a MATLAB ``string`` array is an opaque object in the file and is refused
with the fix (save ``cellstr(names)`` or ``char(names)``).
"""

from __future__ import annotations

import math

from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import DataError, InputError
from .arrays import EXTRA_KEYS, READ_ERRORS, as_float, flat_keys, join_parts, joint_names_of, missing_q, one_line, pick_fields
from .limits import check_log_size
from .names import JOINT_NAME_KEYS, RawLog, pick_key

__all__ = ["read_mat", "is_mat73", "MAT73_HEADER"]

#: how a MATLAB v7.3 file begins (its 128-byte text header, inside the HDF5 user block)
MAT73_HEADER = b"MATLAB 7.3 MAT-file"
_INTERNAL = ("#refs#", "#subsystem#")  # MATLAB's own groups: cell contents and object data
_STRING_FIX = ("is a MATLAB string array, which MATLAB stores as an opaque object; save the names as a cell array "
               "of char or a char matrix instead: names = cellstr(names); (or char(names)), then save")


def is_mat73(path: Path) -> bool:
    """True for a MATLAB v7.3 file (MATLAB header + HDF5), whatever its extension."""
    try:
        with open(path, "rb") as fh:
            head = fh.read(len(MAT73_HEADER))
    except OSError:
        return False
    return head == MAT73_HEADER


def read_mat(path: Path, columns: Mapping | None) -> RawLog:
    src = str(path)
    if is_mat73(path):
        return _read_mat73(path, columns, src)
    import scipy.io

    try:
        header = scipy.io.whosmat(str(path))
    except NotImplementedError:  # an HDF5-based .mat without MATLAB's header
        raise DataError("a MATLAB v7.3 (HDF5) file without MATLAB's header; read it as .h5", src) from None
    except READ_ERRORS as exc:
        raise DataError(f"not a readable MATLAB .mat file ({one_line(exc)})", src) from None
    check_log_size(src, sum(int(np.prod(shape)) for _, shape, cls in header if cls not in ("struct", "cell")),
                   f"its variables ({', '.join(name for name, _, _ in header[:8])})")
    try:
        doc = scipy.io.loadmat(str(path), simplify_cells=True, chars_as_strings=True)
    except READ_ERRORS as exc:
        raise DataError(f"not a readable MATLAB .mat file ({one_line(exc)})", src) from None
    leaves: dict[str, Any] = {}
    _flatten({k: v for k, v in doc.items() if not k.startswith("__")}, "", leaves)
    return _fields(leaves, columns, src, _v5_value)


def _flatten(node: dict, prefix: str, out: dict) -> None:
    for key, val in node.items():
        path = f"{prefix}{key}"
        if isinstance(val, dict):
            _flatten(val, path + "/", out)
        else:
            out[path] = val


def _is_opaque(val: Any) -> bool:
    import scipy.io.matlab as sm

    return isinstance(val, (sm.MatlabOpaque, sm.MatlabObject, sm.MatlabFunction))


def _v5_text(val: Any) -> bool:
    """A v4–v7 variable that holds text: a string, a char/cell array of text or a MATLAB string object."""
    if isinstance(val, str) or _is_opaque(val):
        return True
    if isinstance(val, (list, tuple)):
        return bool(val) and all(isinstance(v, str) for v in val)
    return isinstance(val, np.ndarray) and (val.dtype.kind in "US" or (val.dtype.kind == "O" and val.size > 0 and all(
        isinstance(v, str) for v in val.reshape(-1))))


def _v5_value(val: Any, key: str, src: str, text: bool) -> Any:
    if _is_opaque(val):
        if text:
            raise DataError(f"'{key}' {_STRING_FIX}", src)
        raise DataError(f"'{key}' is a MATLAB object, not a numeric array", src)
    if text:
        if isinstance(val, str):
            return [val]
        items = np.asarray(val, dtype=object).reshape(-1)
        if isinstance(val, np.ndarray) and val.dtype.kind not in "USO":
            raise DataError(f"'{key}' holds {val.dtype} values, not text (a char matrix or a cell array of char)", src)
        odd = next((v for v in items if not isinstance(v, str)), None)
        if odd is not None:
            raise DataError(f"'{key}' is a cell array whose items are not all text (one is {type(odd).__name__} "
                            f"{str(odd)[:40]}); save the joint names as a cell array of char", src)
        return [str(v) for v in items]
    if isinstance(val, (str, list)) or (isinstance(val, np.ndarray) and val.dtype.kind in "USO"):
        raise DataError(f"'{key}' holds text or a cell array, not numbers", src)
    return np.asarray(val)


def _fields(leaves: Mapping[str, Any], columns: Mapping | None, src: str, value, check=None, is_text=None) -> RawLog:
    """Pick the fields, joint names and extras among ``leaves`` (path -> stored value, read by
    ``value(stored, path, src, text)``; ``check(paths)`` vets what will be read first; ``is_text(stored)``: the
    variable holds text, e.g. joint names under a name of the file's own)."""
    is_text = is_text or _v5_text
    keys = list(leaves)
    base = lambda k: k.rsplit("/", 1)[-1]  # noqa: E731
    picked = pick_fields(keys, columns, src, base)
    if "q" not in picked:
        raise missing_q(keys, src)
    extra = {e: k for e in EXTRA_KEYS if (k := pick_key(e, keys, None, src, base, names=(e,))) is not None}
    name_key = pick_key("joint_names", keys, columns, src, base, names=JOINT_NAME_KEYS)
    if check is not None:
        check([*flat_keys(picked), *extra.values(), *([name_key] if name_key else [])])
    arrays = {f: join_parts([as_float(value(leaves[k], k, src, False), src, k) for k in ks], src, ks)
              for f, ks in picked.items()}
    extras = {e: value(leaves[k], k, src, False) for e, k in extra.items()}
    names = joint_names_of(value(leaves[name_key], name_key, src, True), src, name_key) if name_key else None
    used = {*flat_keys(picked), *extra.values(), name_key}
    unused = [k for k in keys if k not in used]
    return RawLog(arrays, names, {f: ",".join(ks) for f, ks in picked.items()}, extras, unused, [k for k in unused if is_text(leaves[k])])


# ---- v7.3 (HDF5) ---------------------------------------------------------------------------
def _read_mat73(path: Path, columns: Mapping | None, src: str) -> RawLog:
    import h5py

    from .containers import check_hdf5

    try:
        f = h5py.File(path, "r")
    except READ_ERRORS as exc:
        raise DataError(f"not a readable MATLAB v7.3 (HDF5) file ({one_line(exc)})", src) from None
    try:
        leaves: dict[str, Any] = {}

        def visit(name: str, obj) -> None:
            if isinstance(obj, h5py.Dataset) and not name.startswith(_INTERNAL):
                leaves[name] = obj

        f.visititems(visit)
        return _fields(leaves, columns, src, lambda ds, key, s, text: _decode73(f, ds, key, s, text),
                       check=lambda keys: check_hdf5(f, keys, src),
                       is_text=lambda ds: _matlab_class(ds) in ("char", "cell", "string"))
    except (DataError, InputError):
        raise
    except READ_ERRORS as exc:
        raise DataError(f"cannot read a variable of the MATLAB v7.3 file ({one_line(exc)})", src) from None
    finally:
        f.close()


def _matlab_class(ds) -> str:
    cls = ds.attrs.get("MATLAB_class", b"")
    return cls.decode() if isinstance(cls, bytes) else str(cls)


def _decode73(f, ds, key: str, src: str, text: bool) -> Any:
    """The MATLAB value of dataset ``ds``: a numeric array in MATLAB's dimension order, or
    (``text``) a list of strings from a char matrix or a cell array of char."""
    cls = _matlab_class(ds)
    if cls == "string":
        raise DataError(f"'{key}' {_STRING_FIX}", src)
    if int(np.asarray(ds.attrs.get("MATLAB_empty", 0)).reshape(-1)[0]) and ds.dtype.kind in "ui":
        return [] if text else np.zeros(tuple(int(d) for d in ds[()][::-1]))
    if text:
        if cls == "char":
            _text_size(ds, key, src, 0)
            return _chars(ds[()])
        if cls == "cell":
            import h5py

            from .containers import check_hdf5

            out, total = [], _text_size(ds, key, src, 0, what="cell array")
            for ref in np.asarray(ds[()]).T.reshape(-1, order="F"):
                item = f[ref]
                if not isinstance(item, h5py.Dataset):
                    raise DataError(f"'{key}' is a cell array whose items are not text (a group)", src)
                total = _text_size(item, key, src, total)
                check_hdf5(f, [item.name], src)  # an item is a dataset too: external storage refused
                if _matlab_class(item) != "char" and not int(np.asarray(item.attrs.get("MATLAB_empty", 0)).ravel()[0]):
                    raise DataError(f"'{key}' is a cell array whose items are not text ({_matlab_class(item)})", src)
                out += [""] if int(np.asarray(item.attrs.get("MATLAB_empty", 0)).ravel()[0]) else _chars(item[()])
            return out
        raise DataError(f"'{key}' holds {cls or ds.dtype} values, not text (a char matrix or a cell array of char)",
                        src)
    if cls in ("char", "cell", "struct") or ds.dtype.kind in "OV":
        raise DataError(f"'{key}' is a MATLAB {cls or ds.dtype} variable, not a numeric array", src)
    return np.asarray(ds[()]).T


#: most characters (or cell items) the joint names of a v7.3 file may declare in all
MAX_TEXT = 1 << 16


def _text_size(ds, key: str, src: str, total: int, what: str = "text") -> int:
    """``total`` + the declared size of ``ds``; DataError past :data:`MAX_TEXT` (before reading it)."""
    total += math.prod(ds.shape or ())
    if total > MAX_TEXT:
        raise DataError(f"'{key}' declares {total:.3g} characters or items of {what}, more than joint names need "
                        f"(limit {MAX_TEXT})", src)
    return total


def _chars(codes: np.ndarray) -> list[str]:
    """A MATLAB char matrix (stored reversed: chars × rows, UTF-16 code units) -> one string per row."""
    rows = np.atleast_2d(np.asarray(codes)).T
    return ["".join(map(chr, row)).rstrip(" \x00") for row in rows.astype(np.uint32)]
