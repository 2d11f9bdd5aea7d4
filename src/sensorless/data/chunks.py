"""Logs read a chunk of samples at a time, never whole (the streamed identification of long logs).

A :class:`ChunkedLog` names its per-sample fields (``t``, ``q``, ``v``, ``tau``: the recognised
names of :mod:`.names`, e.g. ``dq`` → ``v``) and yields row ranges of any of them:

* ``.npz``: each member is an ``.npy`` file inside the zip; its header (``numpy.lib.format``)
  gives dtype, shape and order, and its rows are read from the member's stream (stored members
  are seekable; deflated ones decompress as they are read), C order only;
* ``.parquet``: ``pyarrow.parquet.ParquetFile.iter_batches`` over the needed columns (a time
  column and per-joint columns named by a pattern such as ``q_{joint}``, :func:`~.tabular.detect_patterns`);
* ``.h5`` / ``.hdf5``: top-level datasets sliced by rows (h5py).

:func:`open_chunked` returns None for a file whose layout it does not know (then the whole-log
readers apply). Values are float64; nothing here validates them (the streamed pipeline checks
every chunk and names the sample index in the whole log).
"""

from __future__ import annotations

import zipfile
import zlib
from pathlib import Path
from typing import Iterator, Sequence

import numpy as np

from ..errors import DataError, SensorlessError
from .names import field_of

__all__ = ["CHUNK_FIELDS", "ChunkedLog", "open_chunked"]

#: the per-sample fields a chunked log provides (the streamed path needs all of them)
CHUNK_FIELDS = ("t", "q", "v", "tau")


class ChunkedLog:
    """A log read by row ranges: ``n_samples``, ``width[field]`` (columns; 1 for ``t``) and
    :meth:`chunks`. Subclasses implement :meth:`_rows`."""

    def __init__(self, path: Path, n_samples: int, width: dict[str, int], joint_names: Sequence[str]):
        self.path, self.n_samples, self.width, self.joint_names = Path(path), int(n_samples), dict(width), list(joint_names)

    def chunks(self, fields: Sequence[str], size: int, start: int = 0, stop: int | None = None
               ) -> Iterator[tuple[int, dict[str, np.ndarray]]]:
        """(first sample index, {field: (n, width) float64 rows, ``t`` 1-D}) for consecutive ranges of
        ``size`` samples over [start, stop)."""
        stop = self.n_samples if stop is None else min(stop, self.n_samples)
        for s, part in self._rows(list(fields), int(size), int(start), stop):
            yield s, part

    def column(self, field: str, j: int = 0, size: int = 65536) -> np.ndarray:
        """One column of a field over the whole log (N,), read chunk by chunk."""
        out = np.empty(self.n_samples)
        for s, part in self.chunks([field], size):
            x = part[field]
            out[s : s + len(x)] = x if x.ndim == 1 else x[:, j]
        return out

    def _rows(self, fields, size, start, stop):  # pragma: no cover - abstract
        raise NotImplementedError


class _Npz(ChunkedLog):
    def __init__(self, path: Path, members: dict[str, str], headers: dict[str, tuple], n: int, joint_names):
        self._members, self._headers = members, headers
        width = {f: (1 if len(h[2]) == 1 else int(h[2][1])) for f, h in headers.items()}
        super().__init__(path, n, width, joint_names)

    def _rows(self, fields, size, start, stop):
        with zipfile.ZipFile(self.path) as zf, open(self.path, "rb") as raw:
            streams = {}
            for f in fields:
                info = zf.getinfo(self._members[f])
                offset, dtype, shape = self._headers[f]
                row = dtype.itemsize * (1 if len(shape) == 1 else int(shape[1]))
                if info.compress_type == zipfile.ZIP_STORED:  # the bytes as they are in the file: seek, read
                    raw.seek(info.header_offset)
                    head = raw.read(30)
                    data = info.header_offset + 30 + int.from_bytes(head[26:28], "little") + \
                        int.from_bytes(head[28:30], "little")
                    streams[f] = (None, data + offset + start * row, dtype, shape, row)
                else:  # deflated: decompressed in order
                    fh = zf.open(info)
                    fh.seek(offset + start * row)
                    streams[f] = (fh, 0, dtype, shape, row)
            try:
                for s in range(start, stop, size):
                    n = min(size, stop - s)
                    part = {}
                    for f, (fh, pos, dtype, shape, row) in streams.items():
                        if fh is None:
                            raw.seek(pos + (s - start) * row)
                            buf = raw.read(n * row)
                        else:
                            buf = fh.read(n * row)
                        x = np.frombuffer(buf, dtype=dtype).astype(float)
                        part[f] = x if len(shape) == 1 else x.reshape(n, shape[1])
                    yield s, part
            finally:
                for fh, *_ in streams.values():
                    if fh is not None:
                        fh.close()


