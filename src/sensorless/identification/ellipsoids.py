"""Bounding ellipsoids of the bodies, for density-realisability constraints.

An ellipsoid ``E = {x : (x − c)ᵀ Σ_E⁻¹ (x − c) ≤ 1}`` with ``Σ_E = R diag(s²) Rᵀ``
(centre ``c``, semi-axes ``s``, principal axes the columns of ``R``), written in the
body's joint frame, has the homogeneous form

    [x; 1]ᵀ Q [x; 1] = 1 − (x − c)ᵀ Σ_E⁻¹ (x − c),   Q = [[−Σ_E⁻¹, Σ_E⁻¹ c], [cᵀ Σ_E⁻¹, 1 − cᵀ Σ_E⁻¹ c]]

which is ≥ 0 exactly inside ``E``. For a mass density ρ with pseudo-inertia
``J = ∫ [x; 1][x; 1]ᵀ ρ dV``, ``tr(J Q) = ∫ ρ (1 − (x − c)ᵀ Σ_E⁻¹ (x − c)) dV``; a body
can be realised by a density supported in ``E`` iff ``J ⪰ 0`` and ``tr(J Q) ≥ 0``
(Wensing, Kim & Slotine, RA-L 2018). ``tr(J Q) / m = 1 − E_ρ[(x − c)ᵀ Σ_E⁻¹ (x − c)]``
is the *density margin* reported per body (1 at the centre, 0 on the boundary).

Ellipsoids are built automatically (:func:`auto_ellipsoids`) as the minimum-volume
ellipsoid enclosing a point cloud per body:

* *kinematic* points: the joint origin, the origins of its child joints, every frame
  attached to the joint (merged fixed links, tool and sensor frames) and the prior CoM,
  each inflated by ``margin`` (default 0.06 m) in 14 directions, since links have a
  radius the kinematic skeleton does not show;
* *geometry* points, when a Pinocchio ``GeometryModel`` is given or can be loaded
  from the robot's URDF: the 8 corners of each collision shape's local bounding box,
  placed in the joint frame, plus the kinematic points (margin default 0.01 m).

With ``contain_prior=True`` an ellipsoid is scaled about its centre, if needed, until it
holds not only the prior body but any body near it. With ``μ`` the prior's CoM, ``C`` its
second moment about the CoM per unit mass and ``Σ_E`` the ellipsoid's shape matrix, a body
is realisable in ``E`` iff ``E_ρ[(x − c)ᵀ Σ_E⁻¹ (x − c)] = tr(Σ_E⁻¹ C) + ‖μ − c‖²_Σ ≤ 1``
(``‖v‖²_Σ = vᵀ Σ_E⁻¹ v``). The point cloud first gets the ball of radius ``r`` around ``μ``
(14 points), then the scale ``α`` makes, in ``α E``,

    α² ≥ s · tr(Σ_E⁻¹ C) + (‖μ − c‖_Σ + r / √λ_min(Σ_E))²,

so every body whose second moments about its CoM are at most ``s`` times the prior's
(``prior_slack``, default :data:`PRIOR_SLACK` = 4) and whose CoM lies within ``r`` of the
prior's (``com_margin``, default :data:`PRIOR_COM_MARGIN` = 7.5 cm, the 99.7th percentile of
``‖N(0, (2 cm)² I₃)‖``) is realisable. The prior
is then feasible (and so is the identification problem), and so is a true body that differs
from it as a CAD model differs from the real arm: over 200 draws of the perturbation of
``sensorless benchmark peers`` (mass ``×exp(N(0, 0.1))``, CoM ``+N(0, 2 cm)``, principal
moments ``×exp(N(0, 0.2))``, axes rotated ``N(0, 0.2 rad)``) every true UR5 and Panda body
(fingers included) lies inside (``tests/test_defaults.py`` checks 50 draws). Geometry alone does not suffice:
the UR5 wrists' URDF inertias do not fit in their meshes. ``prior_slack=1, com_margin=0``
is the smallest scaling that makes the prior realisable.
"""

