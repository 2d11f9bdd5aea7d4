"""The model `sensorless identify` fits, from its options: structure, LMI settings, option checks."""

from __future__ import annotations

import math
from pathlib import Path


from ..errors import OptionError, SensorlessError
from .console import console


def _plain(structure) -> bool:
    """A per-joint ModelStructure (no contact projection, no coupled drives)."""
    from ..regressor import ModelStructure

    return type(structure) is ModelStructure


def _friction_options(coulomb_smoothing: str, stribeck_velocity: str):
    """--coulomb-smoothing / --stribeck-velocity as 'auto' or a number (OptionError otherwise)."""
    out = []
    for flag, text in (("--coulomb-smoothing", coulomb_smoothing), ("--stribeck-velocity", stribeck_velocity)):
        if str(text).strip().lower() == "auto":
            out.append("auto")
            continue
        try:
            x = float(text)
        except ValueError:
            raise OptionError(f"{flag} must be a number or 'auto', got '{text}'") from None
        if not (math.isfinite(x) and x >= 0) or (flag == "--stribeck-velocity" and x == 0):
            raise OptionError(f"{flag} must be a finite number {'>' if 'stribeck' in flag else '>='} 0 or 'auto', got '{text}'")
        out.append(x)
    return tuple(out)


def _check_identify_options(method, gamma, regularization, coulomb_smoothing, outliers, weights="auto") -> None:
    """OptionError, naming the option, for values no run can use (checked before any work)."""
    from ..data.outliers import OUTLIER_MODES
    from ..identification import METHODS

    if method not in METHODS:
        raise OptionError(f"--method must be one of {', '.join(METHODS)}, got '{method}'")
    if gamma != "auto":
        try:
            g = float(gamma)
        except ValueError:
            raise OptionError(f"--gamma must be a number or 'auto', got '{gamma}'") from None
        if not (math.isfinite(g) and g >= 0):
            raise OptionError(f"--gamma must be a finite number >= 0 or 'auto', got '{gamma}'")
    if regularization not in ("none", "pullback"):  # the default is checked without loading cvxpy
        from ..identification.regularizers import REGULARIZERS
    if regularization not in ("none", "pullback") and regularization not in REGULARIZERS:
        raise OptionError(f"--regularization must be one of {', '.join(sorted(REGULARIZERS))}, none; "
                          f"got '{regularization}'")
    if coulomb_smoothing != "auto" and not (math.isfinite(coulomb_smoothing) and coulomb_smoothing >= 0):
        raise OptionError(f"--coulomb-smoothing must be a finite number >= 0, got {coulomb_smoothing}")
    if outliers not in OUTLIER_MODES:
        raise OptionError(f"--outliers must be one of {', '.join(OUTLIER_MODES)}, got '{outliers}'")
    if weights not in ("auto", "none") and not Path(weights).is_file():
        raise OptionError(f"--weights must be auto, none or a JSON/CSV file of per-joint σ; no file '{weights}'")


def _structure(robot, joint_terms: str, coulomb_smoothing: float, contact_frames, contact_dims, contact_offset,
               contact_mode, *, contact_rows: str = "auto", wrench_offset: str = "none", offset_axes: str = "xy",
               train=None):
    """ModelStructure, or ContactStructure when contact frames are given (wrench mode: rows
    chosen from the training logs' torques when ``contact_rows="auto"``, with a message)."""
    from ..errors import RobotModelError
    from ..regressor import ModelStructure

    terms = joint_terms if "=" in joint_terms else tuple(t.strip() for t in joint_terms.split(",") if t.strip())
    if not (math.isfinite(coulomb_smoothing) and coulomb_smoothing >= 0):
        raise OptionError(f"--coulomb-smoothing must be a finite number >= 0, got {coulomb_smoothing}")
    if robot.coupled:  # coupled joints (dvrk_psm): drive terms of its own
        if contact_frames:
            raise SensorlessError(f"--contact-frames: '{robot.name}' is a fixed-base coupled-joint model")
        if isinstance(terms, str):
            raise OptionError(f"--joint-terms per joint ('JOINT=...') is not supported for '{robot.name}' (drive terms)")
        return robot.make_structure(terms, coulomb_smoothing)
    if not contact_frames:
        if contact_dims:
            raise SensorlessError("--contact-dims needs --contact-frames")
        if contact_rows != "auto" or wrench_offset != "none":
            raise SensorlessError("--contact-rows and --wrench-offset need --contact-frames and --contact-mode wrench")
        try:
            return ModelStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing)
        except RobotModelError as exc:
            raise OptionError(f"--joint-terms '{joint_terms}': {exc}") from None
    from ..regressor.contact import ContactStructure

    frames = tuple(f.strip() for f in contact_frames.split(",") if f.strip())
    try:
        dims = tuple(int(d) for d in contact_dims.split(",")) if contact_dims else ()
    except ValueError:
        raise SensorlessError(f"--contact-dims must be comma-separated 3 or 6, got '{contact_dims}'") from None
    if contact_mode == "wrench" and contact_rows == "auto" and train:
        from ..regressor.contact import choose_contact_rows

        contact_rows, why = choose_contact_rows(train)
        console.print(f"contact rows: {contact_rows} — {why}")
    try:
        return ContactStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing, contact_frames=frames,
                                contact_dims=dims, contact_offset=contact_offset, mode=contact_mode,
                                contact_rows=contact_rows, wrench_offset=wrench_offset, offset_axes=offset_axes)
    except RobotModelError as exc:
        if "term" in str(exc):
            raise OptionError(f"--joint-terms '{joint_terms}': {exc}") from None
        raise


def _lmi_kwargs(robot, structure, method, prior, regularization, gamma, ellipsoids, contain_prior) -> dict:
    """Options of `identify(method="lmi")` from the command line."""
    if method != "lmi":
        return {}
    from ..identification import auto_ellipsoids

    if gamma != "auto":
        try:
            gamma = float(gamma)
        except ValueError:
            raise SensorlessError(f"--gamma must be a number or 'auto', got '{gamma}'") from None
    prior_vec = None
    if prior is not None:
        from .common import load_robot_cli

        p = load_robot_cli(prior, floating_base=robot.floating_base)
        missing = [b for b in robot.body_names if b not in p.body_names]
        if missing:
            raise SensorlessError(f"{prior}: prior model lacks bodies {missing} of {robot.name}")
        prior_vec = structure.prior()
        pi = p.inertial_parameters().reshape(-1, 10)
        for k, b in enumerate(robot.body_names):
            prior_vec[10 * k : 10 * k + 10] = pi[p.body_names.index(b)]
    ell = {"auto": None, "kinematic": "kinematic", "none": False}.get(ellipsoids)
    if ellipsoids not in ("auto", "kinematic", "none"):
        raise SensorlessError(f"--ellipsoids must be auto, kinematic or none, got '{ellipsoids}'")
    if ell is not False and not contain_prior:
        ell = auto_ellipsoids(robot, geometry=None if ell == "kinematic" else "auto", contain_prior=False)
    reg = None if regularization == "none" else regularization
    return {"gamma": gamma, "regularization": reg, "prior": prior_vec, "ellipsoids": ell}
