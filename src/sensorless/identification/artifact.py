"""The one reader and writer of a model folder (``sensorless identify``, the demo, psm-identify).

A model folder holds ``result.json`` (the model: parameters, structure and preprocessing
settings, diagnostics, identifiability verdicts; ``schema_version``), ``model.urdf`` and
``joint_terms.json`` (or ``drive_terms.json`` for coupled joints, which no URDF can hold).
:func:`save_model_folder` writes all of them from one :class:`~.result.IdentificationResult`,
so the URDF and ``result.json`` are always the same model.

:func:`load_model_folder` is what every command and library reader uses: it refuses special
files and files over :data:`MAX_MODEL_BYTES`, parses strict JSON, checks the document against
the schema (:mod:`.artifact_schema`; ``schema_version`` :data:`SCHEMA_VERSION`, a file without
one is version 0 and loads if it validates), rebuilds the model structure on the given robot
and checks the parameters: the vector's labels and length, finite values, each body's mass
(> 0, or ≥ 0 where the prior body is massless, and below :data:`MASS_CAP_FACTOR` × the prior
robot's total mass, at least 100 kg), first and second moments of bounded size, and for physically consistent
(``lmi``) models the pseudo-inertia and the signs of friction and armature. Paths stored in a
model (e.g. a gains file) are resolved inside the model folder only. Every problem is one
:class:`~sensorless.errors.ParameterError` line naming the file and the key path.

``settings.robot`` records how the robot description was loaded for the fit (floating base,
locked joints, passive joints, frames added to it), written by :func:`robot_settings`;
:func:`load_model_robot` loads the same robot again, so that a command applying the model
needs nothing repeated. :func:`prior_model` is the robot description itself used as a model
(its inertials and armature, no friction), labelled as the prior wherever it is used.
"""

from __future__ import annotations

import dataclasses
from pathlib import Path
from typing import Any

import numpy as np

from ..errors import ParameterError, SensorlessError, setting
from ..io import check_input_file, read_json
from ..outdir import warn_if_edited
from ..regressor.joint_terms import joint_term, terms_where
from .artifact_schema import (Checker, check_kinematics, check_preprocessing_settings, check_robot_settings,
                              check_structure_settings, check_verdicts, summary)

__all__ = ["SCHEMA_VERSION", "RESULT", "MAX_MODEL_BYTES", "FrictionArtifact", "ModelArtifact", "is_friction_model",
           "check_same_robot", "export_mjcf", "is_robot_description", "load_friction_model", "load_model_folder", "load_model_robot", "prior_model",
           "read_result", "read_preprocessing", "read_robot_settings", "result_path", "robot_settings",
           "save_friction_model", "save_model_folder", "stamp", "write_result"]

#: version of the ``result.json`` schema written by every writer (0: files written before it existed)
SCHEMA_VERSION = 1
RESULT = "result.json"
MAX_MODEL_BYTES = 64 * 1024 * 1024
#: a body may weigh at most this many times the prior robot's total mass (at least :data:`MASS_CAP_FLOOR` kg;
#: :data:`MASS_CAP_MASSLESS` kg when every prior body is massless, e.g. dvrk_psm)
MASS_CAP_FACTOR = 10.0
MASS_CAP_FLOOR = 100.0
MASS_CAP_MASSLESS = 1e4
#: first moments [kg·m] and inertias [kg·m²] of a body are bounded by its mass cap × this length (squared)
LENGTH_CAP = 10.0
_TERM_CAP = 1e6
_CONSISTENCY_TOL = 1e-6
#: ``kind`` of a friction-only model's result.json (``sensorless friction``)
FRICTION_KIND = "friction"


def stamp(doc: dict) -> dict:
    """``doc`` with ``schema_version`` set (every writer of a result.json calls this)."""
    doc["schema_version"] = SCHEMA_VERSION
    return doc


def result_path(model: str | Path) -> Path:
    """``model/result.json`` for a model folder, else ``model`` itself."""
    model = Path(model)
    return model / RESULT if model.is_dir() else model


