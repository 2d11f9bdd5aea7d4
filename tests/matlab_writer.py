"""Write MATLAB v7.3 files with h5py the way MATLAB's ``save -v7.3`` lays them out (for the tests).

* a 512-byte user block starting with MATLAB's 128-byte text header;
* every array stored column-major: the dataset holds the MATLAB array with reversed dimensions
  (an N × n matrix is an (n, N) dataset; a row vector 1 × N is (N, 1));
* ``MATLAB_class`` attributes (fixed-length ASCII): double, logical, char, cell, struct, string;
* char arrays as uint16 UTF-16 code units with ``MATLAB_int_decode = 2``;
* cell arrays as object references to datasets in the ``#refs#`` group (which also holds
  MATLAB's canonical empty ``a``);
* structs as groups (``MATLAB_fields`` lists the field names);
* ``string`` objects as opaque uint32 data with ``MATLAB_object_decode = 3``.
"""

from __future__ import annotations

import struct
from pathlib import Path

import h5py
import numpy as np


class MatlabString(list):
    """A MATLAB ``string`` array (R2016b+): written as the opaque object MATLAB writes."""


class CellStr(list):
    """A 1 × n cell array of char."""


def _cls(obj, name: str) -> None:
    obj.attrs.create("MATLAB_class", np.bytes_(name))


def _char(group, name: str, text: str):
    codes = np.array([[ord(c)] for c in text], dtype=np.uint16).reshape(len(text), 1)  # 1 × n char -> (n, 1)
    ds = group.create_dataset(name, data=codes)
    _cls(ds, "char")
    ds.attrs.create("MATLAB_int_decode", np.int32(2))
    return ds


def _char_matrix(group, name: str, rows: list[str]):
    width = max(len(r) for r in rows)
    codes = np.array([[ord(c) for c in r.ljust(width)] for r in rows], dtype=np.uint16)  # rows × width
    ds = group.create_dataset(name, data=codes.T)  # stored reversed
    _cls(ds, "char")
    ds.attrs.create("MATLAB_int_decode", np.int32(2))
    return ds


class _Refs:
    def __init__(self, f):
        self.group = f.create_group("#refs#")
        empty = self.group.create_dataset("a", data=np.zeros(2, dtype=np.uint64))
        _cls(empty, "canonical empty")
        empty.attrs.create("MATLAB_empty", np.uint8(1))
        self.n = 1

    def name(self) -> str:
        self.n += 1
        k, out = self.n - 1, ""
        while True:
            out = chr(ord("a") + k % 26) + out
            k = k // 26 - 1
            if k < 0:
                return out


def _put(group, name: str, val, refs: _Refs) -> None:
    if isinstance(val, dict):
        sub = group.create_group(name)
        _cls(sub, "struct")
        fields = np.empty(len(val), dtype=h5py.vlen_dtype(np.dtype("S1")))
        for i, key in enumerate(val):
            fields[i] = np.frombuffer(key.encode(), dtype="S1")
        sub.attrs.create("MATLAB_fields", fields)
        for key, item in val.items():
            _put(sub, key, item, refs)
    elif isinstance(val, MatlabString):
        ds = group.create_dataset(name, data=np.array([[3707764736, 2, 1, 1, len(val), 1]], dtype=np.uint32).T)
        _cls(ds, "string")
        ds.attrs.create("MATLAB_object_decode", np.int32(3))
    elif isinstance(val, CellStr):
        ids = []
        for item in val:
            ids.append(_char(refs.group, refs.name(), item).ref)
        ds = group.create_dataset(name, data=np.array(ids, dtype=h5py.ref_dtype).reshape(len(val), 1))
        _cls(ds, "cell")
    elif isinstance(val, str):
        _char(group, name, val)
    elif isinstance(val, list):  # a char matrix, one name per row
        _char_matrix(group, name, val)
    else:
        arr = np.asarray(val)
        if arr.ndim == 1:
            arr = arr[:, None]  # MATLAB has no 1-D arrays: a column vector
        ds = group.create_dataset(name, data=np.ascontiguousarray(arr.T))
        _cls(ds, "logical" if arr.dtype == bool else "double")


def write_mat73(path: Path, variables: dict) -> Path:
    """``variables`` (name -> MATLAB value as MATLAB shows it: an ndarray, a str, a list of str
    (char matrix), :class:`CellStr`, :class:`MatlabString` or a dict (struct)) as ``save -v7.3`` would."""
    path = Path(path)
    with h5py.File(path, "w", userblock_size=512, libver="earliest") as f:
        refs = _Refs(f)
        for name, val in variables.items():
            _put(f, name, val, refs)
    text = b"MATLAB 7.3 MAT-file, Platform: GLNXA64, Created on: Mon Jan  1 00:00:00 2024 HDF5 schema 1.00 ."
    header = text.ljust(116) + b"\x00" * 8 + struct.pack("<H", 0x0200) + b"IM"
    with open(path, "r+b") as fh:
        fh.write(header.ljust(512, b"\x00"))
    return path
