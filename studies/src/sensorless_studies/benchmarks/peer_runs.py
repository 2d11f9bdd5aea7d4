"""Fits of a `sensorless benchmark peers` case as separate processes, timed from process start to result file.

* ``sensorless identify --robot ROBOT --data log.npz --out DIR --force [FLAGS]``: a fresh process of
  this Python (same ``sys.path``); its model is read back with :func:`~sensorless.identification.artifact.load_model_folder`.
* a peer NAME (figaroh, rigeo, ...): ``VENV/bin/python DRIVER CASE.npz OUT.npz``, the peer's own virtual
  environment (default ``$XDG_CACHE_HOME/sensorless-peers/NAME``, else ``~/.cache/...``; ``make peers``
  creates them) running ``DRIVER = DRIVERS/NAME_driver.py`` (``studies/benchmarks/peer_drivers/`` of the source
  tree; not ``NAME.py``, which would shadow the peer's package), without our ``PYTHONPATH``.

Driver contract: CASE holds ``urdf`` (path), ``body_names``, training ``q``, ``v``, ``a``, ``tau`` (N × n)
and per body an axis-aligned bounding box in its joint frame (``box_center``, ``box_half_extents``: the
box of the collision meshes, the joint origins and the URDF body's equivalent uniform box in any
orientation, :func:`_boxes`).
The driver writes OUT (``.npz``) with ``params``: 10 inertial parameters per body in ``body_names``
order, Pinocchio's convention (m, m·c, Ixx Ixy Iyy Ixz Iyz Izz about the joint frame), and optionally
``info`` (a JSON string). Every fit is scored on our side the same way: τ̂ = W(q, q̇, q̈) π on the
held-out log (:func:`held_out_nrmse`) and per-body physical consistency of π
(:func:`~sensorless.parameters.check_physical_consistency`).

Wall time ``seconds``: from the process start until the result file exists (``OUT/result.json``,
which appears when identify's output folder is renamed into place with its figures; the peer's OUT),
polled every millisecond (:mod:`.process_timing`; the result file's modification time would be that
of result.json inside the still-hidden folder, before the figures); ``exit_seconds``: to the exit. A peer whose venv or driver is
absent is ``skipped`` (with the reason); a process that fails is an ``error`` (its stderr's tail).
"""

from __future__ import annotations

import json
import os
import sys
from pathlib import Path

import numpy as np

from sensorless.data.readers import write_npz
from sensorless.parameters import check_physical_consistency
from sensorless.regressor.terms import ModelStructure
from sensorless.robot import Robot

from .process_timing import run_timed

__all__ = ["KNOWN_PEERS", "default_drivers", "default_venv", "held_out_nrmse", "peer_python", "peer_skip_reason",
           "run_identify", "run_peer", "score_parameters", "write_case"]

#: peers with a driver in ``studies/benchmarks/peer_drivers`` and a ``make peers`` recipe (name: pip requirement)
KNOWN_PEERS = {"figaroh": "figaroh==1.0.2", "rigeo": "rigeo==0.2.0 pin==4.1.0"}


def default_venv(name: str) -> Path:
    """``$XDG_CACHE_HOME/sensorless-peers/NAME`` (``~/.cache`` when unset)."""
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "sensorless-peers" / name


def default_drivers() -> Path:
    """``studies/benchmarks/peer_drivers`` of the source tree this package runs from."""
    return Path(__file__).resolve().parents[3] / "benchmarks" / "peer_drivers"


def peer_python(venv: Path) -> Path:
    return venv / ("Scripts/python.exe" if os.name == "nt" else "bin/python")


def _prior_sphere_points(pi: np.ndarray) -> np.ndarray:
    """``c ± r e_k``: the axis-aligned box of the ball, centred on the CoM ``c`` of the inertials ``pi``
    (one body, Pinocchio order), that holds the uniform box with exactly these inertials in any
    orientation. Second moments about the CoM ``Σc = ½ tr(Ic) 1 − Ic`` with eigenvalues ``s_k``: the
    box's half extents are ``a_k = √(3 s_k / m)`` and ``r = ‖a‖``."""
    m, c = pi[0], pi[1:4] / pi[0]
    I = np.array([[pi[4], pi[5], pi[7]], [pi[5], pi[6], pi[8]], [pi[7], pi[8], pi[9]]])
    Ic = I - m * (c @ c * np.eye(3) - np.outer(c, c))
    s = np.linalg.eigvalsh(0.5 * np.trace(Ic) * np.eye(3) - Ic)
    r = float(np.linalg.norm(np.sqrt(3.0 * np.clip(s, 0.0, None) / m)))
    return np.vstack([c + r * np.eye(3), c - r * np.eye(3)])


def _boxes(robot: Robot) -> tuple[np.ndarray, np.ndarray]:
    """Per body (joint frame) the axis-aligned box of its collision meshes and joint origins
    (:func:`~sensorless.identification.ellipsoids.body_points`) and of :func:`_prior_sphere_points`
    of its URDF inertials (the URDF's UR5 wrists have up to 60× the second moment their meshes' box
    allows, and the recipe's truth rotates their principal axes); (centres, half extents)."""
    from sensorless.identification.ellipsoids import body_points, load_geometry

    pts = body_points(robot, load_geometry(robot))
    prior = robot.inertial_parameters().reshape(-1, 10)
    lo, hi = [], []
    for k, b in enumerate(robot.body_names):
        p = pts[b] if prior[k, 0] <= 0 else np.vstack([pts[b], _prior_sphere_points(prior[k])])
        lo.append(p.min(axis=0))
        hi.append(p.max(axis=0))
    lo, hi = np.array(lo), np.array(hi)
    return 0.5 * (lo + hi), 0.5 * (hi - lo)