def read_result(model: str | Path) -> dict:
    """The raw ``result.json`` document (bounded, strict JSON, an object, a known schema version)."""
    path = result_path(model)
    doc = read_json(path, "model file (result.json)", MAX_MODEL_BYTES, error=ParameterError)
    if not isinstance(doc, dict):
        raise ParameterError(f"{path}: not a sensorless result file (expected a JSON object, got {summary(doc)})")
    version = doc.get("schema_version", 0)
    Checker(path).number("schema_version", version, 0, 1e9, integer=True)
    if version > SCHEMA_VERSION:
        raise ParameterError(f"{path}: schema_version {version} is newer than this sensorless reads "
                             f"({SCHEMA_VERSION}); upgrade sensorless")
    return doc


def read_preprocessing(model: str | Path) -> dict:
    """The validated ``settings.preprocessing`` of a model (empty when it has none)."""
    path = result_path(model)
    doc = read_result(path)
    c = Checker(path, path.parent)
    settings = c.mapping("settings", doc.get("settings"))
    return check_preprocessing_settings(c, settings.get("preprocessing"))


def read_robot_settings(model: str | Path) -> dict:
    """The validated ``settings.robot`` of a model (module docstring; empty for older models)."""
    path = result_path(model)
    doc = read_result(path)
    c = Checker(path, path.parent)
    settings = c.mapping("settings", doc.get("settings"))
    out = check_robot_settings(c, settings.get("robot"))
    if "floating_base" not in out and settings.get("contact_frames"):
        out["floating_base"] = True  # written before settings.robot: contact models had a floating base
    return out


def robot_settings(robot) -> dict:
    """``settings.robot`` of a model identified on ``robot`` (module docstring)."""
    return {"floating_base": bool(getattr(robot, "floating_base", False)),
            "lock": list(getattr(robot, "locked_joints", ()) or ()),
            "passive": list(getattr(robot, "passive_joints", ()) or ()),
            "frames": [list(f) for f in getattr(robot, "added_frames", None) or ()]}


def load_model_robot(spec, model: str | Path, **load_kwargs):
    """The robot ``spec`` (:func:`~sensorless.robot.load_robot`) loaded as it was for the fit of ``model``:
    its floating base, locked and passive joints and added frames (``settings.robot``)."""
    from ..robot import add_frame, load_robot

    stored = read_robot_settings(model)
    robot = load_robot(spec, floating_base=stored.get("floating_base"), lock_joints=stored.get("lock", ()),
                       passive_joints=stored.get("passive", ()), **load_kwargs)
    for name, parent, xyz, rpy in stored.get("frames", ()):
        add_frame(robot, name, parent, xyz, rpy)
    return robot


#: file suffixes of a robot description (``--model robot.urdf``: the description's own parameters)
DESCRIPTION_SUFFIXES = (".urdf", ".xml", ".mjcf", ".xacro")


def is_robot_description(model: str | Path | None) -> bool:
    """True for a robot description file (URDF/MJCF/xacro) given where a model is expected."""
    return model is not None and Path(model).suffix.lower() in DESCRIPTION_SUFFIXES


@dataclasses.dataclass
class ModelArtifact:
    """A validated model folder: the document, the structure rebuilt on the robot, the parameters,
    and the preprocessing its training logs had (a stored gains file resolved inside the folder).
    ``origin``: "identified", or "prior" for a robot description used as the model (:func:`prior_model`)."""

    path: Path
    doc: dict
    structure: Any
    parameters: np.ndarray
    preprocessing: dict
    origin: str = "identified"

    @property
    def folder(self) -> Path:
        return self.path.parent

    @property
    def label(self) -> str:
        """What the model is, for outputs: the identified model's folder or the prior's file."""
        if self.origin == "prior":
            return f"prior: the inertial parameters of {self.path} (no identified model, no friction)"
        return f"identified ({self.doc.get('method', '?')}): {self.folder}"

    @property
    def schema_version(self) -> int:
        return int(self.doc.get("schema_version", 0))


