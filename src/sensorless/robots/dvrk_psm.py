"""da Vinci Research Kit Patient Side Manipulator (PSM): a coupled-joint dynamic model.

Geometry: the modified-DH *geometric tree* of Wang, Gondokaryono, Munawar & Fischer,
"A Convex Optimization-Based Dynamic Model Identification Package for the da Vinci
Research Kit", RA-L 2019 (model ``psm`` of their identification package), with the
published lengths [m]

    l_2L1 = 0.096, l_2L2 = 0.516, l_2L3 = 0.04009, l_2H1 = 0.14454, l_2H2 = 0.03808,
    l_3 = 0.04009, l_RCC = 0.4318, l_tool = 0.4162, l_p2y = 0.0091.

Each frame i is placed on its parent by T = RotX(α) TransX(a) RotZ(θ) TransZ(d) (Craig's
modified DH). The closed parallelogram is a serial tree whose extra joints are slaved to
the pitch q2 (θ = −q2 on the front links, +q2 on the bottom/top links); the insertion
q3 moves two prismatic bodies (pitch end and main insertion carriage). Tree joints
(Pinocchio order) and their drive in the coordinates θ = (q1, q2, q3, q4, m5, m6, m7):

    =====================  =========  ==================================  =======================
    joint                  parent     a, α, d, θ (constant part)          joint value
    =====================  =========  ==================================  =======================
    yaw                    base       0, π/2, 0, π/2                      q1
    pitch                  yaw        0, −π/2, 0, −π/2                    q2
    pitch_back (fixed)     pitch      l_2L3, 0, 0, π/2                    —  (merged)
    pitch_front            pitch_back l_2H1, 0, 0, π/2                    −q2
    pitch_front_ext        pitch_back l_2H1 + l_2H2, 0, 0, π/2            −q2
    pitch_bottom           pitch_front l_2L2, 0, 0, 0                      q2
    pitch_top              pitch_front l_2L1, 0, 0, π                      q2   (counterweight side)
    pitch_end   (prism.)   pitch_bottom l_3, −π/2, l_2H1 − l_RCC, 0       q3
    insertion   (prism.)   pitch      l_2L3, −π/2, 0, 0                   q3
    roll                   pitch_end  0, 0, l_tool, 0                     q4
    wrist_pitch            roll       0, π/2, 0, π/2                      1.0186 m5
    jaw_1                  wrist_pitch l_p2y, −π/2, 0, π/2                −0.8306 m5 + 1.2178 m6
    jaw_2                  wrist_pitch l_p2y, −π/2, 0, π/2                −0.8306 m5 + 1.2178 m7
    =====================  =========  ==================================  =======================

Gravity is −9.81 m/s² along z of the base frame 0 (the authors' default). m5..m7 are the
*motor* coordinates of the cable-coupled wrist, as logged by the WPI recording script
(dVRK joints = M · motors, M = [[1.0186, 0, 0], [−0.8306, 0.6089, 0.6089], [0, −1.2177, 1.2177]];
the tree uses the authors' rounded coupling 1.0186 / −0.8306 / 1.2178).

Drive terms (:class:`~sensorless.regressor.drive_terms.DriveTerm`), as in the authors' model:
viscous + Coulomb + offset friction on q1, q2, q3, q4, on the wrist pitch, on each jaw and
on the jaw opening (jaw_2 − jaw_1, the q6–q7 coupled friction) and directly on motors 6 and 7;
motor (rotor) inertia on q4, on the wrist pitch and on motors 6 and 7; a torsion spring
on the tool roll, τ₄ += k q4 (− k·q_rest, which is one base parameter with the offset).

The CSV logs of the WPI data set are header-less, 200 Hz, 21 columns (q, q̇, effort of the
7 coordinates; insertion in m and N). Do not copy them into a repository (no licence).
"""

from __future__ import annotations

import functools
import json
from collections.abc import Sequence
from pathlib import Path

import numpy as np
import pinocchio as pin

from ..data import Trajectory, lowpass, read_trajectory
from ..errors import DataError, RobotModelError
from ..regressor.drive_terms import DriveTerm
from ..regressor.transmission import (
    TransmissionStructure,
    add_body_joint,
    coupling_matrix,
)
from ..robot import Robot