from __future__ import annotations

import os
import warnings
from dataclasses import dataclass, field
from typing import Any, Mapping

import numpy as np
import pinocchio as pin

from ..errors import RobotModelError, RobotModelWarning, setting
from ..parameters import as_bodies, pseudo_inertia
from ..robot import Robot

__all__ = [
    "GEOMETRY_MARGIN",
    "KINEMATIC_MARGIN",
    "PRIOR_COM_MARGIN",
    "PRIOR_SLACK",
    "INFLATION_DIRECTIONS",
    "BoundingEllipsoid",
    "auto_ellipsoids",
    "body_points",
    "ellipsoid_source",
    "enclosing_ellipsoid",
    "load_geometry",
    "missing_meshes",
    "mvee",
    "resolve_ellipsoids",
]

KINEMATIC_MARGIN = 0.06  # m, link radius not visible in the kinematic skeleton
GEOMETRY_MARGIN = 0.01  # m, slack around collision shapes
PRIOR_SLACK = 4.0  # the prior must fit with its second moments × PRIOR_SLACK ...
PRIOR_COM_MARGIN = 0.075  # m, ... and its CoM moved anywhere within this distance

#: the 14 directions (axes and cube diagonals, unit) in which each point of a body's cloud is
#: inflated by the margin, and in which the prior's CoM ball is sampled
INFLATION_DIRECTIONS = np.vstack([np.eye(3), -np.eye(3), np.array(np.meshgrid([-1, 1], [-1, 1], [-1, 1])).reshape(3, -1).T / np.sqrt(3)])


@dataclass(frozen=True, eq=False)
class BoundingEllipsoid:
    """``{x : (x − center)ᵀ (R diag(semi_axes²) Rᵀ)⁻¹ (x − center) ≤ 1}`` in the joint frame."""

    center: np.ndarray
    semi_axes: np.ndarray
    rotation: np.ndarray = field(default_factory=lambda: np.eye(3))
    #: what it was built from (:func:`auto_ellipsoids`: "collision geometry", "kinematics (...)"; "given")
    source: str = ""

    def __post_init__(self) -> None:
        c = np.asarray(self.center, dtype=float).reshape(3)
        s = np.asarray(self.semi_axes, dtype=float).reshape(3)
        R = np.asarray(self.rotation, dtype=float).reshape(3, 3)
        if np.any(~np.isfinite(s)) or np.any(s <= 0):
            raise ValueError(f"ellipsoid semi-axes must be positive and finite, got {s}")
        if not np.allclose(R.T @ R, np.eye(3), atol=1e-6):
            raise ValueError("ellipsoid rotation must be orthonormal")
        object.__setattr__(self, "center", c)
        object.__setattr__(self, "semi_axes", s)
        object.__setattr__(self, "rotation", R)

    @classmethod
    def from_spec(cls, spec: BoundingEllipsoid | tuple | Mapping[str, Any]) -> BoundingEllipsoid:
        """From an ellipsoid, ``(center, semi_axes[, rotation])`` or a dict with those keys."""
        if isinstance(spec, BoundingEllipsoid):
            return spec
        if isinstance(spec, Mapping):
            return cls(spec["center"], spec["semi_axes"], spec.get("rotation", np.eye(3)), spec.get("source", "given"))
        return cls(*spec[:3], source="given")

    @classmethod
    def from_shape_matrix(cls, center: np.ndarray, shape: np.ndarray, source: str = "") -> BoundingEllipsoid:
        """From ``Σ_E`` (symmetric positive definite)."""
        lam, R = np.linalg.eigh(0.5 * (shape + shape.T))
        if np.linalg.det(R) < 0:
            R[:, 0] = -R[:, 0]
        return cls(center, np.sqrt(np.maximum(lam, 1e-12)), R, source)

    @property
    def shape_matrix(self) -> np.ndarray:
        """``Σ_E = R diag(s²) Rᵀ``."""
        return (self.rotation * self.semi_axes**2) @ self.rotation.T

    @property
    def Q(self) -> np.ndarray:
        """Homogeneous 4×4 form with ``[x; 1]ᵀ Q [x; 1] = 1 − (x − c)ᵀ Σ_E⁻¹ (x − c)``."""
        P = (self.rotation / self.semi_axes**2) @ self.rotation.T  # Σ_E⁻¹
        Pc = P @ self.center
        Q = np.empty((4, 4))
        Q[:3, :3] = -P
        Q[:3, 3] = Q[3, :3] = Pc
        Q[3, 3] = 1.0 - self.center @ Pc
        return Q

    def mahalanobis(self, points: np.ndarray) -> np.ndarray:
        """``(x − c)ᵀ Σ_E⁻¹ (x − c)`` for points ``(..., 3)`` (≤ 1 inside)."""
        d = (np.asarray(points, dtype=float) - self.center) @ self.rotation / self.semi_axes
        return np.einsum("...i,...i->...", d, d)

    def contains(self, points: np.ndarray, tol: float = 1e-9) -> np.ndarray:
        return self.mahalanobis(points) <= 1.0 + tol

    def density_margin(self, pi: np.ndarray) -> float:
        """``tr(J Q) / m`` of one body ``pi (10,)`` (≥ 0 if realisable inside; nan if m ≤ 0)."""
        pi = np.asarray(pi, dtype=float)
        if pi[0] <= 0:
            return float("nan")
        return float(np.sum(pseudo_inertia(pi) * self.Q) / pi[0])

    def scaled(self, factor: float) -> BoundingEllipsoid:
        """Semi-axes multiplied by ``factor`` (same centre and axes)."""
        return BoundingEllipsoid(self.center, self.semi_axes * factor, self.rotation, self.source)

    def to_dict(self) -> dict:
        return {"center": self.center.tolist(), "semi_axes": self.semi_axes.tolist(), "rotation": self.rotation.tolist(),
                **({"source": self.source} if self.source else {})}