def load_model_folder(model: str | Path, robot) -> ModelArtifact:
    """Read and validate a model folder (or its ``result.json``) for ``robot`` (module docstring)."""
    path = result_path(model)
    check_input_file(path, "model file (result.json)")
    doc = read_result(path)
    warn_if_edited(path, "model file")
    if doc.get("kind") == FRICTION_KIND:
        raise ParameterError(f"{path}: a friction-only model (from `sensorless friction`) has no body model; "
                             f"use it with `sensorless predict` without {setting('robot')}")
    c = Checker(path, path.parent)
    settings = c.mapping("settings", doc.get("settings"))
    values = c.mapping("parameters", doc.get("parameters"))
    method = doc.get("method")
    if method is not None:
        c.string("method", method, max_len=32)
    if doc.get("robot") is not None:
        c.mapping("robot", doc["robot"])
        check_same_robot(c, doc["robot"], robot)
    check_structure_settings(c, settings)
    _check_robot_matches(c, check_robot_settings(c, settings.get("robot")), robot)
    check_verdicts(c, (doc.get("diagnostics") or {}).get("verdicts") if isinstance(doc.get("diagnostics"), dict) else None)
    pre = check_preprocessing_settings(c, settings.get("preprocessing"))
    try:
        structure = structure_from_settings(settings, doc, robot)
    except ParameterError as exc:
        raise ParameterError(f"{path}: {exc}") from None
    except SensorlessError as exc:
        raise ParameterError(f"{path}: settings do not fit robot '{robot.name}': {exc}") from None
    except (ValueError, KeyError, TypeError, AttributeError, RecursionError) as exc:
        raise ParameterError(f"{path}: not a sensorless result file (settings: {type(exc).__name__})") from None
    params = _parameters(c, structure, values, doc, robot)
    _check_bodies(c, structure, params, physical=method == "lmi")
    return ModelArtifact(path, doc, structure, params, pre)


def check_same_robot(c: Checker, stored: dict, robot) -> None:
    """Refuse ``robot`` when it is not the robot the model was identified on (``stored``: the model's
    ``robot``): its kinematic tree (``robot.kinematics``, compared to the printed precision) or, for
    models written before the tree was stored, its body names. One line naming both robots."""
    from ..robot import kinematics_difference, kinematics_fingerprint, kinematics_table

    name = stored.get("name")
    name = name[:80] if isinstance(name, str) else "?"
    kin = check_kinematics(c, stored.get("kinematics"))
    if kin is not None:
        table = kinematics_table(robot.model)
        ours = kinematics_fingerprint(table)
        why = None if ours == kin["fingerprint"] else kinematics_difference(kin["joints"], table)
        if why is not None:
            raise ParameterError(f"{c.src}: identified on robot '{name}' (kinematics {kin['fingerprint']}), not on "
                                 f"the robot given, '{robot.name}' (kinematics {ours}): {why}; give "
                                 f"{setting('robot')} the robot the model was identified on")
        return
    bodies = stored.get("bodies")
    if isinstance(bodies, list) and all(isinstance(b, str) for b in bodies):
        missing = [b for b in bodies if b not in robot.body_names]
        if missing:
            raise ParameterError(f"{c.src}: identified on robot '{name}', whose bodies {missing[:3]}"
                                 f"{' …' if len(missing) > 3 else ''} the robot given, '{robot.name}', has not; give "
                                 f"{setting('robot')} the robot the model was identified on")


def _check_robot_matches(c: Checker, stored: dict, robot) -> None:
    """The robot must be loaded as for the fit: the same passive joints (they change the parameters)."""
    passive = list(getattr(robot, "passive_joints", ()) or ())
    if stored and sorted(stored.get("passive", [])) != sorted(passive):
        raise c.fail("settings.robot.passive", f"the model was identified with passive joint(s) "
                     f"{stored.get('passive', [])}, the robot given has {passive}; load the robot as for the fit "
                     "(sensorless.identification.artifact.load_model_robot; the commands do it)")