__all__ = [
    "COORDINATES",
    "INSERTION_SMOOTHING_RATIO",
    "LENGTHS",
    "MOTOR_TO_JOINT",
    "PSM_BODIES_AUTHORS",
    "PSM_FRAMES",
    "PSM_LIMITS",
    "mdh_placement",
    "psm_drives",
    "psm_robot",
    "psm_structure",
    "psm_tree",
    "published_parameters",
    "read_psm_log",
]

LENGTHS = {
    "l_2L1": 0.096,
    "l_2L2": 0.516,
    "l_2L3": 0.04009,
    "l_2H1": 0.14454,
    "l_2H2": 0.03808,
    "l_3": 0.04009,
    "l_RCC": 0.4318,
    "l_tool": 0.4162,
    "l_p2y": 0.0091,
}
MOTOR_TO_JOINT = np.array([[1.0186, 0.0, 0.0], [-0.8306, 0.6089, 0.6089], [0.0, -1.2177, 1.2177]])
"""dVRK wrist joints (pitch, yaw, jaw) = MOTOR_TO_JOINT @ motors (m5, m6, m7)."""

COORDINATES = ("q1", "q2", "q3", "q4", "m5", "m6", "m7")
WRIST_PITCH, JAW_M5, JAW_MOTOR = 1.0186, -0.8306, 1.2178

# Bodies that carry inertia in the authors' model (links 1, 2, 4–9); the tool links are massless there.
PSM_BODIES_AUTHORS = ("yaw", "pitch", "pitch_front", "pitch_front_ext", "pitch_bottom", "pitch_top", "pitch_end", "insertion")

# Box limits of the coordinates used for excitation design: the envelope of the WPI
# excitation logs, rounded outwards (not the official dVRK joint limits), and velocity limits.
PSM_LIMITS = {
    "lower": np.array([-0.60, -0.80, 0.065, -1.45, -0.70, -1.25, -1.0]),
    "upper": np.array([0.10, 0.82, 0.235, 1.45, 0.70, 0.75, 1.45]),
    "velocity": np.array([1.6, 1.6, 0.33, 2.5, 2.7, 2.7, 2.9]),
    "acceleration": np.array([10.0, 10.0, 2.0, 15.0, 20.0, 20.0, 20.0]),
}

# Authors' link numbers in params.json → tree bodies; drive terms by link number.
_AUTHOR_BODY = {1: "yaw", 2: "pitch", 4: "pitch_front", 5: "pitch_front_ext", 6: "pitch_bottom", 7: "pitch_top", 8: "pitch_end", 9: "insertion"}
_AUTHOR_DRIVE = {1: "q1", 2: "q2", 8: "q3", 10: "q4", 11: "wrist_pitch", 12: "jaw_1", 13: "jaw_2", 14: "m6", 15: "m7", 16: "jaw_opening"}


def mdh_placement(a: float, alpha: float, d: float, theta: float) -> pin.SE3:
    """Craig's modified DH transform RotX(α) TransX(a) RotZ(θ) TransZ(d)."""
    R = pin.utils.rotate("x", alpha) @ pin.utils.rotate("z", theta)
    p = np.array([a, -np.sin(alpha) * d, np.cos(alpha) * d])
    return pin.SE3(R, p)


def _table():
    L = LENGTHS
    back = mdh_placement(L["l_2L3"], 0.0, 0.0, np.pi / 2)  # fixed frame 'pitch back' (massless)
    h = np.pi / 2
    return [
        # name, parent, placement, kind, coupling
        ("yaw", None, mdh_placement(0, h, 0, h), "revolute", {"q1": 1.0}),
        ("pitch", "yaw", mdh_placement(0, -h, 0, -h), "revolute", {"q2": 1.0}),
        ("pitch_front", "pitch", back * mdh_placement(L["l_2H1"], 0, 0, h), "revolute", {"q2": -1.0}),
        ("pitch_front_ext", "pitch", back * mdh_placement(L["l_2H1"] + L["l_2H2"], 0, 0, h), "revolute", {"q2": -1.0}),
        ("pitch_bottom", "pitch_front", mdh_placement(L["l_2L2"], 0, 0, 0), "revolute", {"q2": 1.0}),
        ("pitch_top", "pitch_front", mdh_placement(L["l_2L1"], 0, 0, np.pi), "revolute", {"q2": 1.0}),
        ("pitch_end", "pitch_bottom", mdh_placement(L["l_3"], -h, L["l_2H1"] - L["l_RCC"], 0), "prismatic", {"q3": 1.0}),
        ("insertion", "pitch", mdh_placement(L["l_2L3"], -h, 0, 0), "prismatic", {"q3": 1.0}),
        ("roll", "pitch_end", mdh_placement(0, 0, L["l_tool"], 0), "revolute", {"q4": 1.0}),
        ("wrist_pitch", "roll", mdh_placement(0, h, 0, h), "revolute", {"m5": WRIST_PITCH}),
        ("jaw_1", "wrist_pitch", mdh_placement(L["l_p2y"], -h, 0, h), "revolute", {"m5": JAW_M5, "m6": JAW_MOTOR}),
        ("jaw_2", "wrist_pitch", mdh_placement(L["l_p2y"], -h, 0, h), "revolute", {"m5": JAW_M5, "m7": JAW_MOTOR}),
    ]