# ---- point clouds -------------------------------------------------------------
def mvee(P: np.ndarray, eps: float = 1e-3, max_iter: int = 20000) -> tuple[np.ndarray, np.ndarray]:
    """Minimum-volume enclosing ellipsoid (Khachiyan with Todd–Yildirim away steps):
    centre and Σ_E, within a factor (1 + eps) of optimal, scaled to contain every point."""
    n, d = P.shape
    Qh = np.vstack([P.T, np.ones(n)])
    u = np.full(n, 1.0 / n)
    for _ in range(max_iter):
        X = (Qh * u) @ Qh.T
        M = np.einsum("in,in->n", Qh, np.linalg.solve(X, Qh))
        j = int(np.argmax(M))
        act = np.flatnonzero(u > 0)
        i = act[int(np.argmin(M[act]))]
        if M[j] <= (d + 1) * (1.0 + eps) and M[i] >= (d + 1) * (1.0 - eps):
            break
        if M[j] - (d + 1) >= (d + 1) - M[i]:  # toward the farthest point
            step = (M[j] - d - 1.0) / ((d + 1.0) * (M[j] - 1.0))
            u *= 1.0 - step
            u[j] += step
        else:  # away from the nearest supporting point
            step = min((d + 1.0 - M[i]) / ((d + 1.0) * (M[i] - 1.0)), u[i] / (1.0 - u[i]))
            u *= 1.0 + step
            u[i] -= step
            u[i] = max(u[i], 0.0)
    c = P.T @ u
    S = d * ((P.T * u) @ P - np.outer(c, c))  # Σ_E of the (approximate) MVEE
    dev = P - c
    worst = np.einsum("ni,ni->n", dev, np.linalg.solve(S, dev.T).T).max()
    return c, S * max(worst, 1.0)


def _fibonacci_sphere(n: int) -> np.ndarray:
    """``n`` unit vectors spread evenly over the sphere (a Fibonacci lattice), ``(n, 3)``."""
    i = np.arange(n) + 0.5
    z = 1.0 - 2.0 * i / n
    r = np.sqrt(1.0 - z * z)
    phi = np.pi * (1.0 + np.sqrt(5.0)) * i
    return np.stack([r * np.cos(phi), r * np.sin(phi), z], axis=1)


