"""The excitation design problem in the Fourier coefficients x = (a, b, q0) (:func:`~.design.design_excitation`):
the criterion of the base regressor W₁ over one period and its gradient, and the limit, start-at-rest and
Cartesian constraints with their Jacobians (module docstring of :mod:`.design` for the math)."""

from __future__ import annotations

import copy
from collections.abc import Callable

import numpy as np
import pinocchio as pin

from ..errors import ExcitationError, RobotModelError
from ..identification.base import base_parameters
from .criteria import neg_logdet, regressor_at
from .fourier import FourierTrajectory

__all__ = ["FourierProblem"]


# ---- kinematics for Cartesian constraints ---------------------------------------------------
def _kinematics(structure):
    """(model, data, θ → Pinocchio q, P) with v_tree = P θ̇ for a ModelStructure or TransmissionStructure."""
    if structure.robot.transmission_matrix is not None:  # coordinates θ of a tree q = Gθ + q₀ (TransmissionStructure)
        tree = structure.robot.tree
        idx = [tree.v_index(j) for j in tree.joint_names]
        P = np.zeros((tree.nv, structure.G.shape[1]))
        P[idx] = structure.G
        return tree.model, tree.model.createData(), lambda th: tree.full_configuration(structure.joint_values(th)), P
    robot = structure.robot
    if robot.floating_base:
        raise ExcitationError("Cartesian excitation constraints need a fixed-base robot")
    P = np.zeros((robot.nv, len(robot.joint_names)))
    for k, j in enumerate(robot.joint_names):
        P[robot.v_index(j), k] = 1.0
    return robot.model, robot.model.createData(), robot.full_configuration, P


