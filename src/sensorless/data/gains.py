"""Joint torques from logged motor currents: τ_j = K_j · i_j with per-joint drive gains.

Most arms have no torque sensor; their logs hold motor currents. A drive gain K_j
[N·m/A, joint side] lumps the motor torque constant, the gear ratio and the
efficiency. Gains are given as

* a number (the same for every joint; also ``"2.5"``),
* a list, in the log's joint (column) order,
* a mapping ``{joint name: gain}`` covering every joint,
* a file: JSON (a list, a mapping, or ``{"gains": ...}``) or CSV (``joint,gain`` rows,
  header optional, or one row/column of numbers),
* an inline string: ``"10,10.7,9.6"`` or ``"shoulder=10,elbow=10.7"``.

In a column map the gains ride on the field: ``{"tau": "i_{joint}:gain=10,10.7,..."}``
(``i_*`` is short for ``i_{joint}``). The current is the log's ``current`` field if it
has one, else the field mapped to ``tau``. The reader keeps the current in
``extras["current"]`` and records the gains in ``Trajectory.provenance["gains"]``.
"""

from __future__ import annotations

import csv
import json
from pathlib import Path
from typing import Any, Mapping, Sequence

import numpy as np

from ..errors import DataError, JointNameError, ShapeMismatchError, setting
from .tabular import is_number
from .trajectory import Trajectory

__all__ = ["split_gain_modifiers", "load_gains", "resolve_gains", "currents_to_torques", "no_effort_message"]

_MODIFIER = ":gain="
_GAIN_FIELDS = ("tau", "current")


def split_gain_modifiers(columns: Mapping[str, Any] | None, src: str) -> tuple[dict | None, str | None, str | None]:
    """``columns`` with any ``':gain=...'`` suffix removed and ``*`` patterns turned into
    ``{joint}``; returns ``(columns, gain_text, field_it_was_on)``.

    A list entry carries the suffix on its last item (``'a|b|c:gain=1,2,3'`` split at ``|``).
    """
    if columns is None:
        return None, None, None
    out: dict = {}
    gain, on = None, None
    for field, entry in columns.items():
        items = list(entry) if isinstance(entry, (list, tuple)) else [entry]
        last = items[-1] if items else None
        if isinstance(last, str) and _MODIFIER in last:
            head, _, text = last.rpartition(_MODIFIER)
            if field not in _GAIN_FIELDS:
                raise DataError(f"columns['{field}']: a gain applies only to 'tau' or 'current' columns (currents)", src)
            if gain is not None:
                raise DataError(f"gains are given on both '{on}' and '{field}' columns; give them once", src)
            if not text.strip():
                raise DataError(f"columns['{field}']: empty gain list after ':gain='", src)
            gain, on = text.strip(), field
            items[-1] = head.strip()
        items = [_glob(i) for i in items]
        out[field] = items if isinstance(entry, (list, tuple)) else items[0]
    return out, gain, on


def _glob(item: Any) -> Any:
    """``'i_*'`` -> ``'i_{joint}'`` (one ``*``, no ``{joint}`` already)."""
    if isinstance(item, str) and item.count("*") == 1 and "{joint}" not in item:
        return item.replace("*", "{joint}")
    return item


def load_gains(spec: Any) -> "float | list[float] | dict[str, float]":
    """Parse a gain specification (module docstring) into a number, a list or a mapping."""
    if isinstance(spec, (int, float, np.integer, np.floating)) and not isinstance(spec, bool):
        return float(spec)
    if isinstance(spec, Mapping):
        return {str(k): _number(v, str(k), "<gains>") for k, v in spec.items()}
    if isinstance(spec, Path) or (isinstance(spec, str) and Path(spec).suffix.lower() in (".json", ".csv", ".txt")):
        return _read_file(Path(spec))
    if isinstance(spec, str):
        if Path(spec).exists():  # a file, or a FIFO/device that _read_file refuses
            return _read_file(Path(spec))
        return _parse_inline(spec, "<gains>")
    if isinstance(spec, (Sequence, np.ndarray)):
        return [_number(v, f"#{k}", "<gains>") for k, v in enumerate(spec)]
    raise DataError(f"gains must be a number, a list, a {{joint: gain}} mapping or a file, got {type(spec).__name__}")


def _gain(val: Any, src: str, not_a_number: str, not_finite: str) -> float:
    """``float(val)``, finite and non-zero (else a DataError with the message given for each case)."""
    try:
        out = float(val)
    except (TypeError, ValueError):
        raise DataError(not_a_number, src) from None
    if not np.isfinite(out) or out == 0:
        raise DataError(not_finite, src)
    return out


def _number(val: Any, what: str, src: str) -> float:
    what = f" {what}" if what else ""
    return _gain(val, src, f"gain{what} is not a number: {val!r}",
                 f"gain{what} must be finite and non-zero, got {val!r}")


def _parse_inline(text: str, src: str) -> "list[float] | dict[str, float]":
    parts = [p.strip() for p in text.replace(";", ",").split(",") if p.strip()]
    if not parts:
        raise DataError("empty gain list", src)
    if all("=" in p for p in parts):
        pairs = [p.split("=", 1) for p in parts]
        return {k.strip(): _number(v, k.strip(), src) for k, v in pairs}
    if any("=" in p for p in parts):
        raise DataError(f"gains mix 'joint=gain' and bare numbers: {text!r}", src)
    if len(parts) == 1:  # one number: every joint
        return _number(parts[0], "", src)
    return [_number(p, f"#{k}", src) for k, p in enumerate(parts)]


def _file_number(val: Any, where: str, src: str) -> float:
    """A gain read from a file; the message names the row/key, never the file's text."""
    return _gain(val, src, f"gains file {where}: not a number",
                 f"gains file {where}: a gain must be finite and non-zero")