def prior_model(robot, description=None, source: str | Path | None = None) -> ModelArtifact:
    """The robot description as a model: the inertials (and armature) of ``description`` (a robot with
    the same bodies, e.g. another URDF of it; default ``robot`` itself), no friction, on the rows of a
    per-joint model (known generalized forces: actuated and passive joints, and a floating base's 6).
    ``origin`` is "prior": outputs say the parameters are the prior's, not identified."""
    from ..errors import RobotModelError
    from ..regressor.terms import ModelStructure

    if getattr(robot, "coupled", False):
        structure = robot.make_structure(None)
    else:
        structure = ModelStructure(robot, joint_terms=("armature",))
    params = np.asarray(structure.prior(), dtype=float)
    if description is not None and description is not robot:
        missing = [b for b in robot.body_names if b not in description.body_names]
        if missing:
            raise RobotModelError(f"{source or description.source}: the model lacks bodies {missing} of '{robot.name}'")
        pi = description.inertial_parameters().reshape(-1, 10)
        for k, b in enumerate(robot.body_names):
            params[10 * k: 10 * k + 10] = pi[description.body_names.index(b)]
    path = Path(source or getattr(robot, "source", "") or robot.name)
    doc = {"method": "prior", "robot": robot.summary(), "settings": {"robot": robot_settings(robot)}}
    return ModelArtifact(path, doc, structure, params, {}, origin="prior")


def _parameters(c: Checker, structure, values: dict, doc: dict, robot) -> np.ndarray:
    missing = [lab for lab in structure.labels if lab not in values]
    if missing:
        name = doc.get("robot", {}).get("name") if isinstance(doc.get("robot"), dict) else None
        raise c.fail("parameters", f"parameters {missing[:5]} are missing; was it identified for another robot "
                                   f"(file says '{summary(name) if not isinstance(name, str) else name[:80]}', "
                                   f"given '{robot.name}')?")
    bad = [lab for lab in structure.labels if isinstance(values[lab], bool) or not isinstance(values[lab], (int, float))
           or not np.isfinite(values[lab])]
    if bad:
        raise c.fail(f"parameters.{bad[0]}", f"parameter(s) {bad[:5]} are not finite numbers "
                                             f"(e.g. {bad[0]} = {summary(values[bad[0]])})")
    extra = len(values) - len(structure.labels)
    if extra > 0:
        unknown = [k for k in values if k not in set(structure.labels)][:3]
        raise c.fail("parameters", f"{extra} parameter(s) the model structure does not have (e.g. "
                                   f"{', '.join(k[:60] for k in unknown)}); the vector must have {len(structure.labels)}")
    return np.array([float(values[lab]) for lab in structure.labels])


