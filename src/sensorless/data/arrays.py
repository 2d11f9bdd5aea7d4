"""Array files: NPZ archives and HDF5 files, read into a :class:`~sensorless.data.names.RawLog`.

Each field is the array named in ``columns`` (HDF5: a dataset path such as ``run/q``, or a
last component that is unique), else the first recognised name
(:data:`~sensorless.data.names.FIELD_NAMES`). Contact flags/forces and the IMU
accelerometer are read under their fixed names (:data:`EXTRA_KEYS`); joint names from
``joint_names`` (a dataset, or an attribute of the HDF5 root). Every other array is named
in the reader's unused-array warning.
"""

from __future__ import annotations

import tokenize
import zipfile
import zlib
from pathlib import Path
from typing import Any, Mapping

import numpy as np

from ..errors import DataError, InputError, ShapeMismatchError, setting
from .containers import check_hdf5, check_npz
from .imu import IMU_KEY
from .names import FIELD_NAMES, JOINT_NAME_KEYS, RawLog, pick_key, short_list
from .trajectory import as_float_array

__all__ = ["read_npz", "read_hdf5", "EXTRA_KEYS", "READ_ERRORS", "one_line", "joint_names_of", "as_float", "flat_keys",
           "join_parts", "pick_fields"]

#: Per-sample contact data of legged-robot logs, flags (N, n_feet) and measured contact forces
#: (N, n_feet, 3 or 6) in the order of the contact frames, and the base IMU accelerometer (N, 3).
EXTRA_KEYS = ("contact", "contact_forces", IMU_KEY)

#: What a corrupt NPZ/HDF5 member can raise on read (zlib, zip, h5py/HDF5 and numpy errors).
#: numpy parses a corrupt .npy header with tokenize/ast (TokenError, SyntaxError) and may try to
#: allocate what a corrupt header declares (MemoryError).
READ_ERRORS = (OSError, ValueError, EOFError, KeyError, RuntimeError, TypeError, IndexError, AttributeError,
               OverflowError, MemoryError, SyntaxError, tokenize.TokenError, zipfile.BadZipFile, zlib.error)


def one_line(exc: BaseException) -> str:
    text = " ".join(str(exc).split())
    return f"{type(exc).__name__}: {text[:300]}" if text else type(exc).__name__


def as_float(arr: Any, src: str, key: str, allow_bool: bool = False, max_dim: int = 2) -> np.ndarray:
    out = as_float_array(arr, key, src, allow_bool=allow_bool)
    if out.ndim > max_dim:
        raise ShapeMismatchError(f"array '{key}' has shape {out.shape}; expected 1-D or 2-D", src)
    return out


def joint_names_of(raw: Any, src: str, key: str = "joint_names") -> list[str]:
    """Joint names stored in a file: a 1-D array of strings (bytes are decoded)."""
    arr = np.atleast_1d(np.asarray(raw))
    if arr.ndim == 2 and 1 in arr.shape:
        arr = arr.reshape(-1)
    if arr.ndim != 1 or arr.dtype.kind not in "USO":
        raise DataError(f"'{key}' must be a 1-D array of strings, got dtype {arr.dtype} shape {arr.shape}", src)
    try:
        return [n.decode() if isinstance(n, bytes) else str(n) for n in arr]
    except UnicodeDecodeError:
        raise DataError(f"'{key}' are not valid UTF-8", src) from None


def missing_q(keys: list[str], src: str) -> DataError:
    return DataError(f"no joint positions found (looked for {list(FIELD_NAMES['q'])}); available: {short_list(keys)}; "
                     f"say which array holds them: {setting('columns', {'q': 'NAME'})}", src)


def pick_fields(keys: list[str], columns: Mapping | None, src: str, base=lambda k: k) -> dict[str, tuple[str, ...]]:
    """field -> the array(s) it is read from: one, or several a ``columns`` entry lists with commas
    (``base_q=base_position,base_rpy``: their columns side by side, :func:`join_parts`)."""
    out = {}
    for f in FIELD_NAMES:
        spec = columns.get(f) if columns is not None else None
        if isinstance(spec, str) and "," in spec:
            out[f] = tuple(pick_key(f, keys, {f: part}, src, base) for part in spec.split(","))
        elif (k := pick_key(f, keys, columns, src, base)) is not None:
            out[f] = (k,)
    return out


