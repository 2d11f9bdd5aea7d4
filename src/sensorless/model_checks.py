"""Sanity checks of robot model files and loaded Pinocchio models, with one-line typed errors.

URDF files are pre-parsed with :mod:`xml.etree.ElementTree` before Pinocchio sees them, so
a malformed file gives one line naming the element instead of urdfdom's multi-line C++
messages, and values urdfdom accepts silently are refused: masses and inertias that are not
finite numbers, negative masses, joint axes of zero length, lower limits above upper
limits. An inertia matrix that is not positive semi-definite only warns
(:class:`~sensorless.errors.RobotModelWarning`): it loads, but no real body has it.
:func:`check_model` repeats the numeric checks on any loaded Pinocchio model (URDF, MJCF,
example-robot-data). :func:`quiet_stderr` captures what C++ code writes to file
descriptor 2 so it can be folded into the error message.
"""

from __future__ import annotations

import contextlib
import math
import os
import tempfile
import warnings
import xml.etree.ElementTree as ET
from pathlib import Path
from typing import Iterator

import numpy as np

from .errors import RobotModelError, RobotModelWarning

__all__ = ["check_urdf_file", "check_model", "quiet_stderr"]

_MOVING = ("revolute", "continuous", "prismatic")


@contextlib.contextmanager
def quiet_stderr() -> Iterator[list[str]]:
    """Redirect file descriptor 2 (C/C++ stderr) to a temporary file; yields a list that holds
    the captured lines after the block."""
    lines: list[str] = []
    try:
        fd = os.dup(2)
    except OSError:  # no fd 2 (embedded interpreters): nothing to capture
        yield lines
        return
    with tempfile.TemporaryFile(mode="w+b") as tmp:
        os.dup2(tmp.fileno(), 2)
        try:
            yield lines
        finally:
            os.dup2(fd, 2)
            os.close(fd)
            tmp.seek(0)
            text = tmp.read(20000).decode("utf-8", "replace")
            lines.extend(ln.strip() for ln in text.splitlines() if ln.strip())


def _number(text: str | None, what: str, src: str, default: float | None = None) -> float:
    if text is None:
        if default is None:
            raise RobotModelError(f"{src}: {what} is missing")
        return default
    try:
        v = float(text)
    except ValueError:
        raise RobotModelError(f"{src}: {what} is not a number: {text!r}") from None
    if not math.isfinite(v):
        raise RobotModelError(f"{src}: {what} is not finite: {text!r}")
    return v


def _vector(text: str | None, what: str, src: str, default: tuple[float, ...]) -> np.ndarray:
    if text is None:
        return np.array(default, dtype=float)
    parts = text.split()
    if len(parts) != len(default):
        raise RobotModelError(f"{src}: {what} needs {len(default)} numbers, got {text!r}")
    return np.array([_number(p, what, src) for p in parts])


def read_xml(path: str | Path) -> ET.Element:
    """The root element of a robot description; RobotModelError (one line) when it is not
    well-formed XML or cannot be read."""
    try:
        return ET.parse(str(path)).getroot()
    except ET.ParseError as exc:
        raise RobotModelError(f"{path}: not well-formed XML ({exc})") from None
    except OSError as exc:
        raise RobotModelError(f"{path}: cannot read ({exc.strerror or exc})") from None


def check_urdf_file(path: str | Path) -> None:
    """RobotModelError (one line) for a URDF that is not well-formed or has impossible values."""
    src = str(path)
    root = read_xml(src)
    if root.tag != "robot":
        raise RobotModelError(f"{src}: not a URDF (root element is <{root.tag}>, expected <robot>)")
    for link in root.iter("link"):
        name = link.get("name", "?")
        inertial = link.find("inertial")
        if inertial is None:
            continue
        mass_el = inertial.find("mass")
        mass = _number(mass_el.get("value") if mass_el is not None else None, f"link '{name}' mass", src, 0.0)
        if mass < 0:
            raise RobotModelError(f"{src}: link '{name}' has a negative mass {mass:g}")
        _vector(inertial.find("origin").get("xyz") if inertial.find("origin") is not None else None,
                f"link '{name}' inertial origin xyz", src, (0.0, 0.0, 0.0))
        inertia = inertial.find("inertia")
        if inertia is None:
            continue
        v = {k: _number(inertia.get(k), f"link '{name}' inertia {k}", src, 0.0)
             for k in ("ixx", "ixy", "ixz", "iyy", "iyz", "izz")}
        I = np.array([[v["ixx"], v["ixy"], v["ixz"]], [v["ixy"], v["iyy"], v["iyz"]], [v["ixz"], v["iyz"], v["izz"]]])
        lam = np.linalg.eigvalsh(I)
        if lam[0] < -1e-9 * max(1.0, abs(lam[-1])):
            warnings.warn(f"{src}: link '{name}' has an inertia matrix that is not positive semi-definite "
                          f"(eigenvalues {np.array2string(lam, precision=3)}); no real body has it",
                          RobotModelWarning, stacklevel=3)
    for joint in root.iter("joint"):
        name, kind = joint.get("name", "?"), joint.get("type", "")
        if kind not in _MOVING:
            continue
        axis_el = joint.find("axis")
        axis = _vector(axis_el.get("xyz") if axis_el is not None else None, f"joint '{name}' axis", src,
                       (1.0, 0.0, 0.0))
        if np.linalg.norm(axis) < 1e-9:
            raise RobotModelError(f"{src}: joint '{name}' has a zero-length axis {axis.tolist()}")
        limit = joint.find("limit")
        if limit is not None and kind != "continuous":
            lo = _number(limit.get("lower"), f"joint '{name}' lower limit", src, 0.0)
            hi = _number(limit.get("upper"), f"joint '{name}' upper limit", src, 0.0)
            if lo > hi:
                raise RobotModelError(f"{src}: joint '{name}' has lower limit {lo:g} above upper limit {hi:g}")
            for k in ("effort", "velocity"):
                if limit.get(k) is not None and _number(limit.get(k), f"joint '{name}' {k} limit", src) < 0:
                    raise RobotModelError(f"{src}: joint '{name}' has a negative {k} limit")


