"""Stribeck velocities chosen from one compression pass (variable projection on candidates).

The Stribeck column of joint j, z_j(vs) = exp(−(v_j/vs)²) sgn v_j, is non-linear in vs. For a
grid of G candidate values per joint, :class:`StribeckCandidates` compresses all G columns in
the same pass as the rest of the model: they sit on row j only, so the extra fold per sample is
one (row columns × G) product. From the per-row normal equations of [X | Z] (X: the model's base
columns with the other joints' current choice, Z: joint j's candidates, row weights w_r) the
weighted least-squares residual with candidate g, every other parameter free, is
(Frisch–Waugh–Lovell)

    SSE(g) = SSE_X − β_g² / a_g,   a_g = A_gg − A_gX A_XX⁺ A_Xg,   β_g = b_g − A_gX A_XX⁺ b_X,

so each candidate costs O(p) after one pseudo-inverse per joint. Joints are visited in turn
(coordinate descent, :data:`SWEEPS` sweeps) and the chosen columns are selected out of the
compressed equations for the final fit (OLS, WLS or LMI): no second pass over the data, and a
cluster (which compresses the same candidates on its workers) chooses exactly as a local run.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..errors import DataError
from ..regressor.compress import NormalEquations
from ..regressor.terms import ModelStructure
from .base import base_parameters

__all__ = ["SWEEPS", "StribeckCandidates", "choose_stribeck"]

#: coordinate-descent sweeps over the joints
SWEEPS = 2


class StribeckCandidates:
    """A :class:`~sensorless.regressor.ModelStructure` whose joint-term block carries, after the
    model's own terms, G candidate Stribeck columns per joint (``grid[joint]``, padded with its
    last value; zeros for joints without a grid). It has the interface :func:`compress` reads.
    """

    def __init__(self, structure: ModelStructure, grid: Mapping[str, Sequence[float]]):
        if type(structure) is not ModelStructure:
            raise DataError(f"the Stribeck velocity search needs a per-joint model (got {type(structure).__name__}); "
                            "give the Stribeck velocity as a number instead")
        joints = list(structure.robot.actuated_joints)
        unknown = [j for j in grid if j not in joints or "stribeck" not in structure.terms_of(j)]
        if unknown:
            raise DataError(f"Stribeck grid given for joints without a 'stribeck' term: {unknown}")
        lists = {j: np.asarray(grid[j], dtype=float).ravel() for j in grid}
        if any(g.size == 0 or not np.all(np.isfinite(g) & (g > 0)) for g in lists.values()):
            raise DataError("every Stribeck candidate velocity must be finite and > 0")
        self.structure = structure
        self.sizes = {j: int(g.size) for j, g in lists.items()}
        G = max(self.sizes.values())
        self.grid = np.ones((len(joints), G))  # (n_act, G); rows of joints without a grid are unused
        self.searched = np.zeros(len(joints), dtype=bool)
        for k, j in enumerate(joints):
            if j in lists:
                g = lists[j]
                self.grid[k] = np.concatenate([g, np.full(G - g.size, g[-1])])
                self.searched[k] = True

    # ---- what compress() reads (the wrapped structure's, plus the G candidate columns) ----------
    robot = property(lambda self: self.structure.robot)
    n_rows = property(lambda self: self.structure.n_rows)
    row_names = property(lambda self: self.structure.row_names)
    row_map = property(lambda self: self.structure.row_map)
    n_body_params = property(lambda self: self.structure.n_body_params)
    n_block_params = property(lambda self: self.structure.n_block_params)
    actuated_rows = property(lambda self: self.structure.actuated_rows)

    @property
    def n_terms(self) -> int:
        """Columns per joint: the model's joint terms, then the G candidates."""
        return len(self.structure.joint_terms) + self.grid.shape[1]

    @property
    def n_params(self) -> int:
        return self.n_block_params + self.structure.robot.n_actuated * self.n_terms

    def row_body_columns(self):
        return self.structure.row_body_columns()

    def state(self, traj):
        return self.structure.state(traj)

    def block_regressor(self, Q, V, A, out=None):
        return self.structure.block_regressor(Q, V, A, out=out)

    def target(self, traj):
        return self.structure.target(traj)

    def fit_mask(self, V):
        return self.structure.fit_mask(V)

    def joint_features(self, V: np.ndarray, A: np.ndarray) -> np.ndarray:
        s = self.structure
        v = V[:, s.robot.actuated_v_indices]
        Z = np.exp(-((v[:, :, None] / self.grid[None]) ** 2)) * s.coulomb_sign(v)[:, :, None]
        Z *= self.searched[None, :, None]
        return np.concatenate([s.joint_features(V, A), Z], axis=2)

    # ---- from candidate equations to the model's -------------------------------------------------
    def columns(self, choice: np.ndarray) -> np.ndarray:
        """Candidate-layout column of each parameter of the wrapped structure, with candidate
        ``choice[k]`` as the Stribeck column of searched joint k."""
        s, nb, nt = self.structure, self.n_block_params, len(self.structure.joint_terms)
        idx = list(range(nb))
        for k in range(s.robot.n_actuated):
            start = nb + k * self.n_terms
            for t, term in enumerate(s.joint_terms):
                idx.append(start + nt + int(choice[k]) if term == "stribeck" and self.searched[k] else start + t)
        return np.asarray(idx)

    def select(self, ne: NormalEquations, choice: np.ndarray) -> NormalEquations:
        """The wrapped structure's normal equations with the chosen candidates."""
        if ne.A.shape[-1] != self.n_params:
            raise DataError(f"the compressed equations have {ne.A.shape[-1]} columns, the Stribeck candidates "
                            f"{self.n_params}: they were not compressed with this grid")
        idx = self.columns(choice)
        return NormalEquations(ne.A[:, idx][:, :, idx], ne.b[:, idx], ne.c.copy(), ne.y_min, ne.y_max,
                               ne.y_sum, ne.n_samples)

    def structure_for(self, choice: np.ndarray) -> ModelStructure:
        import dataclasses

        joints = self.structure.robot.actuated_joints
        vs = dict(self.structure.stribeck_velocity or {})
        vs.update({j: float(self.grid[k, choice[k]]) for k, j in enumerate(joints) if self.searched[k]})
        return dataclasses.replace(self.structure, stribeck_velocity=vs)