def _npz(path: Path, joint_names) -> "ChunkedLog | None":
    with zipfile.ZipFile(path) as zf:
        members, headers, names = {}, {}, None
        for info in zf.infolist():
            key = info.filename[:-4] if info.filename.endswith(".npy") else info.filename
            with zf.open(info) as fh:
                major, _ = np.lib.format.read_magic(fh)
                read = np.lib.format.read_array_header_1_0 if major == 1 else np.lib.format.read_array_header_2_0
                shape, fortran, dtype = read(fh)
                offset = fh.tell()
                if key == "joint_names":
                    names = [str(x) for x in np.lib.format.read_array(fh, allow_pickle=False)]
                    continue
            fld = field_of(key)
            if fld not in CHUNK_FIELDS or fld in members:
                return None  # another field (a, base, extras ...) or two spellings of one: the whole-log readers
            if fortran or dtype.kind not in "fiu" or len(shape) not in (1, 2) or (fld == "t") != (len(shape) == 1):
                return None
            members[fld], headers[fld] = info.filename, (offset, dtype, shape)
    return _checked(path, headers, names, joint_names, lambda h: h[2], lambda n: _Npz(path, members, headers, n, _names(names, joint_names)))


def _names(names, joint_names):
    return list(names) if names is not None else list(joint_names)


def _checked(path, headers, names, joint_names, shape_of, make) -> "ChunkedLog | None":
    if set(headers) != set(CHUNK_FIELDS):
        return None
    n = {shape_of(h)[0] for h in headers.values()}
    cols = {shape_of(h)[1] for f, h in headers.items() if f != "t"}
    if len(n) != 1 or len(cols) != 1 or cols != {len(joint_names)}:
        return None
    if names is not None and list(names) != list(joint_names):
        return None  # a log in another joint order: the whole-log readers reorder it
    return make(n.pop())


class _H5(ChunkedLog):
    def __init__(self, path, datasets: dict[str, str], n: int, width, joint_names):
        self._datasets = datasets
        super().__init__(path, n, width, joint_names)

    def _rows(self, fields, size, start, stop):
        import h5py

        with h5py.File(self.path, "r") as h:
            for s in range(start, stop, size):
                e = min(s + size, stop)
                yield s, {f: np.asarray(h[self._datasets[f]][s:e], dtype=float) for f in fields}


def _h5(path: Path, joint_names) -> "ChunkedLog | None":
    try:
        import h5py
    except ImportError:
        return None
    from .containers import check_hdf5

    with h5py.File(path, "r") as h:
        found, shapes, names = {}, {}, None
        check_hdf5(h, [k for k, obj in h.items() if isinstance(obj, h5py.Dataset)], str(path))  # external data
        for key, obj in h.items():
            if not isinstance(obj, h5py.Dataset):
                return None
            if key == "joint_names":
                names = [x.decode() if isinstance(x, bytes) else str(x) for x in obj[()]]
                continue
            fld = field_of(key)
            if fld not in CHUNK_FIELDS or fld in found or obj.dtype.kind not in "fiu" or obj.ndim != (1 if fld == "t" else 2):
                return None
            found[fld], shapes[fld] = key, obj.shape
    width = {f: (1 if len(s) == 1 else s[1]) for f, s in shapes.items()}
    return _checked(path, shapes, names, joint_names, lambda s: (s[0], s[1] if len(s) > 1 else None),
                    lambda n: _H5(path, found, n, width, _names(names, joint_names)))