_SUPPORT_DIRS = _fibonacci_sphere(256)


def enclosing_ellipsoid(P: np.ndarray, eps: float = 1e-3) -> tuple[np.ndarray, np.ndarray]:
    """:func:`mvee` of the cloud ``P`` computed on few of its points: those farthest along each of
    256 directions (vertices of its convex hull, where an enclosing ellipsoid touches), then any point
    still outside added until none is. An ellipsoid enclosing a subset and every other point encloses
    the cloud, so this is the cloud's MVEE, within the same factor; no convex hull is needed (SciPy's
    Qhull costs ~0.08 s of import on every identification)."""
    idx = np.unique(np.argmax(P @ _SUPPORT_DIRS.T, axis=0))
    while True:
        c, S = mvee(P[idx], eps)
        dev = P - c
        dist = np.einsum("ni,ni->n", dev, np.linalg.solve(S, dev.T).T)
        outside = np.setdiff1d(np.flatnonzero(dist > 1.0 + 1e-12), idx)
        if outside.size == 0:
            return c, S * max(float(dist.max()), 1.0)
        idx = np.union1d(idx, outside)


def _children(model: pin.Model, jid: int) -> list[int]:
    return [j for j in range(1, model.njoints) if model.parents[j] == jid]


def body_points(robot: Robot, geometry: pin.GeometryModel | None = None) -> dict[str, np.ndarray]:
    """Per identified body (joint frame): joint origin, child joint origins, attached frames
    (operational points such as a remote centre of motion excepted: they are not material)
    and, with ``geometry``, the corners of each collision shape's local bounding box.

    The keys are ``robot.body_names`` in order; for a robot whose identified bodies are a
    subset of its Pinocchio tree (a transmission's coordinate robot: lumped or massless
    tree bodies are left out) only those bodies are returned."""
    m = robot.model
    pts: dict[int, list[np.ndarray]] = {j: [np.zeros(3)] for j in range(1, m.njoints)}
    for j in range(1, m.njoints):
        pts[j] += [m.jointPlacements[c].translation.copy() for c in _children(m, j)]
    for f in m.frames:
        if f.parentJoint >= 1 and f.type != pin.FrameType.OP_FRAME:
            pts[f.parentJoint].append(f.placement.translation.copy())
    if geometry is not None:
        for go in geometry.geometryObjects:
            j = go.parentJoint
            if j < 1 or j >= m.njoints:
                continue
            geo = go.geometry
            geo.computeLocalAABB()
            lo, hi = np.asarray(geo.aabb_local.min_), np.asarray(geo.aabb_local.max_)
            if not (np.all(np.isfinite(lo)) and np.all(np.isfinite(hi))):
                continue
            corners = np.array(np.meshgrid(*zip(lo, hi))).reshape(3, -1).T
            M = go.placement
            pts[j] += list(corners @ M.rotation.T + M.translation)
    tree_names = list(m.names)
    missing = [b for b in robot.body_names if b not in tree_names[1:]]
    if missing:
        raise RobotModelError(f"{robot.name}: bodies {missing} are not joints of its Pinocchio model")
    return {b: np.unique(np.round(np.array(pts[tree_names.index(b)]), 12), axis=0) for b in robot.body_names}


_GEOMETRY_CACHE: dict[tuple, tuple[pin.GeometryModel | None, list[dict]]] = {}


def load_geometry(robot: Robot, kind: str = "collision") -> pin.GeometryModel | None:
    """The robot's collision (or visual) ``GeometryModel`` from its URDF, or None if the URDF
    cannot be read. A mesh that is missing or outside the allowed folders is left out, and one
    RobotModelWarning (when the robot's geometry is first loaded) names each such file and the
    ellipsoid its body gets instead (:func:`missing_meshes`). Cached per (URDF and its modification time, bodies, kind, package folders)."""
    return _cached_geometry(robot, kind)[0]