def _check_bodies(c: Checker, structure, params: np.ndarray, physical: bool) -> None:
    """Masses, moments (and for ``physical`` models consistency, friction and armature signs) in range."""
    from ..parameters import check_physical_consistency

    nb = structure.n_body_params
    prior = np.asarray(structure.prior(), dtype=float)
    m0 = prior[:nb:10]
    total = float(np.sum(np.clip(m0, 0, None)))
    cap = max(MASS_CAP_FACTOR * total, MASS_CAP_FLOOR) if total > 0 else MASS_CAP_MASSLESS
    why = (f"{MASS_CAP_FACTOR:g} × the prior robot's {total:.6g} kg" if total > 0
           else "the cap for a robot whose prior bodies are massless")
    labels = structure.labels
    for k in range(nb // 10):
        lab, m = labels[10 * k], params[10 * k]
        body = lab.rsplit(".", 1)[0]
        if m < 0 or (m == 0 and m0[k] > 0):
            raise c.fail(f"parameters.{lab}", f"body '{body}' has mass {m:.6g} kg; a mass must be > 0"
                                              + (" (≥ 0 where the prior body is massless)" if m0[k] > 0 else ""))
        if m > cap:
            raise c.fail(f"parameters.{lab}", f"body '{body}' has mass {m:.6g} kg, more than the plausible "
                                              f"{cap:.6g} kg ({why})")
        for i in range(1, 10):
            lim = cap * LENGTH_CAP ** (1 if i < 4 else 2)
            if abs(params[10 * k + i]) > lim:
                raise c.fail(f"parameters.{labels[10 * k + i]}", f"{params[10 * k + i]:.6g} is implausibly large "
                                                                 f"for body '{body}' (|value| ≤ {lim:.6g})")
    for i in range(nb, len(params)):
        if abs(params[i]) > _TERM_CAP:
            raise c.fail(f"parameters.{labels[i]}", f"{params[i]:.6g} is implausibly large (|value| ≤ {_TERM_CAP:g})")
    if not physical:
        return
    bodies = [labels[10 * k].rsplit(".", 1)[0] for k in range(nb // 10)]
    for rep in check_physical_consistency(params[:nb], bodies, tol=_CONSISTENCY_TOL):
        if not rep.consistent:
            raise c.fail(f"parameters.{rep.name}", f"body '{rep.name}' is not physically consistent (its "
                                                   "pseudo-inertia is not positive semi-definite), yet the model "
                                                   "says it was identified with method lmi")
    start = getattr(structure, "n_block_params", nb)  # the joint-term block (drive terms are not constrained)
    for i in range(start, len(params)):
        term = labels[i].rsplit(".", 1)[-1]
        if term in terms_where("nonnegative") and params[i] < -_CONSISTENCY_TOL * max(1.0, float(np.max(np.abs(params[start:])))):
            raise c.fail(f"parameters.{labels[i]}", f"{term} = {params[i]:.6g} is negative; a physically "
                                                    "consistent (lmi) model has it ≥ 0")


def structure_from_settings(settings: dict, doc: dict, robot):
    """The model structure ``settings`` describe, on ``robot`` (typed errors when it does not fit)."""
    from ..regressor.terms import ModelStructure

    file_robot = doc.get("robot", {}).get("name") if isinstance(doc.get("robot"), dict) else None
    file_robot = file_robot[:80] if isinstance(file_robot, str) else summary(file_robot)
    if settings.get("structure") == "transmission":
        from ..regressor.transmission import TransmissionStructure

        if not robot.coupled:
            raise ParameterError(f"a model of a coupled-joint robot ('{file_robot}'); "
                                 f"load it with that robot (e.g. {setting('robot', 'dvrk_psm')}), not '{robot.name}'")
        lo, hi = robot.position_limits()
        structure = TransmissionStructure.from_settings(robot.tree, settings, limits=(lo, hi),
                                                        velocity_limits=robot.velocity_limits(), name=robot.name)
        structure.robot.factory = getattr(robot, "factory", None)
        return structure
    if robot.coupled:
        raise ParameterError(f"identified for '{file_robot}' (per-joint model), "
                             f"not for the coupled-joint robot '{robot.name}'")
    common = {"joint_terms": tuple(settings["joint_terms"]),
              "coulomb_smoothing": float(settings.get("coulomb_smoothing", 0.0))}
    by_joint = settings.get("joint_terms_by_joint")
    if by_joint is not None:
        common["per_joint_terms"] = {j: tuple(t) for j, t in by_joint.items()}
    for key, name in (("coulomb_smoothing_by_joint", "coulomb_smoothing"), ("stribeck_velocity", "stribeck_velocity"),
                      ("rest_velocity", "rest_velocity"), ("presliding", "presliding")):
        if settings.get(key) is not None:
            common[name] = settings[key]
    if "stribeck" in common["joint_terms"]:  # files written before the fitted transition width: the product law
        common["friction_law"] = settings.get("friction_law", "product")
    if settings.get("contact_frames"):
        from ..regressor.contact import ContactStructure

        return ContactStructure.from_settings(robot, settings, **common)
    return ModelStructure(robot, **common, rows=settings.get("rows"))


# ---- writing ------------------------------------------------------------------------------
def write_result(doc: dict, path: str | Path) -> Path:
    """``doc`` stamped with the schema version, as strict JSON, written atomically to ``path``."""
    from ..io import write_json_atomic

    write_json_atomic(stamp(doc), path)
    return Path(path)


def save_model_folder(directory: str | Path, result, doc: dict | None = None, *, urdf_values: str = "prior") -> dict:
    """Write the model folder of ``result`` into ``directory`` (module docstring) and return the
    ``result.json`` document written (``doc``, default ``result.to_dict()``, completed with the
    physical-consistency report and what was exported). ``urdf_values``: ``"prior"`` (a body whose
    mass the data do not determine gets the prior's mass, the identified dynamics unchanged, said in
    an XML comment; :mod:`.urdf_values`) or ``"regularised"``. A model that is no physical body, or
    whose robot cannot be written as a URDF, is reported in ``doc["urdf_error"]`` with a warning."""
    import warnings

    from ..errors import RobotModelWarning
    from ..export import write_joint_terms
    from ..io import write_json_atomic
    from ..parameters import JointTerms, check_physical_consistency
    from .urdf_values import urdf_comment, urdf_inertials

    directory = Path(directory)
    doc = result.to_dict() if doc is None else doc
    reports = check_physical_consistency(result.inertial_parameters, list(result.robot.body_names))
    doc["physical_consistency"] = {"inconsistent_bodies": [r.name for r in reports if not r.consistent],
                                   "n_bodies": len(reports)}
    s = result.structure
    if s.robot.transmission_matrix is not None:
        write_json_atomic(s.drive_values(result.parameters), directory / "drive_terms.json")
        doc["urdf"] = None
        doc["urdf_error"] = f"'{result.robot.name}' has coupled joints; a URDF cannot hold it (result.json does)"
        write_result(doc, directory / RESULT)
        return doc
    law = {j: {"stribeck_velocity": float((s.stribeck_velocity or {}).get(j, 0.0)) if "stribeck" in s.terms_of(j)
               else 0.0, "coulomb_smoothing": s.smoothing_of(j)} for j in s.robot.term_joints}
    # terms the registry does not export (the presliding state: its amplitude, k and play) live in result.json only
    terms = JointTerms.from_dict({j: {**{t: x for t, x in d.items() if joint_term(t).exported}, **law[j]}
                                  for j, d in result.joint_terms().items()})
    write_joint_terms(terms, directory / "joint_terms.json")
    try:
        from ..urdf_patch import export_urdf  # the source URDF patched (meshes kept), else write_urdf

        pi, doc["urdf_values"] = urdf_inertials(result, urdf_values)
        _, doc["urdf_export"] = export_urdf(result.robot, pi, directory / "model.urdf", joint_terms=terms)
        _comment_urdf(directory / "model.urdf", urdf_comment(doc["urdf_values"]))
        doc["urdf"] = "model.urdf"
    except SensorlessError as exc:
        doc["urdf"] = None
        doc["urdf_error"] = str(exc)
        warnings.warn(f"no URDF written: {exc}", RobotModelWarning, stacklevel=2)
    write_result(doc, directory / RESULT)
    return doc


def export_mjcf(model: "str | Path | ModelArtifact", robot, path: str | Path) -> Path:
    """The model folder ``model`` (loaded on ``robot``, :func:`load_model_folder`; or an artifact already
    loaded on it) as MJCF at ``path``
    (:func:`sensorless.export_mjcf.write_mjcf`: inertials, armature, damping, frictionloss, verdicts in
    comments, the friction terms MuJoCo cannot hold named in the header). A model of coupled joints
    (drive terms on motor coordinates) has no MJCF counterpart and is refused."""
    from ..export_mjcf import write_mjcf

    art = model if isinstance(model, ModelArtifact) else load_model_folder(model, robot)
    s, p = art.structure, art.parameters
    if getattr(robot, "coupled", False) or s.n_body_params != 10 * robot.n_bodies:
        raise ParameterError(f"{art.path}: a model of coupled joints (drive terms on motor coordinates) has no MJCF "
                             "counterpart; export a per-joint model")
    terms = {j: {t: float(p[s.joint_term_index(j, t)]) for t in s.terms_of(j)} for j in s.robot.term_joints}
    for j, t in terms.items():  # the friction law's shape, which MuJoCo's ideal dry friction lacks
        if t.get("fc") and s.smoothing_of(j) > 0:
            t["coulomb_smoothing"] = s.smoothing_of(j)
        vs = (getattr(s, "stribeck_velocity", None) or {}).get(j)
        if t.get("stribeck") and vs:
            t["stribeck_velocity"] = float(vs)
    verdicts = (art.doc.get("diagnostics") or {}).get("verdicts")
    return write_mjcf(robot, p[: s.n_body_params], path, terms, verdicts=verdicts,
                      title=f"{art.label}; robot '{robot.name}'")


def _comment_urdf(path: Path, comment: str | None) -> None:
    """Insert ``<!-- comment -->`` after the XML declaration of ``path`` (atomic rewrite)."""
    if not comment:
        return
    from ..io import atomic_write_text

    text = path.read_text()
    line = "<!-- " + comment.replace("--", "–") + " -->\n"
    head, sep, rest = text.partition("?>\n") if text.startswith("<?xml") else ("", "", text)
    atomic_write_text(path, head + sep + line + rest if sep else line + text)


# ---- friction-only models (``sensorless friction``) -------------------------------------------
@dataclasses.dataclass
class FrictionArtifact:
    """A validated friction-only model folder: the document, the model
    (:class:`~.friction_model.FrictionModel`) and the preprocessing of its training logs."""

    path: Path
    doc: dict
    model: Any
    preprocessing: dict

    @property
    def folder(self) -> Path:
        return self.path.parent


def is_friction_model(model: str | Path) -> bool:
    """Whether ``model`` (a folder or its result.json) is a friction-only model; False when it is
    no readable model (the loader that follows names the problem)."""
    path = result_path(model)
    if not path.is_file():
        return False
    try:
        return read_result(path).get("kind") == FRICTION_KIND
    except SensorlessError:
        return False


def save_friction_model(directory: str | Path, model, doc: dict | None = None) -> dict:
    """Write ``directory/result.json`` of a fitted :class:`~.friction_model.FrictionModel`: ``kind``
    "friction", the joints, each joint's chosen and best static law, and ``doc`` (settings,
    diagnostics, validation) merged in. Returns the document written."""
    out = dict(doc or {})
    out.update({"kind": FRICTION_KIND, "joints": list(model.joint_names_),
                "laws": {j: model.laws_[j].to_dict() for j in model.joint_names_},
                "static_laws": {j: model.static_laws_[j].to_dict() for j in model.joint_names_
                                if j in model.static_laws_}})
    out.setdefault("settings", {})["friction"] = model.get_params()
    write_result(out, Path(directory) / RESULT)
    return out


def load_friction_model(model: str | Path) -> FrictionArtifact:
    """Read and validate a friction-only model folder (or its result.json): every law's kind, terms
    and numbers (:func:`.artifact_schema.check_friction_law`), the preprocessing settings."""
    from .artifact_schema import check_friction_law
    from .friction_model import FrictionModel

    path = result_path(model)
    check_input_file(path, "model file (result.json)")
    doc = read_result(path)
    c = Checker(path, path.parent)
    if doc.get("kind") != FRICTION_KIND:
        raise ParameterError(f"{path}: not a friction-only model (no \"kind\": \"friction\"); a model from "
                             f"`sensorless identify` needs {setting('robot')}")
    joints = c.strings("joints", doc.get("joints"))
    if not joints or len(set(joints)) != len(joints):
        raise c.fail("joints", "expected a non-empty list of distinct joint names")
    laws, static = c.mapping("laws", doc.get("laws")), c.mapping("static_laws", doc.get("static_laws", {}))
    missing = [j for j in joints if j not in laws]
    if missing:
        raise c.fail("laws", f"no law for joint(s) {missing}")
    settings = c.mapping("settings", doc.get("settings", {}))
    params = c.mapping("settings.friction", settings.get("friction", {}))
    pre = check_preprocessing_settings(c, settings.get("preprocessing"))
    fm = FrictionModel.from_laws({j: check_friction_law(c, f"laws.{j}", laws[j]) for j in joints},
                                 {j: check_friction_law(c, f"static_laws.{j}", static[j]) for j in joints if j in static},
                                 state=params.get("state", "auto") if params.get("state") in ("auto", "on", "off")
                                 else "auto")
    return FrictionArtifact(path, doc, fm, pre)