class _Parquet(ChunkedLog):
    def __init__(self, path, columns: dict[str, list[str]], n: int, joint_names):
        self._columns = columns
        super().__init__(path, n, {f: len(c) for f, c in columns.items()}, joint_names)

    def _rows(self, fields, size, start, stop):
        import pyarrow.parquet as pq

        names = [c for f in fields for c in self._columns[f]]
        pf = pq.ParquetFile(self.path, page_checksum_verification=True)
        try:
            yield from self._batches(pf, names, fields, size, start, stop)
        except OSError as exc:  # a page failing its CRC, a truncated file: named, never half a fit
            raise DataError(f"not a readable Parquet file ({type(exc).__name__}: {exc})", str(self.path)) from None

    def _batches(self, pf, names, fields, size, start, stop):
        s = 0
        for batch in pf.iter_batches(batch_size=size, columns=names):
            n = batch.num_rows
            if s + n <= start:
                s += n
                continue
            lo, hi = max(start - s, 0), min(stop - s, n)
            cols = {c: batch.column(c).to_numpy(zero_copy_only=False).astype(float)[lo:hi] for c in names}
            yield s + lo, {f: (cols[self._columns[f][0]] if f == "t" else
                               np.column_stack([cols[c] for c in self._columns[f]])) for f in fields}
            s += n
            if s >= stop:
                return


def _parquet(path: Path, joint_names) -> "ChunkedLog | None":
    try:
        import pyarrow.parquet as pq
    except ImportError:
        return None
    from .tabular import detect_patterns

    pf = pq.ParquetFile(path, page_checksum_verification=True)
    avail = list(pf.schema_arrow.names)
    times = [c for c in avail if field_of(c) == "t"]
    pats = detect_patterns(avail) or {}
    if len(times) != 1:
        return None
    cols: dict[str, list[str]] = {"t": times}
    for fld in ("q", "v", "tau"):
        pat = pats.get(fld)
        if pat is None:
            return None
        cols[fld] = [pat.replace("{joint}", j) for j in joint_names]
        if any(c not in avail for c in cols[fld]):
            return None
    used = {c for v in cols.values() for c in v}
    if set(avail) - used:
        return None  # columns the whole-log reader would use or name in a warning
    return _Parquet(path, cols, pf.metadata.num_rows, joint_names)


def open_chunked(path, joint_names: Sequence[str]) -> "ChunkedLog | None":
    """A chunked reader of ``path`` when its format and layout are known (module docstring): exactly
    the fields t, q, v, tau (recognised names), joint columns in ``joint_names`` order (robot
    order: an npz/h5 ``joint_names`` array must match it); else None. A FIFO, device or socket is an
    InputError before anything opens it, an HDF5 dataset with external or virtual storage one without
    ``allow_external`` (:func:`~.containers.check_hdf5`), as for the whole-log readers."""
    from ..io import check_input_file

    p = Path(path)
    if p.is_dir() or not (p.exists() or p.is_symlink()):  # a folder of per-signal files, or missing: read whole
        return None
    check_input_file(p, "log file")  # a FIFO or device would block or never end
    suffix = p.suffix.lower()
    try:
        if suffix == ".npz":
            return _npz(p, joint_names)
        if suffix in (".h5", ".hdf5"):
            return _h5(p, joint_names)
        if suffix in (".parquet", ".pq"):
            return _parquet(p, joint_names)
    except SensorlessError:
        raise
    except (OSError, ValueError, KeyError, EOFError, zipfile.BadZipFile, zlib.error):
        return None  # the whole-log readers raise their typed error for the same file
    return None