def join_parts(parts: list[np.ndarray], src: str, keys) -> np.ndarray:
    """One array from the arrays of :func:`pick_fields`: side by side along the channel axis (each part's
    shorter axis; the sample axis is the longer one and must agree)."""
    if len(parts) == 1:
        return parts[0]
    two = [p.reshape(-1, 1) if p.ndim == 1 else p for p in parts]
    if any(p.ndim != 2 for p in two):
        raise ShapeMismatchError(f"arrays {list(keys)} must each be 1-D or 2-D to be joined", src)
    along = [int(np.argmax(p.shape)) for p in two]
    n = {p.shape[a] for p, a in zip(two, along)}
    if len(n) > 1:
        raise ShapeMismatchError(f"arrays {list(keys)} have different sample counts {sorted(n)}; they cannot be "
                                 "joined", src)
    return np.hstack([p if a == 0 else p.T for p, a in zip(two, along)])


def flat_keys(picked: dict) -> list[str]:
    """Every array key :func:`pick_fields` picked."""
    return [k for ks in picked.values() for k in ks]


def read_npz(path: Path, columns: Mapping | None) -> RawLog:
    src = str(path)
    try:
        archive = np.load(path, allow_pickle=False)
    except READ_ERRORS as exc:
        raise DataError(f"not a readable NPZ archive ({one_line(exc)})", src) from None
    if not isinstance(archive, np.lib.npyio.NpzFile):
        raise DataError("holds a single array (.npy), not an NPZ archive of named arrays", src)
    with archive as z:
        keys = list(z.files)
        picked = pick_fields(keys, columns, src)
        extra = [k for k in EXTRA_KEYS if k in keys]
        name_key = pick_key("joint_names", keys, columns, src, names=JOINT_NAME_KEYS)
        check_npz(path, src, [*flat_keys(picked), *extra])
        try:
            arrays = {field: join_parts([as_float(z[k], src, k) for k in ks], src, ks) for field, ks in picked.items()}
            extras = {k: z[k] for k in extra}
            names = joint_names_of(z[name_key], src, name_key) if name_key else None
        except (DataError, InputError):
            raise
        except READ_ERRORS as exc:  # pickled/object or corrupt member (zlib.error, BadZipFile...)
            raise DataError(f"cannot read an array from the NPZ archive ({one_line(exc)})", src) from None
    if "q" not in arrays:
        raise missing_q(keys, src)
    used = {*flat_keys(picked), *extra, name_key}
    unused = [k for k in keys if k not in used]
    return RawLog(arrays, names, {f: ",".join(ks) for f, ks in picked.items()}, extras, unused,
                  [k for k in unused if _npz_text(path, k)])


def _npz_text(path: Path, key: str) -> bool:
    """Whether NPZ member ``key`` holds strings (its header only)."""
    import zipfile

    try:
        with zipfile.ZipFile(path) as zf, zf.open(key + ".npy") as fh:
            major, _ = np.lib.format.read_magic(fh)
            read = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
            _, _, dtype = read(fh)
    except (OSError, ValueError, KeyError, zipfile.BadZipFile):
        return False
    return dtype.kind in "US"


def read_hdf5(path: Path, columns: Mapping | None) -> RawLog:
    import h5py

    src = str(path)
    try:
        f = h5py.File(path, "r")
    except READ_ERRORS as exc:
        raise DataError(f"not a readable HDF5 file ({one_line(exc)})", src) from None
    try:
        return _hdf5_fields(f, src, columns)
    except (DataError, InputError):
        raise
    except READ_ERRORS as exc:  # corrupt dataset, bad link, undecodable names...
        raise DataError(f"cannot read a dataset from the HDF5 file ({one_line(exc)})", src) from None
    finally:
        f.close()


def _hdf5_fields(f, src: str, columns: Mapping | None) -> RawLog:
    import h5py

    keys: list[str] = []
    f.visititems(lambda name, obj: keys.append(name) if isinstance(obj, h5py.Dataset) else None)
    base = lambda k: k.rsplit("/", 1)[-1]  # noqa: E731
    picked = pick_fields(keys, columns, src, base)
    extra = [k for k in EXTRA_KEYS if k in keys]
    name_key = pick_key("joint_names", keys, columns, src, base, names=JOINT_NAME_KEYS)
    check_hdf5(f, [*flat_keys(picked), *extra, *([name_key] if name_key else [])], src)
    arrays = {field: join_parts([as_float(f[k][()], src, k) for k in ks], src, ks) for field, ks in picked.items()}
    names = None
    if name_key is not None:
        names = joint_names_of(f[name_key][()], src, name_key)
    elif "joint_names" in f.attrs:
        names = joint_names_of(f.attrs["joint_names"], src)
    if "q" not in arrays:
        raise missing_q(keys, src)
    used = {*flat_keys(picked), *extra, name_key}
    unused = [k for k in keys if k not in used]
    return RawLog(arrays, names, {fl: ",".join(ks) for fl, ks in picked.items()}, {k: f[k][()] for k in extra}, unused,
                  [k for k in unused if f[k].dtype.kind in "SUO"])