def _frames() -> list[tuple[str, str, pin.SE3]]:
    """Operational frames (name, parent joint, placement in the joint frame).

    * ``rcm``: the remote centre of motion, on the instrument axis l_RCC beyond the
      insertion frame at q3 = 0. It is placed on ``pitch_bottom`` (the body the shaft slides
      in), so it is fixed in space for every (q1, q2, q3) and its z axis is the instrument
      axis pointing to the tip. Being the fixed point, its linear Jacobian is zero.
    * ``tool_tip``: the end of the instrument's wrist, on the wrist-pitch body at the jaw
      (wrist-yaw) axis, l_p2y beyond the wrist-pitch axis (the shaft ends l_tool past the
      insertion frame); axes of the jaw frames at zero jaw angle. The jaw length itself is not
      in the model (tool-specific): forces at the jaw tips act here with their moment arm lost.
    """
    L = LENGTHS
    h = np.pi / 2
    insertion_zero = mdh_placement(L["l_3"], -h, L["l_2H1"] - L["l_RCC"], 0)  # pitch_end at q3 = 0
    return [
        ("rcm", "pitch_bottom", insertion_zero * pin.SE3(np.eye(3), np.array([0.0, 0.0, L["l_RCC"]]))),
        ("tool_tip", "wrist_pitch", mdh_placement(L["l_p2y"], -h, 0, h)),
    ]


PSM_FRAMES = ("rcm", "tool_tip")
"""Operational frames of the PSM tree besides one frame per joint (see :func:`psm_tree`)."""

def psm_tree() -> tuple[Robot, np.ndarray]:
    """The Pinocchio tree (massless bodies; 12 joints) and its coupling matrix G (12 × 7).

    Frames: one per joint (same name) plus :data:`PSM_FRAMES` (``rcm``, ``tool_tip``)."""
    model = pin.Model()
    model.name = "dvrk_psm"
    ids: dict[str, int] = {}
    rules = {}
    for name, parent, placement, kind, coupling in _table():
        ids[name] = add_body_joint(model, 0 if parent is None else ids[parent], name, placement, kind)
        rules[name] = coupling
    for name, parent, placement in _frames():
        jid = ids[parent]
        model.addFrame(pin.Frame(name, jid, model.getFrameId(parent), placement, pin.FrameType.OP_FRAME))
    # joint limits of the tree induced by the coordinate box (informative only)
    robot = Robot(model, name="dvrk_psm", source="sensorless.robots.dvrk_psm (WPI modified-DH tree)")
    G = coupling_matrix(robot.joint_names, COORDINATES, rules)
    return robot, G


INSERTION_SMOOTHING_RATIO = 0.2
"""Coulomb smoothing of the insertion (m/s) relative to the rotary drives (rad/s): its
velocities are ~5× smaller (velocity limit 0.33 m/s vs 1.6 rad/s)."""