class FourierProblem:
    """Variables x = [a (n·H), b (n·H), q0 (n)]; q, v, v̇ are linear in x."""

    def __init__(self, structure, limits, harmonics, base_freq, n_samples, criterion, cartesian, smoothing):
        self.s = copy.copy(structure)
        if getattr(self.s, "coulomb_smoothing", 0.0) <= 0.0:
            self.s.coulomb_smoothing = smoothing
        self.limits = limits
        self.n, self.H, self.f0 = len(limits.joint_names), harmonics, base_freq
        self.w = 2 * np.pi * base_freq * np.arange(1, harmonics + 1)
        self.t = np.arange(n_samples) / (n_samples * base_freq)  # one period, periodic grid
        wt = np.outer(self.t, self.w)
        S, C = np.sin(wt), np.cos(wt)
        # q = q0 + Sq a − Cq b ; v = C a + S b ; v̇ = −Sa a + Ca b  (per joint, (N, H) bases)
        self.Bq = (S / self.w, -C / self.w)
        self.Bv = (C, S)
        self.Ba = (-S * self.w, C * self.w)
        self.ind = base_parameters(self.s).independent
        self.criterion = criterion
        self.cartesian = list(cartesian)
        if self.cartesian:
            self.model, self.data, self.to_q, self.P = _kinematics(self.s)
            self.fids = []
            for box in self.cartesian:
                if not self.model.existFrame(box.frame):
                    raise RobotModelError(f"unknown frame '{box.frame}' in a Cartesian excitation constraint")
                self.fids.append(self.model.getFrameId(box.frame))
            self.cart_idx = np.arange(0, n_samples, max(1, n_samples // 100))
        self.n_eval = 0

    # variables
    @property
    def nx(self) -> int:
        return self.n * (2 * self.H + 1)

    def pack(self, traj: FourierTrajectory) -> np.ndarray:
        return np.concatenate([traj.a.ravel(), traj.b.ravel(), traj.q0])

    def unpack(self, x: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        nH = self.n * self.H
        return x[:nH].reshape(self.n, self.H), x[nH : 2 * nH].reshape(self.n, self.H), x[2 * nH :]

    def fourier(self, x: np.ndarray) -> FourierTrajectory:
        a, b, q0 = self.unpack(x)
        return FourierTrajectory(self.f0, a.copy(), b.copy(), q0.copy(), self.limits.joint_names)

    def states(self, x: np.ndarray):
        a, b, q0 = self.unpack(x)
        q = q0 + self.Bq[0] @ a.T + self.Bq[1] @ b.T
        v = self.Bv[0] @ a.T + self.Bv[1] @ b.T
        acc = self.Ba[0] @ a.T + self.Ba[1] @ b.T
        return q, v, acc

    # objective
    def _base_regressor(self, q, v, a) -> np.ndarray:
        """W₁ stacked over samples and rows, (N·rows, r); q, v, a may carry a leading batch axis."""
        n = q.shape[-1]
        W = regressor_at(self.s, q.reshape(-1, n), v.reshape(-1, n), a.reshape(-1, n))[:, :, self.ind]
        self.n_eval += W.shape[0]
        return W.reshape(q.shape[:-2] + (-1, W.shape[-1]))

    def _crit(self, X: np.ndarray) -> tuple[float, Callable[[np.ndarray], np.ndarray]]:
        """Criterion of W₁ = X (m × r) and its exact directional derivative d(dX) for a batch
        of directions dX (K, m, r), by first-order eigenvalue / log-det perturbation:

        * cond: X̃ = X C⁻¹ (C = column norms), λ = uᵀX̃ᵀX̃u ⇒ dλ = 2 (X̃u)ᵀ dX̃ u with
          dX̃ = dX C⁻¹ − X C⁻² dC, dC_i = X_iᵀ dX_i / C_i; d log cond = ½ (dλ_max/λ_max − dλ_min/λ_min);
        * dopt: −log det(XᵀX/m) ⇒ −2 ⟨X (XᵀX)⁻¹, dX⟩.
        """
        M = X.T @ X
        if self.criterion == "dopt":
            f = float(neg_logdet(M, X.shape[0]))
            try:
                Z = X @ np.linalg.inv(M)
            except np.linalg.LinAlgError:
                Z = X @ np.linalg.pinv(M)
            return f, lambda dX: -2.0 * np.einsum("mr,kmr->k", Z, dX)
        c = np.sqrt(np.maximum(np.diag(M), 1e-300))
        Ms = M / np.outer(c, c)
        ev, U = np.linalg.eigh(Ms)
        lmin, lmax = max(ev[0], 1e-300 * ev[-1]), ev[-1]
        f = 0.5 * float(np.log(lmax) - np.log(lmin))
        parts = []
        for lam, u in ((lmax, U[:, -1]), (lmin, U[:, 0])):
            y = X @ (u / c)  # X̃u
            parts.append((lam, u / c, X.T @ y, y))

        def directional(dX: np.ndarray) -> np.ndarray:
            dc = np.einsum("mr,kmr->kr", X, dX) / c  # (K, r)
            out = np.zeros(dX.shape[0])
            for sign, (lam, uc, Xty, y) in zip((0.5, -0.5), parts):
                dlam = 2.0 * (np.einsum("m,kmr,r->k", y, dX, uc) - (dc / c) @ (uc * Xty))
                out += sign * dlam / lam
            return out

        return f, directional

    def value(self, x: np.ndarray) -> float:
        return self._crit(self._base_regressor(*self.states(x)))[0]

    def value_and_grad(self, x: np.ndarray, h: float = 1e-6) -> tuple[float, np.ndarray]:
        """Criterion and gradient, by the chain rule through the states. Sample t of W₁ depends on
        x only through (q, v, v̇)(t), each linear in x, so per joint j

            dW₁(t)/dx_k = ∂W₁/∂q_j(t) B^q_k(t) + ∂W₁/∂v_j(t) B^v_k(t) + ∂W₁/∂v̇_j(t) B^a_k(t)

        for the 2H + 1 coefficients k of joint j (B = the Fourier bases, 1 for q0). The three partials
        are forward differences of the regressor (one batched evaluation of 3 states per joint, instead
        of one per coefficient), chained with the exact derivative of the criterion in W₁."""
        q, v, a = self.states(x)
        X = self._base_regressor(q, v, a)
        f0, directional = self._crit(X)
        g = np.zeros_like(x)
        nH, N, r = self.n * self.H, len(self.t), X.shape[-1]
        X3 = X.reshape(N, -1, r)
        bases = (np.concatenate([self.Bq[0].T, self.Bq[1].T, np.ones((1, N))]),  # (K, N), K = 2H + 1
                 np.concatenate([self.Bv[0].T, self.Bv[1].T, np.zeros((1, N))]),
                 np.concatenate([self.Ba[0].T, self.Ba[1].T, np.zeros((1, N))]))
        for j in range(self.n):
            Q, V, A = (np.repeat(z[None], 3, axis=0) for z in (q, v, a))
            Q[0, :, j] += h
            V[1, :, j] += h
            A[2, :, j] += h
            D = (self._base_regressor(Q, V, A).reshape(3, N, -1, r) - X3[None]) / h  # ∂W₁/∂(q_j, v_j, v̇_j)
            dX = sum(np.einsum("kn,nmr->knmr", B, Dz) for B, Dz in zip(bases, D)).reshape(len(bases[0]), -1, r)
            idx = np.concatenate([j * self.H + np.arange(self.H), nH + j * self.H + np.arange(self.H), [2 * nH + j]])
            g[idx] = directional(dX)
        if not (np.isfinite(f0) and np.all(np.isfinite(g))):
            g = np.nan_to_num(g, nan=0.0, posinf=0.0, neginf=0.0)
        return f0, g

    # constraints: c(x) ≥ 0
    def _amp(self, x):
        a, b, _ = self.unpack(x)
        return a, b, np.sqrt(a * a + b * b + 1e-12)

    def limit_constraints(self, x: np.ndarray) -> np.ndarray:
        _, _, q0 = self.unpack(x)
        _, _, amp = self._amp(x)
        L = self.limits
        dq, dv, da = amp @ (1 / self.w), amp.sum(axis=1), amp @ self.w
        return np.concatenate([q0 - dq - L.lower, L.upper - q0 - dq, L.velocity - dv, L.acceleration - da])

    def limit_jacobian(self, x: np.ndarray) -> np.ndarray:
        a, b, amp = self._amp(x)
        n, H = self.n, self.H
        nH = n * H
        J = np.zeros((4 * n, self.nx))
        for weights, block, sign_q0 in ((1 / self.w, 0, 1.0), (1 / self.w, 1, -1.0), (np.ones(H), 2, 0.0), (self.w, 3, 0.0)):
            for j in range(n):
                r = block * n + j
                J[r, j * H : (j + 1) * H] = -weights * a[j] / amp[j]
                J[r, nH + j * H : nH + (j + 1) * H] = -weights * b[j] / amp[j]
                J[r, 2 * nH + j] = sign_q0
        return J

    def rest_constraints(self, x: np.ndarray) -> np.ndarray:
        a, b, _ = self.unpack(x)
        return np.concatenate([a.sum(axis=1), b @ self.w])

    def rest_jacobian(self, x: np.ndarray) -> np.ndarray:
        n, H = self.n, self.H
        J = np.zeros((2 * n, self.nx))
        for j in range(n):
            J[j, j * H : (j + 1) * H] = 1.0
            J[n + j, n * H + j * H : n * H + (j + 1) * H] = self.w
        return J

    def _cartesian(self, x: np.ndarray, jac: bool):
        q, _, _ = self.states(x)
        idx = self.cart_idx
        Qp = self.to_q(q[idx])
        vals, rows = [], []
        nH = self.n * self.H
        for box, fid in zip(self.cartesian, self.fids):
            lo, hi = np.asarray(box.lower, float), np.asarray(box.upper, float)
            for k, i in enumerate(idx):
                pin.framesForwardKinematics(self.model, self.data, Qp[k])
                p = self.data.oMf[fid].translation
                if jac:
                    Jf = pin.computeFrameJacobian(self.model, self.data, Qp[k], fid, pin.LOCAL_WORLD_ALIGNED)[:3] @ self.P
                for ax in range(3):
                    for sign, bound in ((1.0, lo[ax]), (-1.0, hi[ax])):
                        if not np.isfinite(bound):
                            continue
                        vals.append(sign * (p[ax] - bound))
                        if jac:
                            r = np.zeros(self.nx)
                            dth = sign * Jf[ax]  # (n,)
                            for j in range(self.n):
                                r[j * self.H : (j + 1) * self.H] = dth[j] * self.Bq[0][i]
                                r[nH + j * self.H : nH + (j + 1) * self.H] = dth[j] * self.Bq[1][i]
                                r[2 * nH + j] = dth[j]
                            rows.append(r)
        return np.array(vals), (np.array(rows) if jac else None)

    def cartesian_constraints(self, x):
        return self._cartesian(x, False)[0]

    def cartesian_jacobian(self, x):
        return self._cartesian(x, True)[1]