def _pinv_psd(A: np.ndarray, rcond: float = 1e-12) -> np.ndarray:
    """Pseudo-inverse of a symmetric PSD matrix, equilibrated (columns of very different scale)."""
    d = np.sqrt(np.maximum(np.diag(A), 0.0))
    d = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    lam, U = np.linalg.eigh(d[:, None] * A * d[None, :])
    keep = lam > rcond * max(float(lam.max(initial=0.0)), 1e-300)
    return (d[:, None] * (U[:, keep] / lam[keep]) @ U[:, keep].T) * d[None, :]


def choose_stribeck(cand: StribeckCandidates, ne: NormalEquations, weights) -> tuple[np.ndarray, dict]:
    """Choose each joint's Stribeck velocity from candidate equations ``ne`` (module docstring).

    ``weights``: as :func:`~.identify.identify` (row weights of the criterion, computed once at the
    starting choice, the middle of every grid). Returns the chosen candidate index per actuated
    joint (for :meth:`StribeckCandidates.select` / :meth:`~StribeckCandidates.structure_for`) and
    a record ``{joint: {"grid", "sse", "vs"}}`` (the weighted SSE of the last sweep over the
    joint's own grid).
    """
    from .least_squares import row_weights

    s = cand.structure
    joints = list(s.robot.actuated_joints)
    choice = np.array([cand.sizes.get(j, 1) // 2 for j in joints])
    w = row_weights(cand.select(ne, choice), weights)
    A, b, c = ne.total(w)
    base = base_parameters(s).independent
    record = {}
    for _ in range(SWEEPS):
        for k in np.flatnonzero(cand.searched):
            cols = cand.columns(choice)
            own = int(cols[s.joint_term_index(joints[k], "stribeck")])
            X = np.array([cols[i] for i in base if cols[i] != own])
            start = cand.n_block_params + k * cand.n_terms + len(s.joint_terms)
            Z = np.arange(start, start + cand.grid.shape[1])
            P = _pinv_psd(A[np.ix_(X, X)])
            AXZ = A[np.ix_(X, Z)]
            U = P @ AXZ
            sse_x = c - b[X] @ P @ b[X]
            a = np.diag(A)[Z] - np.einsum("xg,xg->g", AXZ, U)
            beta = b[Z] - U.T @ b[X]
            gain = np.where(a > 1e-12 * np.maximum(np.diag(A)[Z], 1e-300), beta**2 / np.where(a > 0, a, 1.0), 0.0)
            sse = sse_x - gain
            n = cand.sizes[joints[k]]
            choice[k] = int(np.argmin(sse[:n]))
            record[joints[k]] = {"grid": cand.grid[k, :n].tolist(), "sse": sse[:n].tolist(),
                                 "vs": float(cand.grid[k, choice[k]])}
    return choice, record
