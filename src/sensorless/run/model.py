"""The model of a run from its :class:`~.config.ModelConfig` and :class:`~.config.SolverConfig`: the
robot (a description, an example-robot-data name or a model authored in code, with locked, passive
and floating joints and added frames), the model structure (joint terms, contacts) and the LMI
settings (prior, regulariser, γ, ellipsoids)."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Callable, Sequence

from ..errors import OptionError, SensorlessError, setting

__all__ = ["parse_add_frame", "load_run_robot", "model_structure", "lmi_settings", "is_plain"]


def parse_add_frame(spec: str) -> tuple:
    """'NAME:PARENT:x,y,z[:r,p,y]' → (name, parent, xyz, rpy); SensorlessError naming the spec."""
    parts = str(spec).split(":")
    bad = f"{setting('model.add_frame')} '{spec}': expected NAME:PARENT:x,y,z or NAME:PARENT:x,y,z:roll,pitch,yaw"
    if len(parts) not in (3, 4) or not parts[0].strip() or not parts[1].strip():
        raise SensorlessError(bad)
    try:
        vecs = [[float(x) for x in p.split(",")] for p in parts[2:]]
    except ValueError:
        raise SensorlessError(bad + " (numbers)") from None
    if any(len(v) != 3 for v in vecs):
        raise SensorlessError(bad + " (three numbers each)")
    return parts[0].strip(), parts[1].strip(), vecs[0], vecs[1] if len(vecs) == 2 else [0.0, 0.0, 0.0]


def load_run_robot(spec, lock: Sequence[str] = (), floating_base: bool | None = None, passive: Sequence[str] = (),
                   *, frames: Sequence = (), trust_xacro: bool = False, package_paths: Sequence = ()):
    """A URDF/MJCF/xacro file or a name of the robot registry (:mod:`sensorless.robots.registry`), with
    ``frames`` (``(name, parent, xyz, rpy)``, :func:`parse_add_frame`) added."""
    from ..errors import UntrustedModelError
    from ..robot import add_frame, load_robot
    from ..xacro_expand import refuse_xacro

    try:
        r = load_robot(spec, trust_xacro=trust_xacro, package_paths=tuple(package_paths),
                       lock_joints=tuple(lock or ()), floating_base=floating_base, passive_joints=tuple(passive or ()))
    except UntrustedModelError:
        refuse_xacro(Path(str(spec)), f"rerun with {setting('trust_xacro', True)}")
    for f in frames:
        add_frame(r, *f)
    return r


def is_plain(structure) -> bool:
    """A per-joint ModelStructure (no contact projection, no coupled drives)."""
    from ..regressor import ModelStructure

    return type(structure) is ModelStructure


def model_structure(robot, joint_terms: str, coulomb_smoothing: float, contact_frames, contact_dims, contact_offset,
                    contact_mode, *, contact_rows: str = "auto", wrench_offset: str = "none", offset_axes: str = "xy",
                    train=None, say: Callable[[str], None] | None = None):
    """ModelStructure, or ContactStructure when contact frames are given (wrench mode: rows chosen from
    the training logs' torques when ``contact_rows="auto"``, said through ``say``)."""
    from ..errors import RobotModelError
    from ..regressor import ModelStructure

    terms = joint_terms if "=" in joint_terms else tuple(t.strip() for t in joint_terms.split(",") if t.strip())
    if not (math.isfinite(coulomb_smoothing) and coulomb_smoothing >= 0):
        raise OptionError(f"{setting('model.coulomb_smoothing')} must be a finite number >= 0, got {coulomb_smoothing}")
    if robot.coupled:  # coupled joints (dvrk_psm): drive terms of its own
        if contact_frames:
            raise SensorlessError(f"{setting('model.contact_frames')}: '{robot.name}' is a fixed-base coupled-joint model")
        if isinstance(terms, str):
            raise OptionError(f"{setting('model.joint_terms')} per joint ('JOINT=...') is not supported for "
                              f"'{robot.name}' (drive terms)")
        return robot.make_structure(terms, coulomb_smoothing)
    if not contact_frames:
        if contact_dims:
            raise SensorlessError(f"{setting('model.contact_dims')} needs {setting('model.contact_frames')}")
        if contact_rows != "auto" or wrench_offset != "none":
            raise SensorlessError(f"{setting('model.contact_rows')} and {setting('model.wrench_offset')} need "
                                  f"{setting('model.contact_frames')} and {setting('model.contact_mode', 'wrench')}")
        try:
            return ModelStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing)
        except RobotModelError as exc:
            raise OptionError(f"{setting('model.joint_terms', joint_terms)}: {exc}") from None
    from ..regressor.contact import ContactStructure

    frames = tuple(f.strip() for f in contact_frames.split(",") if f.strip())
    try:
        dims = tuple(int(d) for d in contact_dims.split(",")) if contact_dims else ()
    except ValueError:
        raise SensorlessError(f"{setting('model.contact_dims')} must be comma-separated 3 or 6, got "
                              f"'{contact_dims}'") from None
    if contact_mode == "wrench" and contact_rows == "auto" and train:
        from ..regressor.contact import choose_contact_rows

        contact_rows, why = choose_contact_rows(train)
        if say is not None:
            say(f"contact rows: {contact_rows} — {why}")
    try:
        return ContactStructure(robot, joint_terms=terms, coulomb_smoothing=coulomb_smoothing, contact_frames=frames,
                                contact_dims=dims, contact_offset=contact_offset, mode=contact_mode,
                                contact_rows=contact_rows, wrench_offset=wrench_offset, offset_axes=offset_axes)
    except RobotModelError as exc:
        if "term" in str(exc):
            raise OptionError(f"{setting('model.joint_terms', joint_terms)}: {exc}") from None
        raise


def lmi_settings(robot, structure, method, prior, regularization, gamma, ellipsoids, contain_prior,
                 load_prior: Callable | None = None) -> dict:
    """Keyword arguments of ``identify(method="lmi")`` (empty for another method); ``prior``: a URDF whose
    inertials are the prior, loaded with ``load_prior(path, floating_base=...)``."""
    if method != "lmi":
        return {}
    from ..identification import auto_ellipsoids

    if gamma != "auto":
        gamma = float(gamma)  # checked by .checks
    prior_vec = None
    if prior is not None:
        p = load_prior(prior, floating_base=robot.floating_base)
        missing = [b for b in robot.body_names if b not in p.body_names]
        if missing:
            raise SensorlessError(f"{prior}: prior model lacks bodies {missing} of {robot.name}")
        prior_vec = structure.prior()
        pi = p.inertial_parameters().reshape(-1, 10)
        for k, b in enumerate(robot.body_names):
            prior_vec[10 * k : 10 * k + 10] = pi[p.body_names.index(b)]
    ell = {"auto": None, "kinematic": "kinematic", "none": False}.get(ellipsoids)
    if ellipsoids not in ("auto", "kinematic", "none"):
        raise SensorlessError(f"{setting('solver.ellipsoids')} must be auto, kinematic or none, got '{ellipsoids}'")
    if ell is not False and not contain_prior:
        ell = auto_ellipsoids(robot, geometry=None if ell == "kinematic" else "auto", contain_prior=False)
    reg = None if regularization == "none" else regularization
    return {"gamma": gamma, "regularization": reg, "prior": prior_vec, "ellipsoids": ell}