#: no robot body is heavier (kg) or has a larger inertia (kg·m²): a value above it is a unit or typing error
MAX_BODY_MASS = 1e5


def check_mjcf_file(path: str | Path) -> None:
    """RobotModelError (one line, naming the body) for an MJCF mass, density or inertia below zero,
    which Pinocchio would clamp to 0 silently."""
    src = str(path)
    root = read_xml(src)
    for body in root.iter("body"):
        name = body.get("name", "?")
        for el in [body.find("inertial"), *body.findall("geom")]:
            if el is None:
                continue
            what = f"body '{name}' {'inertial' if el.tag == 'inertial' else 'geom'}"
            for key in ("mass", "density"):
                if el.get(key) is not None and _number(el.get(key), f"{what} {key}", src) < 0:
                    raise RobotModelError(f"{src}: {what} has a negative {key} {el.get(key)}")
            if el.get("diaginertia") is not None:
                d = _vector(el.get("diaginertia"), f"{what} diaginertia", src, (0.0, 0.0, 0.0))
                if np.any(d < 0):
                    raise RobotModelError(f"{src}: {what} has a negative diaginertia {d.tolist()}")
            if el.get("fullinertia") is not None:
                f = _vector(el.get("fullinertia"), f"{what} fullinertia", src, (0.0,) * 6)
                if f.size == 6:
                    inertia = np.array([[f[0], f[3], f[4]], [f[3], f[1], f[5]], [f[4], f[5], f[2]]])
                    if np.linalg.eigvalsh(inertia)[0] < -1e-9 * max(1.0, float(np.abs(f).max())):
                        raise RobotModelError(f"{src}: {what} has a fullinertia that is not positive "
                                              f"semi-definite {f.tolist()}")


def check_model(model, src: str) -> None:
    """RobotModelError for non-finite inertias, zero joint axes or inverted limits in a Pinocchio model."""
    for j in range(1, model.njoints):
        I = model.inertias[j]
        vals = np.concatenate([[I.mass], I.lever, np.asarray(I.inertia).ravel()])
        if not np.all(np.isfinite(vals)):
            raise RobotModelError(f"{src}: body '{model.names[j]}' has non-finite inertial values")
        if I.mass < 0:
            raise RobotModelError(f"{src}: body '{model.names[j]}' has a negative mass {I.mass:g}")
        if I.mass > MAX_BODY_MASS or np.max(np.abs(np.asarray(I.inertia))) > MAX_BODY_MASS:
            raise RobotModelError(f"{src}: body '{model.names[j]}' has an implausible mass {I.mass:.3g} kg or inertia "
                                  f"(over {MAX_BODY_MASS:g} kg / kg·m²); check the file's units")
        jm = model.joints[j]
        axis = getattr(jm, "axis", None)
        if axis is not None and np.linalg.norm(np.asarray(axis)) < 1e-9:
            raise RobotModelError(f"{src}: joint '{model.names[j]}' has a zero-length axis")
    lo, hi = np.asarray(model.lowerPositionLimit), np.asarray(model.upperPositionLimit)
    bad = np.flatnonzero(np.isfinite(lo) & np.isfinite(hi) & (lo > hi))
    if bad.size:
        iq = int(bad[0])
        name = next((model.names[j] for j in range(1, model.njoints)
                     if model.joints[j].idx_q <= iq < model.joints[j].idx_q + model.joints[j].nq), "?")
        raise RobotModelError(f"{src}: joint '{name}' has lower limit {lo[iq]:g} above upper limit {hi[iq]:g}")