def missing_meshes(robot: Robot, kind: str = "collision") -> list[dict]:
    """The meshes :func:`load_geometry` left out: ``{"link", "body", "file", "reason"}`` each
    (``body``: the identified body the link belongs to, or None)."""
    return _cached_geometry(robot, kind)[1]


def _cached_geometry(robot: Robot, kind: str) -> tuple[pin.GeometryModel | None, list[dict]]:
    urdf = getattr(robot, "urdf_path", None)
    try:
        stamp = (os.stat(urdf).st_mtime_ns, os.stat(urdf).st_size) if urdf else None
    except OSError:
        stamp = None
    key = (urdf, stamp, robot.source, robot.body_names, kind, tuple(getattr(robot, "package_paths", ())))
    if key not in _GEOMETRY_CACHE:
        _GEOMETRY_CACHE[key] = _load_geometry(robot, kind)
    return _GEOMETRY_CACHE[key]


def _load_geometry(robot: Robot, kind: str) -> tuple[pin.GeometryModel | None, list[dict]]:
    """Meshes are read only under the description's folder and its package folders
    (:func:`~sensorless.robot_paths.confine_urdf_meshes`: others are left out and reported);
    an example-robot-data robot's own package tree is one of them."""
    from ..robot_paths import confine_urdf_meshes

    urdf = getattr(robot, "urdf_path", None) or (robot.source if str(robot.source).endswith(".urdf") else None)
    if not urdf or not os.path.exists(urdf):
        return None, []
    path = os.path.normpath(urdf)
    packages = list(getattr(robot, "package_paths", ()))
    base = getattr(robot, "description_dir", None) or os.path.dirname(path)
    if str(robot.source).startswith("example-robot-data:"):  # the installed package's own tree
        packages += [os.path.dirname(os.path.dirname(path)), os.path.dirname(os.path.dirname(os.path.dirname(path)))]
        if "/example-robot-data/" in path:
            packages.insert(0, path.split("/example-robot-data/")[0])
    gtype = pin.GeometryType.COLLISION if kind == "collision" else pin.GeometryType.VISUAL
    src, dropped = str(robot.source or path), []
    try:
        with open(path, encoding="utf-8") as f:
            text = confine_urdf_meshes(f.read(), base, packages, src, dropped)
        geom = pin.buildGeomFromUrdfString(robot.model, text, gtype, package_dirs=[])
    except Exception as exc:  # noqa: BLE001 - unreadable file or mesh, unknown links: fall back to kinematics
        warnings.warn(f"{src}: its {kind} geometry could not be read ({' '.join(str(exc).split())[:300]}); every "
                      f"bounding ellipsoid comes from {_KINEMATIC_TEXT}", RobotModelWarning, stacklevel=2)
        return None, []
    missing = [{**d, "body": _body_of(robot, d["link"])} for d in dropped if d["kind"] == kind]
    if missing:
        warnings.warn(_missing_message(src, kind, missing, _geometry_bodies(robot, geom)), RobotModelWarning,
                      stacklevel=2)
    return geom, missing


_KINEMATIC_TEXT = f"the kinematics (joint positions and frames, {100 * KINEMATIC_MARGIN:g} cm margin)"


def _body_of(robot: Robot, link: str | None) -> str | None:
    m = robot.model
    if link is None or not m.existFrame(link):
        return None
    name = m.names[m.frames[m.getFrameId(link)].parentJoint]
    return name if name in robot.body_names else None


def _geometry_bodies(robot: Robot, geometry: pin.GeometryModel | None) -> set[str]:
    """The identified bodies with at least one shape in ``geometry``."""
    if geometry is None:
        return set()
    return {robot.model.names[go.parentJoint] for go in geometry.geometryObjects
            if 1 <= go.parentJoint < robot.model.njoints} & set(robot.body_names)