def psm_drives(terms: str = "authors", coulomb_smoothing: float = 0.0) -> list[DriveTerm]:
    """Drive terms: ``"authors"`` (see module docstring) or ``"motors"`` (friction and
    rotor inertia on each of the 7 coordinates, spring on q4, coupled jaw friction).
    ``coulomb_smoothing`` [rad/s] is the tanh smoothing velocity of the rotary drives; the
    insertion uses :data:`INSERTION_SMOOTHING_RATIO` times it (in m/s)."""
    e = np.eye(7)
    fr = ("fv", "fc", "offset")
    eps3 = INSERTION_SMOOTHING_RATIO * coulomb_smoothing
    jaw1 = JAW_M5 * e[4] + JAW_MOTOR * e[5]
    jaw2 = JAW_M5 * e[4] + JAW_MOTOR * e[6]
    if terms == "authors":
        return [
            DriveTerm("q1", e[0], fr),
            DriveTerm("q2", e[1], fr),
            DriveTerm("q3", e[2], fr, smoothing=eps3),
            DriveTerm("q4", e[3], fr + ("inertia", "spring")),
            DriveTerm("wrist_pitch", WRIST_PITCH * e[4], fr + ("inertia",)),
            DriveTerm("jaw_1", jaw1, fr),
            DriveTerm("jaw_2", jaw2, fr),
            DriveTerm("m6", e[5], fr + ("inertia",)),
            DriveTerm("m7", e[6], fr + ("inertia",)),
            DriveTerm("jaw_opening", jaw2 - jaw1, fr),
        ]
    if terms == "motors":
        out = [
            DriveTerm(c, e[k], fr + ("inertia",) + (("spring",) if c == "q4" else ()), smoothing=eps3 if c == "q3" else None)
            for k, c in enumerate(COORDINATES)
        ]
        return out + [DriveTerm("jaw_opening", jaw2 - jaw1, fr)]
    raise RobotModelError(f"unknown PSM drive set '{terms}'; use 'authors' or 'motors'")


def psm_structure(
    bodies: str | Sequence[str] = "authors",
    drives: str | Sequence[DriveTerm] = "authors",
    coulomb_smoothing: float = 0.0,
) -> TransmissionStructure:
    """Identification structure of the PSM in coordinates (q1, q2, q3, q4, m5, m6, m7).

    ``bodies``: ``"authors"`` (the 8 bodies with inertia in the authors' model), ``"all"``
    (also the roll, wrist and jaw links) or a list of tree body names. ``coulomb_smoothing``
    [rad/s]: sgn(ṡ) → tanh(ṡ/ε) in the friction terms (0: sign); see :func:`psm_drives`.
    """
    tree, G = psm_tree()
    if isinstance(bodies, str):
        if bodies not in ("authors", "all"):
            raise RobotModelError(f"bodies must be 'authors', 'all' or a list of names, got '{bodies}'")
        bodies = PSM_BODIES_AUTHORS if bodies == "authors" else tree.body_names
    drive_list = psm_drives(drives, coulomb_smoothing) if isinstance(drives, str) else list(drives)
    structure = TransmissionStructure(
        tree, G, COORDINATES, drives=drive_list, bodies=bodies,
        limits=(PSM_LIMITS["lower"], PSM_LIMITS["upper"]), velocity_limits=PSM_LIMITS["velocity"],
        coulomb_smoothing=coulomb_smoothing, name="dvrk_psm",
    )
    default_drives = drives if isinstance(drives, str) else drive_list
    structure.robot.factory = functools.partial(_rebuild, bodies, default_drives)  # picklable (Dask workers)
    structure.robot.excitation_box = PSM_LIMITS  # excitation design uses the logs' envelope as is
    return structure


def _rebuild(bodies, default_drives, terms, coulomb_smoothing: float) -> TransmissionStructure:
    """The PSM structure with another drive set (``terms``) or Coulomb smoothing (``robot.make_structure``)."""
    return psm_structure(bodies, _drive_set(terms, default_drives), coulomb_smoothing)


# the generic per-joint terms of URDF robots (the CLI default of --joint-terms, now and before Stribeck friction
# joined it): the PSM uses a drive set instead
_URDF_DEFAULT_TERMS = {("fv", "fc", "stribeck", "offset", "armature"), ("fv", "fc", "offset", "armature")}


def _drive_set(terms, default):
    """Drive set of a ``--joint-terms`` value: "authors" | "motors"; None or the URDF default → ``default``."""
    if terms is None:
        return default
    if isinstance(terms, str):
        terms = tuple(t.strip() for t in terms.split(",") if t.strip())
    terms = tuple(terms)
    if terms in _URDF_DEFAULT_TERMS:
        return default
    if len(terms) == 1 and terms[0] in ("authors", "motors"):
        return terms[0]
    raise RobotModelError(
        f"the dVRK PSM takes a drive set as joint terms: 'authors' (default) or 'motors', got {','.join(terms)!r}"
    )