def write_case(folder: Path, case, robot: Robot) -> tuple[Path, Path]:
    """Write the training log of ``case`` twice: ``case.npz`` (driver contract, module docstring) and
    ``log.npz`` for ``sensorless identify`` (t, q, dq, ddq, tau: the same samples and accelerations)."""
    folder.mkdir(parents=True, exist_ok=True)
    t = case.train
    center, half = _boxes(robot)
    case_file, log = folder / "case.npz", folder / "log.npz"
    np.savez(case_file, urdf=str(robot.urdf_path), body_names=np.array(robot.body_names), q=t.q, v=t.v, a=t.a,
             tau=t.tau, box_center=center, box_half_extents=half, case=case.name, seed=case.seed)
    write_npz(t, log)
    return case_file, log


def _timed(argv: list[str], result: Path, env: dict, timeout: float) -> dict:
    """Run ``argv``; wall time until ``result`` exists (for ``sensorless identify``: its output folder
    renamed into place, figures included) and to the exit; the error from the stderr tail."""
    r = run_timed(argv, env, result, timeout)
    if r["timed_out"]:
        return {"error": f"timed out after {timeout:g} s"}
    if r["returncode"] != 0 or not result.is_file():
        tail = r["stderr_tail"]
        return {"error": f"exit code {r['returncode']}" + (": " + " | ".join(tail) if tail else "")
                + ("" if result.is_file() else f"; no {result.name} written")}
    return {"seconds": r["result_json"], "exit_seconds": r["exit"]}


def held_out_nrmse(pred: np.ndarray, case) -> np.ndarray:
    """Per-joint ``RMSE(τ̂ − τ_true) / std(τ_true)`` on the held-out log of a
    :class:`~.peers.PeerCase` (noise-free torques), in %."""
    tau = case.test.tau
    return 100.0 * np.sqrt(np.mean((pred - tau) ** 2, axis=0)) / tau.std(axis=0)


def score_parameters(structure: ModelStructure, params: np.ndarray, case) -> dict:
    """Held-out nRMSE of τ̂ = W π (:func:`held_out_nrmse`) and per-body consistency of π."""
    e = held_out_nrmse(structure.torques(params, case.test), case)
    robot = structure.robot
    reports = check_physical_consistency(params[: structure.n_body_params], list(robot.body_names))
    return {"nrmse_percent": float(e.mean()),
            "nrmse_percent_per_joint": dict(zip(structure.row_names, map(float, e))),
            "consistent_bodies": {r.name: bool(r.consistent) for r in reports},
            "all_consistent": all(r.consistent for r in reports)}


def run_identify(log: Path, out: Path, robot: Robot, robot_spec: str, case, flags: list[str],
                 timeout: float = 600.0) -> dict:
    """``sensorless identify`` on ``log`` as a fresh process (module docstring), scored."""
    from sensorless.identification.artifact import load_model_folder

    env = {**os.environ, "PYTHONPATH": os.pathsep.join(p for p in sys.path if p)}
    argv = [sys.executable, "-c", "from sensorless.__main__ import main; main()", "identify", "--robot", robot_spec,
            "--data", str(log), "--out", str(out), "--force", *flags]
    res = {"command": " ".join(["sensorless", *argv[3:]]), **_timed(argv, out / "result.json", env, timeout)}
    if "error" in res:
        return res
    model = load_model_folder(out, robot)
    d = model.doc.get("diagnostics") or {}
    return {**res, **score_parameters(model.structure, model.parameters, case), "gamma": d.get("gamma"),
            "gamma_edge": (d.get("gamma_selection") or {}).get("edge")}


def peer_skip_reason(name: str, venv: Path, drivers: Path) -> str | None:
    """Why peer ``name`` cannot run (no venv python, no driver), or None."""
    if not peer_python(venv).exists():
        hint = f" (`make peers` creates it: pip install {KNOWN_PEERS[name]})" if name in KNOWN_PEERS else ""
        return f"no virtual environment at {venv}{hint}; --peer-venv {name}=PATH to use another"
    if not (drivers / f"{name}_driver.py").is_file():
        return f"no driver {drivers / f'{name}_driver.py'}; --drivers DIR to use another folder"
    return None


def run_peer(name: str, venv: Path, drivers: Path, case_file: Path, out: Path, robot: Robot, case,
             timeout: float = 600.0) -> dict:
    """Peer ``name``'s driver in its venv on ``case_file`` (module docstring), scored; ``skipped``
    when its venv or driver is absent, ``error`` when it fails or returns unusable parameters."""
    reason = peer_skip_reason(name, venv, drivers)
    if reason is not None:
        return {"skipped": reason}
    python, driver = peer_python(venv), drivers / f"{name}_driver.py"
    env = {k: v for k, v in os.environ.items() if k not in ("PYTHONPATH", "PYTHONHOME")}
    res = {"python": str(python), "driver": str(driver),
           **_timed([str(python), str(driver), str(case_file), str(out)], out, env, timeout)}
    if "error" in res:
        return res
    structure = ModelStructure(robot, joint_terms=())
    try:
        with np.load(out, allow_pickle=False) as z:
            params = np.asarray(z["params"], dtype=float).ravel()
            info = json.loads(str(z["info"])) if "info" in z.files else {}
    except (OSError, ValueError, KeyError) as exc:
        return {**res, "error": f"{out.name}: unreadable result ({exc})"}
    if params.shape != (structure.n_params,) or not np.all(np.isfinite(params)):
        return {**res, "error": f"{out.name}: expected {structure.n_params} finite parameters, got {params.shape}"}
    return {**res, **score_parameters(structure, params, case), "info": info}