def _missing_message(src: str, kind: str, missing: list[dict], with_geometry: set[str]) -> str:
    """One warning for every mesh left out: the files grouped by reason, then each body's ellipsoid."""
    by_reason: dict[str, list[str]] = {}
    for m in missing:
        by_reason.setdefault(m["reason"], []).append(f"{m['file']!r} (link {m['link']})")
    files = "; ".join(f"{', '.join(f)}: {why}" for why, f in by_reason.items())
    bodies = list(dict.fromkeys(m["body"] for m in missing if m["body"] is not None))
    kin = [b for b in bodies if b not in with_geometry]
    part = [b for b in bodies if b in with_geometry]
    instead = "; ".join(([f"from {_KINEMATIC_TEXT} for {', '.join(kin)}"] if kin else [])
                        + ([f"from their other {kind} shapes and joint positions for {', '.join(part)}"] if part else []))
    return (f"{src}: {len(missing)} {kind} mesh(es) left out of the bounding ellipsoids: {files}. "
            + (f"Bounding ellipsoids used instead: {instead}; the identified masses depend on them (source per body "
               "in result.json diagnostics.ellipsoid_sources). " if bodies else "No identified body uses them. ")
            + f"Add the meshes' folder with {setting('package_paths', placeholder='DIR')}")


def ellipsoid_source(has_geometry: bool, lost_mesh: bool, geometry_loaded: bool = True) -> str:
    """The ``source`` of an automatic ellipsoid (:attr:`BoundingEllipsoid.source`)."""
    if not geometry_loaded:
        return "kinematics"
    if has_geometry:
        return "collision geometry (partial: mesh missing)" if lost_mesh else "collision geometry"
    return "kinematics (collision mesh missing)" if lost_mesh else "kinematics (no collision geometry)"


def _prior_scale(E: BoundingEllipsoid, pi: np.ndarray, slack: float = 1.0, com_margin: float = 0.0) -> float:
    """Smallest α ≥ 1 with ``α² ≥ slack·tr(Σ_E⁻¹ C) + (‖μ − c‖_Σ + com_margin/√λ_min(Σ_E))²``
    (module docstring; ``slack = 1, com_margin = 0``: the prior just realisable)."""
    if pi[0] <= 0:
        return 1.0
    total = max(1.0 - E.density_margin(pi), 0.0)  # E_ρ0[d²] = tr(Σ_E⁻¹ C) + ‖μ − c‖²_Σ
    offset = float(E.mahalanobis(np.asarray(pi[1:4], dtype=float) / pi[0]))
    spread = max(total - offset, 0.0)
    reach = np.sqrt(offset) + com_margin / float(E.semi_axes.min())
    return max(1.0, float(np.sqrt(slack * spread + reach**2)) * (1.0 + 1e-6))


def auto_ellipsoids(
    robot: Robot,
    *,
    geometry: pin.GeometryModel | str | None = "auto",
    margin: float | None = None,
    prior: np.ndarray | None = None,
    contain_prior: bool = True,
    prior_slack: float = PRIOR_SLACK,
    com_margin: float = PRIOR_COM_MARGIN,
) -> dict[str, BoundingEllipsoid]:
    """One bounding ellipsoid per body (see module docstring).

    ``geometry``: a ``GeometryModel``, ``"auto"`` (load the URDF's collision geometry when
    possible) or None (kinematic points only). ``margin`` defaults, per body, to
    :data:`KINEMATIC_MARGIN` where its shape is unknown (no geometry, or its meshes missing) and
    :data:`GEOMETRY_MARGIN` otherwise. Each ellipsoid's ``source`` says which.
    ``prior`` (10·n_bodies) defaults to the model's inertials; with ``contain_prior`` each
    ellipsoid is grown to hold any body within ``prior_slack`` (≥ 1) and ``com_margin`` [m]
    of it.
    """
    if not (np.isfinite(prior_slack) and prior_slack >= 1.0):
        raise ValueError(f"prior_slack must be a number >= 1, got {prior_slack}")
    if not (np.isfinite(com_margin) and com_margin >= 0.0):
        raise ValueError(f"com_margin must be a number >= 0, got {com_margin}")
    if not (geometry is None or isinstance(geometry, str)):  # a caller's GeometryModel: not memoised
        return _auto_ellipsoids(robot, geometry, margin, prior, contain_prior, prior_slack, com_margin)
    # memoised on the robot: a run asks for the same ellipsoids for the fit, each γ fold and the checks
    p0 = robot.inertial_parameters() if prior is None else np.asarray(prior, dtype=float)
    key = (geometry, margin, p0.tobytes(), contain_prior, prior_slack, com_margin)
    memo = robot.__dict__.setdefault("_auto_ellipsoids", {})
    if key not in memo:
        memo[key] = _auto_ellipsoids(robot, geometry, margin, prior, contain_prior, prior_slack, com_margin)
    return dict(memo[key])


