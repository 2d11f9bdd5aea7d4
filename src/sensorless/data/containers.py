"""What NPZ and HDF5 files declare, checked before anything is allocated.

* NPZ: each member's uncompressed size (zip directory) and the shape × item size its ``.npy``
  header declares; a member that expands past the memory budget (a zip bomb) is refused by
  name with both sizes.
* HDF5: each dataset's shape × item size (a 2 KB file can declare terabytes of fill value);
  datasets with external raw storage (bytes of another file) or virtual datasets (other files'
  datasets; a missing source reads as the fill value) are refused unless ``allow_external``.
"""

from __future__ import annotations

import math
import tokenize
import zipfile
import zlib
from pathlib import Path
from typing import Iterable

import numpy as np

from ..errors import DataError, InputError, setting
from .limits import FIXES, check_log_size, current_options, format_size, memory_budget

__all__ = ["check_npz", "check_hdf5"]


def _npy_shape(zf: zipfile.ZipFile, info: zipfile.ZipInfo, src: str) -> tuple[tuple[int, ...], np.dtype]:
    from numpy.lib import format as npf

    with zf.open(info) as fh:
        version = npf.read_magic(fh)
        shape, _, dtype = (npf.read_array_header_1_0(fh) if version == (1, 0) else npf.read_array_header_2_0(fh))
    return tuple(int(s) for s in shape), dtype


def check_npz(path: Path, src: str, members: Iterable[str], max_memory=None) -> None:
    """Refuse an NPZ whose ``members`` (names without ``.npy``) declare more than the budget."""
    wanted = {m + ".npy" for m in members}
    limit, origin = memory_budget(max_memory)
    total, bomb = 0, ""
    try:
        with zipfile.ZipFile(path) as zf:
            for info in zf.infolist():
                if info.filename not in wanted:
                    continue
                name = info.filename[:-4]
                if info.file_size > limit:
                    ratio = info.file_size / max(info.compress_size, 1)
                    raise InputError(
                        f"{src}: array '{name}' expands from {format_size(info.compress_size)} to "
                        f"{format_size(info.file_size)} (zip directory" + (f"; {ratio:.0f}:1, a zip bomb?" if ratio > 50
                                                                           else "") +
                        f"), over the limit of {format_size(limit)} ({origin}); {FIXES}")
                shape, dtype = _npy_shape(zf, info, src)
                n = math.prod(shape)
                if n * dtype.itemsize > info.file_size:
                    raise DataError(f"array '{name}' declares shape {shape} ({format_size(n * dtype.itemsize)}) but "
                                    f"holds {format_size(info.file_size)}; the archive is corrupt", src)
                if dtype.kind in "biufc":
                    total += n
                    if info.file_size > 50 * max(info.compress_size, 1) and info.file_size > 1 << 26:
                        bomb = f" ('{name}' is compressed {info.file_size / max(info.compress_size, 1):.0f}:1)"
    except (InputError, DataError):
        raise
    except (OSError, ValueError, EOFError, zipfile.BadZipFile, KeyError, SyntaxError, OverflowError, zlib.error,
            tokenize.TokenError, TypeError, RuntimeError) as exc:  # RuntimeError: zipfile's NotImplementedError
        # for an unknown compression method or encryption flag
        raise DataError(f"not a readable NPZ archive ({type(exc).__name__}: {' '.join(str(exc).split())[:200]})",
                        src) from None
    check_log_size(src, total, f"{total:.3g} numbers{bomb}", max_memory)


def check_hdf5(f, keys: Iterable[str], src: str, allow_external: bool | None = None, max_memory=None) -> None:
    """Refuse external/virtual datasets among ``keys`` (unless allowed) and a total declared size over budget."""
    if allow_external is None:
        allow_external = bool(current_options().get("allow_external", False))
    total = 0
    for key in keys:
        dset = f[key]
        if not allow_external:
            if dset.is_virtual:
                raise InputError(f"{src}: dataset '{key}' is a virtual dataset (its data live in other files; a "
                                 f"missing source reads as zeros); refused — read it with {setting('allow_external', True)}")
            if dset.id.get_create_plist().get_external_count() > 0:
                raise InputError(f"{src}: dataset '{key}' has external raw storage (its bytes are read from another "
                                 f"file); refused — read it with {setting('allow_external', True)}")
        total += math.prod(dset.shape or ())
    check_log_size(src, total, f"its datasets ({total:.3g} numbers)", max_memory)