def _key(name: Any) -> str:
    text = str(name)
    return text if len(text) <= 40 and text.isprintable() else f"key of {len(text)} characters"


def _read_file(path: Path) -> "list[float] | dict[str, float]":
    from .limits import read_small_text

    src = str(path)
    text = read_small_text(path, "gains file")  # a FIFO or device is refused, not waited on
    if path.suffix.lower() == ".json":
        try:
            doc = json.loads(text)
        except ValueError as exc:
            raise DataError(f"not valid JSON ({getattr(exc, 'msg', 'parse error')})", src) from None
        except RecursionError:
            raise DataError("not valid JSON (nested too deeply)", src) from None
        if isinstance(doc, dict) and "gains" in doc:
            doc = doc["gains"]
        if isinstance(doc, dict):
            return {str(k): _file_number(v, f"key '{_key(k)}'", src) for k, v in doc.items()}
        if isinstance(doc, list):
            return [_file_number(v, f"item #{k}", src) for k, v in enumerate(doc)]
        raise DataError("JSON gains must be a list or a {joint: gain} object", src)
    rows = [[c.strip() for c in row] for row in csv.reader(line for line in text.splitlines() if line.strip())]
    rows = [[c for c in row if c] for row in rows if any(row)]
    if not rows:
        raise DataError("gains file is empty", src)
    if all(len(r) == 2 for r in rows):  # joint,gain (optional header)
        body = rows[1:] if not is_number(rows[0][1]) else rows
        first = 2 if body is not rows else 1
        return {r[0]: _file_number(r[1], f"row {i + first}", src) for i, r in enumerate(body)}
    flat = [c for r in rows for c in r]
    if all(len(r) == 1 for r in rows) or len(rows) == 1:
        return [_file_number(c, f"value #{k}", src) for k, c in enumerate(flat)]
    raise DataError("CSV gains must be 'joint,gain' rows or one row/column of numbers", src)


def resolve_gains(gains: Any, joint_names: Sequence[str], src: str = "<gains>") -> np.ndarray:
    """Per-joint gains (n_joints,) in the order of ``joint_names``; a list is in that order."""
    g = load_gains(gains)
    names = list(joint_names)
    if isinstance(g, float):
        return np.full(len(names), g)
    if isinstance(g, list):
        if len(g) != len(names):
            raise ShapeMismatchError(
                f"{len(g)} gains for {len(names)} joints {names}; give one gain per joint in column order "
                "or a {joint: gain} mapping", src)
        return np.asarray(g, dtype=float)
    unknown = [k for k in g if k not in names]
    missing = [j for j in names if j not in g]
    if unknown or missing:
        what = [f"gains name joint(s) {[_key(k) for k in unknown[:5]]} not in the log"] if unknown else []
        what += [f"no gain for joint(s) {missing}"] if missing else []
        raise JointNameError(f"{'; '.join(what)} (log joints: {names})", src)
    return np.array([g[j] for j in names], dtype=float)


def currents_to_torques(traj: Trajectory, gains: Any, current_field: str | None = None) -> Trajectory:
    """``traj`` with ``tau = K · i`` (per joint) and the current kept in ``extras["current"]``.

    ``current_field`` is ``"current"`` or ``"tau"`` (the columns mapped to ``tau`` hold
    currents); by default ``"current"`` if the log has one, else ``"tau"``.
    """
    src = traj.source
    if current_field is None:
        current_field = "current" if "current" in traj.extras else "tau"
    if current_field == "current":
        if "current" not in traj.extras:
            raise DataError("gains given but the log has no 'current' columns", src)
        if traj.tau is not None:
            raise DataError(
                "the log has both torque and current columns; gains would replace the logged torque: "
                f"map only one of them ({setting('columns', {'tau': '...'})} or {setting('columns', {'current': '...'})})",
                src)
        current = np.asarray(traj.extras["current"], dtype=float)
    else:
        if traj.tau is None:
            raise DataError(
                "gains given but the log has no current columns; map them, e.g. "
                f"{setting('columns', {'q': 'pos_{joint}', 'current': 'i_{joint}'})}", src)
        current = np.asarray(traj.tau, dtype=float)
    if current.ndim == 1:
        current = current[:, None]
    if current.ndim != 2 or current.shape[1] != traj.n_joints:
        raise ShapeMismatchError(
            f"current has shape {current.shape}; expected (samples, {traj.n_joints}) for joints {list(traj.joint_names)}",
            src)
    K = resolve_gains(gains, traj.joint_names, src)
    gain_map = {j: float(k) for j, k in zip(traj.joint_names, K)}
    units = {**traj.units, "tau": "N·m (= drive gain × current)", "current": "as logged"}
    prov = {**traj.provenance, "tau": f"current × drive gain (from '{current_field}' columns)", "gains": gain_map}
    return traj.with_(tau=current * K, extras={**traj.extras, "current": current}, units=units, provenance=prov)


def no_effort_message(traj: Trajectory) -> str:
    """Why a log without torque/effort cannot be fitted or scored, and the way out: a log of motor
    currents needs the drive gains (``gains``, τ = K·i per joint)."""
    gains = setting("gains", placeholder="FILE")
    if traj.extras.get("current") is not None:
        return (f"the log has motor currents but no torque/effort: give the drive gains, {gains} (τ = K·i per joint; "
                "`sensorless drive-gains` identifies them from a run with a known payload)")
    return (f"the log has no torque/effort ('tau'); a log of motor currents needs the drive gains, {gains} "
            "(τ = K·i per joint), and its current columns mapped (columns 'current=...')")
