"""The sample records of ``sensorless stream``: one sample in, one estimate out.

Input record, per sample (joint arrays in the model's joint order)::

    seq, t, q[0..nj), v[0..nj), tau[0..na)

``seq`` is a sample counter (consecutive integers: a gap is a dropped sample), ``t`` the sample
time [s], q [rad or m], v [rad/s or m/s], tau the measured torque/effort of the ``na`` actuated
joints [N·m or N]. Output record::

    seq, t, tau_ext[0..m), fx, fy, fz (with a frame), contact

tau_ext the external torque of the ``m`` monitored joints (the signs and rows of
``sensorless monitor``; NaN in the observer warm-up), F the force at the frame [N] (NaN where
unobservable or in the warm-up), contact 1.0 or 0.0. A sample the monitor refuses (non-finite or
out of range, :mod:`.guard`) is answered with NaN estimates and contact 1.0.

A CSV line is at most :func:`max_line` bytes (longer lines are bad records, never buffered whole).

Two encodings of the same fields:

* ``csv``: one line per record, fields separated by commas (lines starting with ``#`` and
  blank lines are ignored on input; the output starts with a ``#`` header naming the fields);
* ``binary``: the fields as consecutive little-endian IEEE-754 float64 (``<f8``), no header,
  no padding: an input record is 8·(2 + 2 nj + na) bytes (160 for a 6-joint arm), an output
  record 8·(3 + m + 3) bytes with a frame. ``seq`` is an exact integer up to 2⁵³.

Over UDP each datagram carries one record (CSV: one line); an empty datagram ends the stream.
"""

from __future__ import annotations

import math
import struct
from dataclasses import dataclass

import numpy as np

from ..errors import DataError

__all__ = ["FORMATS", "RecordLayout", "max_line"]

FORMATS = ("csv", "binary")


def max_line(n_fields: int) -> int:
    """Longest CSV input line read for a record of ``n_fields`` fields [bytes]: 64 per field + 4 KiB."""
    return 4096 + 64 * n_fields


@dataclass(frozen=True)
class RecordLayout:
    """Field names and sizes of the input and output records (module docstring)."""

    joints: tuple[str, ...]  # q and v, in this order
    actuated: tuple[str, ...]  # tau
    monitored: tuple[str, ...]  # tau_ext
    force: tuple[str, ...] = ()  # ("fx", "fy", "fz") with a frame

    @property
    def n_in(self) -> int:
        return 2 + 2 * len(self.joints) + len(self.actuated)

    @property
    def n_out(self) -> int:
        return 3 + len(self.monitored) + len(self.force)

    @property
    def in_bytes(self) -> int:
        return 8 * self.n_in

    @property
    def out_bytes(self) -> int:
        return 8 * self.n_out

    def input_fields(self) -> list[str]:
        return (["seq", "t"] + [f"q[{j}]" for j in self.joints] + [f"v[{j}]" for j in self.joints]
                + [f"tau[{j}]" for j in self.actuated])

    def output_fields(self) -> list[str]:
        return ["seq", "t"] + [f"tau_ext[{j}]" for j in self.monitored] + list(self.force) + ["contact"]

    def describe(self) -> dict:
        """The record layout as recorded in the summary (JSON-able)."""
        return {"input_fields": self.input_fields(), "output_fields": self.output_fields(),
                "binary": {"dtype": "<f8", "input_bytes": self.in_bytes, "output_bytes": self.out_bytes}}

    # ---- input --------------------------------------------------------------------------
    def parse_csv(self, line: bytes, index: int, out: np.ndarray) -> bool:
        """Fill ``out`` (n_in,) from one CSV line; False for a comment/blank line; DataError naming
        the record ``index`` and the field when a value is missing, extra or not a number, or seq or t
        is not finite (a non-finite q, v or τ is the monitor's to refuse: :mod:`.guard`)."""
        text = line.strip()
        if not text or text.startswith(b"#"):
            return False
        parts = text.split(b",")
        if len(parts) != self.n_in:
            raise DataError(f"record {index}: {len(parts)} comma-separated fields, expected {self.n_in} "
                            f"(seq, t, q×{len(self.joints)}, v×{len(self.joints)}, tau×{len(self.actuated)})")
        for k, p in enumerate(parts):
            try:
                x = float(p)
            except ValueError:
                raise DataError(f"record {index}, field {self.input_fields()[k]}: "
                                f"{p.decode(errors='replace').strip()!r} is not a number") from None
            if k < 2 and not math.isfinite(x):
                raise DataError(f"record {index}, field {self.input_fields()[k]}: {x} is not finite")
            out[k] = x
        return True

    def parse_binary(self, data: bytes, index: int, out: np.ndarray) -> None:
        """Fill ``out`` from one binary record; DataError naming the record for a wrong size or a
        non-finite seq or t."""
        if len(data) != self.in_bytes:
            raise DataError(f"record {index}: {len(data)} bytes, expected {self.in_bytes} "
                            f"({self.n_in} little-endian float64: seq, t, q×{len(self.joints)}, "
                            f"v×{len(self.joints)}, tau×{len(self.actuated)})")
        out[:] = np.frombuffer(data, dtype="<f8")
        if not np.isfinite(out[:2]).all():
            k = int(np.flatnonzero(~np.isfinite(out[:2]))[0])
            raise DataError(f"record {index}, field {self.input_fields()[k]}: {out[k]} is not finite")

    # ---- output -------------------------------------------------------------------------
    def csv_header(self) -> bytes:
        return ("# " + ",".join(self.output_fields()) + "\n").encode()

    def format_csv(self, rec: np.ndarray) -> bytes:
        """One output line: seq as an integer, values with 17 significant digits (exact), contact 0/1."""
        vals = ",".join(repr(float(x)) for x in rec[1:-1])
        return f"{int(rec[0])},{vals},{int(rec[-1])}\n".encode()

    def format_binary(self, rec: np.ndarray) -> bytes:
        return np.asarray(rec, dtype="<f8").tobytes()

    def encode_input(self, seq: int, t: float, q, v, tau, fmt: str) -> bytes:
        """One input record (for senders and tests): ``fmt`` "csv" or "binary"."""
        vals = [float(seq), float(t), *map(float, q), *map(float, v), *map(float, tau)]
        if len(vals) != self.n_in:
            raise DataError(f"a record needs {len(self.joints)} q, {len(self.joints)} v and {len(self.actuated)} tau "
                            f"values, got {len(vals) - 2} values")
        if fmt == "binary":
            return struct.pack(f"<{self.n_in}d", *vals)
        return (f"{int(seq)}," + ",".join(repr(x) for x in vals[1:]) + "\n").encode()

    def decode_output(self, data: bytes, fmt: str) -> np.ndarray:
        """One output record as floats (for receivers and tests)."""
        if fmt == "binary":
            return np.frombuffer(data, dtype="<f8").copy()
        return np.array([float(x) for x in data.strip().split(b",")])