def psm_robot(
    bodies: str | Sequence[str] = "authors",
    drives: str | Sequence[DriveTerm] = "authors",
    coulomb_smoothing: float = 0.0,
):
    """The PSM as a robot in the coordinates (q1, q2, q3, q4, m5, m6, m7): the
    :class:`~sensorless.regressor.transmission.CoordinateRobot` of :func:`psm_structure`.

    It is what ``--robot dvrk_psm`` loads: logs are read in its coordinates, frames
    (``tool_tip``, ``rcm``, one per joint) resolve in the tree and their Jacobians are mapped
    through G, and ``robot.make_structure(drive_set, ε)`` builds its identification structure.
    """
    return psm_structure(bodies, drives, coulomb_smoothing).robot


def read_psm_log(
    path: str | Path,
    *,
    cutoff_hz: float | None = 5.4,
    order: int = 4,
    rate: float = 200.0,
) -> Trajectory:
    """A WPI PSM log (header-less CSV: q, q̇, effort × 7 at ``rate`` Hz) as a Trajectory in
    :data:`COORDINATES`, with q, q̇ and effort low-passed (zero-phase Butterworth of
    ``order`` at ``cutoff_hz``; None: raw) and q̈ the central difference of the filtered q̇.
    The unfiltered effort is kept in ``extras["tau_raw"]``."""
    cols = {"q": "0:7", "v": "7:14", "tau": "14:21"}
    traj = read_trajectory(path, columns=cols, rate=rate, joint_names=COORDINATES)
    if traj.n_joints != 7:
        raise DataError(f"expected 7 coordinates (21 columns), got {traj.n_joints}", str(path))
    raw = traj.tau.copy()
    if cutoff_hz:
        traj = lowpass(traj, cutoff_hz, order=order, fields=("q", "v", "tau"))
    a = np.gradient(traj.v, traj.t, axis=0)
    return traj.with_(a=a, extras={**traj.extras, "tau_raw": raw})


def published_parameters(
    structure: TransmissionStructure,
    params_json: str | Path,
    *,
    wrist_inertia_factor: float = WRIST_PITCH,
) -> np.ndarray:
    """Map the authors' ``params.json`` (per link: m, r, I, Fc, Fv, Fo, K, Im) onto the
    parameter vector of a PSM structure built with the authors' drive set.

    Conventions (from the authors' package): ``r`` is the centre of mass in the link's
    MDH frame, ``I`` = [xx, xy, xz, yy, yz, zz] the inertia *about the centre of mass*
    in that frame's axes (converted with π = Inertia(m, r, I).toDynamicParameters(),
    i.e. about the joint origin); friction f = Fc sgn(ṡ) + Fv ṡ + Fo on each link's
    joint coordinate s; spring τ₄ += K q4; rotor inertia added as Im·s̈ to the equation
    of the coordinate s depends on (for the wrist pitch s = 1.0186 m5 this is
    1.0186·Im·m̈5, whereas the drive term here is 1.0186²·inertia·m̈5, hence the factor).
    """
    path = Path(params_json)
    try:
        doc = json.loads(path.read_text())
    except (OSError, json.JSONDecodeError) as exc:
        raise DataError(f"cannot read the published parameters: {exc}", str(path)) from None
    p = np.zeros(structure.n_params)
    bodies = list(structure.robot.body_names)
    for link, body in _AUTHOR_BODY.items():
        e = doc[str(link)]
        if body not in bodies:
            if e["m"] != 0.0:
                raise RobotModelError(f"published link {link} ({body}) has mass {e['m']} but the structure has no body '{body}'")
            continue
        xx, xy, xz, yy, yz, zz = e["I"]
        I = np.array([[xx, xy, xz], [xy, yy, yz], [xz, yz, zz]])
        k = bodies.index(body)
        p[10 * k : 10 * k + 10] = pin.Inertia(float(e["m"]), np.asarray(e["r"], float), I).toDynamicParameters()
    for link, drive in _AUTHOR_DRIVE.items():
        e = doc[str(link)]
        for term, key in (("fc", "Fc"), ("fv", "Fv"), ("offset", "Fo")):
            p[structure.joint_term_index(drive, term)] = e[key]
        if e.get("Im", 0.0):
            factor = wrist_inertia_factor / WRIST_PITCH**2 if drive == "wrist_pitch" else 1.0
            p[structure.joint_term_index(drive, "inertia")] = e["Im"] * factor
        if e.get("K", 0.0):
            p[structure.joint_term_index(drive, "k")] = e["K"]
    return p