def _auto_ellipsoids(robot, geometry, margin, prior, contain_prior, prior_slack, com_margin) -> dict:
    lost: set = set()
    if isinstance(geometry, str):
        if geometry != "auto":
            raise RobotModelError(f"geometry must be a GeometryModel, 'auto' or None, got {geometry!r}")
        geometry = load_geometry(robot)
        lost = {m["body"] for m in missing_meshes(robot)}
    if margin is not None and margin <= 0:
        raise ValueError("ellipsoid margin must be positive (a point cloud can be flat)")
    shaped = _geometry_bodies(robot, geometry)
    P0 = as_bodies(robot.inertial_parameters() if prior is None else np.asarray(prior)[: 10 * robot.n_bodies])
    out = {}
    for k, (name, pts) in enumerate(body_points(robot, geometry).items()):
        if P0[k, 0] > 0:
            com = P0[k, 1:4] / P0[k, 0]
            pts = np.vstack([pts, com] + ([com + com_margin * INFLATION_DIRECTIONS] if contain_prior and com_margin > 0 else []))
        # the kinematic margin where the body's shape is unknown: no geometry at all, or its meshes missing;
        # a body the description gives no shape (authored in code, e.g. the PSM's links) keeps the geometry margin
        unknown = geometry is None or (name in lost and name not in shaped)
        m = margin if margin is not None else KINEMATIC_MARGIN if unknown else GEOMETRY_MARGIN
        cloud = (pts[:, None, :] + m * INFLATION_DIRECTIONS[None]).reshape(-1, 3)
        E = BoundingEllipsoid.from_shape_matrix(*enclosing_ellipsoid(cloud), source=ellipsoid_source(
            name in shaped, name in lost, geometry is not None))
        if contain_prior:
            E = E.scaled(_prior_scale(E, P0[k], prior_slack, com_margin))
        out[name] = E
    return out


def resolve_ellipsoids(
    robot: Robot,
    spec: Mapping[str, Any] | bool | str | None,
    prior: np.ndarray | None = None,
    **auto_kwargs: Any,
) -> dict[str, BoundingEllipsoid]:
    """Ellipsoids from the ``ellipsoids`` option of the solver.

    ``None``/``True``/``"auto"``: :func:`auto_ellipsoids`; ``"kinematic"``: automatic
    without geometry; ``False``: none (no density constraint); a mapping
    ``{body: BoundingEllipsoid | (center, semi_axes[, rotation])}``: those bodies as given,
    the others automatic.
    """
    if spec is False:
        return {}
    if spec is None or spec is True or spec == "auto":
        return auto_ellipsoids(robot, prior=prior, **auto_kwargs)
    if spec == "kinematic":
        return auto_ellipsoids(robot, prior=prior, geometry=None, **auto_kwargs)
    if isinstance(spec, str):
        raise RobotModelError(f"ellipsoids must be None, False, 'auto', 'kinematic' or a mapping, got {spec!r}")
    unknown = [b for b in spec if b not in robot.body_names]
    if unknown:
        raise RobotModelError(f"ellipsoids given for unknown bodies {unknown}; bodies are {list(robot.body_names)}")
    given = {b: BoundingEllipsoid.from_spec(e) for b, e in spec.items()}
    auto = auto_ellipsoids(robot, prior=prior, **auto_kwargs) if len(given) < robot.n_bodies else {}
    return {b: given[b] if b in given else auto[b] for b in robot.body_names}
