"""The least-squares machinery of payload identification (:mod:`.payload`): per-block normal
equations of [Y_p, 1] z ≈ r, the constrained solve, HAC-robust covariances and per-joint
consistency checks."""

from __future__ import annotations


import numpy as np

from ..errors import ExcitationError, SolverError
from ..parameters import pseudo_inertia, pseudo_inertia_basis
from .payload_model import JointConsistency, point_mass_parameters

MAX_COM = 10.0
"""[m] A point-mass CoM farther than this from the frame is taken as "no payload" (mode com):
it only happens when the fitted mass is ≈ 0 and c = (m c)/m is noise over noise."""


class PayloadBlocks:
    """Per-block, per-row normal equations of [Y_p, 1] z ≈ r (11 columns: φ and the row's offset)."""

    def __init__(self, rows: int) -> None:
        self.A: list[np.ndarray] = []  # (rows, 11, 11) per block
        self.b: list[np.ndarray] = []  # (rows, 11)
        self.c: list[np.ndarray] = []  # (rows,)
        self.n: list[int] = []
        self.rows = rows

    def add(self, Y: np.ndarray, r: np.ndarray) -> None:
        X = np.concatenate([Y, np.ones(Y.shape[:2] + (1,))], axis=2).transpose(1, 0, 2)  # (rows, n, 11)
        self.A.append(np.einsum("rni,rnj->rij", X, X))
        self.b.append(np.einsum("rni,nr->ri", X, r))
        self.c.append(np.einsum("nr,nr->r", r, r))
        self.n.append(Y.shape[0])

    def total(self, idx=None):
        sel = range(len(self.A)) if idx is None else idx
        return (sum(self.A[i] for i in sel), sum(self.b[i] for i in sel), sum(self.c[i] for i in sel),
                sum(self.n[i] for i in sel))


class PayloadSystem:
    """Weighted normal equations in z = [φ (10), o (rows)] and their reduction to φ."""

    def __init__(self, A: np.ndarray, b: np.ndarray, w: np.ndarray, offsets: np.ndarray) -> None:
        self.mask = np.asarray(offsets, bool)  # rows with a free offset
        self.offsets = bool(self.mask.any())
        mw = w * self.mask
        self.App = np.einsum("r,rij->ij", w, A[:, :10, :10])
        self.bp = np.einsum("r,ri->i", w, b[:, :10])
        self.Apo = (mw[:, None] * A[:, :10, 10]).T  # (10, R), zero columns for rows without offset
        self.Aoo = np.where(self.mask & (w > 0), w * A[:, 10, 10], 1.0)  # diagonal (R,); a row set aside: 1
        self.bo = mw * b[:, 10]
        K = self.Apo / self.Aoo
        self.Ar = self.App - K @ self.Apo.T
        self.br = self.bp - K @ self.bo

    def offsets_for(self, phi: np.ndarray) -> np.ndarray:
        return np.where(self.mask, (self.bo - self.Apo.T @ phi) / self.Aoo, 0.0)

    def profile_score(self, Ab: np.ndarray, bb: np.ndarray, w: np.ndarray, phi: np.ndarray, o: np.ndarray) -> np.ndarray:
        """Score of one block for φ with the offsets profiled out: g_φ − A_φo A_oo⁻¹ g_o."""
        z_res_p = bb[:, :10] - np.einsum("rij,j->ri", Ab[:, :10, :10], phi) - Ab[:, :10, 10] * o[:, None]
        g_p = np.einsum("r,ri->i", w, z_res_p)
        g_o = w * self.mask * (bb[:, 10] - Ab[:, 10, :10] @ phi - Ab[:, 10, 10] * o)
        return g_p - (self.Apo / self.Aoo) @ g_o


class PayloadSolver:
    """The estimator of one mode on reduced weighted normal equations (A 10×10, b 10)."""

    def __init__(self, mode: str, consistent: bool, com: np.ndarray | None) -> None:
        self.mode, self.consistent, self.com = mode, consistent, com
        self._basis = pseudo_inertia_basis()

    def __call__(self, A: np.ndarray, b: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(φ, inverse of the used normal matrix in φ coordinates, Jacobian Gφ of φ = Gφ x)."""
        if self.mode == "mass":
            g = point_mass_parameters(1.0, self.com)
            a, bb = float(g @ A @ g), float(g @ b)
            if a <= 0:
                raise ExcitationError("the payload mass is not excited by this log (zero regressor)")
            m = max(bb / a, 0.0)
            return m * g, np.outer(g, g) / a, g[:, None]
        if self.mode == "com":
            c = np.zeros(3)
            for _ in range(10):
                G = np.zeros((10, 4))  # φ = G [m, h]: inertia of a point mass at the current c
                G[0, 0] = 1.0
                G[1:4, 1:4] = np.eye(3)
                G[4:, 0] = point_mass_parameters(1.0, c)[4:]
                Ar, br = G.T @ A @ G, G.T @ b
                x = solve_spd(Ar, br)
                c_new = x[1:4] / x[0] if x[0] > 0 else np.zeros(3)
                if not (x[0] > 0 and np.all(np.isfinite(c_new)) and np.linalg.norm(c_new) < MAX_COM):
                    x, c_new = np.zeros(4), np.zeros(3)  # no (physical) payload: m ≤ 0 or CoM out of reach
                if np.allclose(c_new, c, atol=1e-9):
                    break
                c = c_new
            phi = point_mass_parameters(x[0], c) if x[0] > 0 else np.zeros(10)
            return phi, G @ np.linalg.pinv(Ar) @ G.T, G
        phi = solve_spd(A, b)
        cov = np.linalg.pinv(A)
        if self.consistent and np.linalg.eigvalsh(pseudo_inertia(phi))[0] < 0:
            phi = self._sdp(A, b)
        return phi, cov, np.eye(10)

    def _sdp(self, A: np.ndarray, b: np.ndarray) -> np.ndarray:
        import cvxpy as cp

        # equilibrate columns (x = s ⊙ φ) and normalise the data (y = x / κ): the pseudo-inertia
        # constraint is homogeneous, so the minimiser scales back exactly
        s = np.sqrt(np.maximum(np.diag(A), 1e-300))
        As = A / np.outer(s, s)
        L = np.linalg.cholesky(As + 1e-12 * np.trace(As) / 10 * np.eye(10))
        z = np.linalg.solve(L, b / s)
        kappa = max(float(np.linalg.norm(z)), 1e-300)
        x = cp.Variable(10)
        P = cp.Variable((4, 4), PSD=True)
        phi = cp.multiply(1.0 / s, x)
        scale = 1.0 / max(float(np.max(np.abs(self._basis.reshape(10, -1)).max(1) / s)), 1e-300)
        J = sum((scale * phi[i]) * self._basis[i] for i in range(10))
        prob = cp.Problem(cp.Minimize(cp.sum_squares(L.T @ x - z / kappa)), [P == J])
        try:
            prob.solve(solver=cp.CLARABEL)
        except cp.error.SolverError as exc:
            raise SolverError(f"payload SDP failed: {exc}") from None
        if prob.status not in ("optimal", "optimal_inaccurate") or x.value is None:
            raise SolverError(f"payload SDP ended with status '{prob.status}'")
        return kappa * np.asarray(x.value) / s


def solve_without(solver, A_r, b_r, w, off_mask) -> "np.ndarray | None":
    """φ from the joints with weight w > 0, or None when they cannot determine it (a
    singular or non-finite reduced system, e.g. every joint set aside)."""
    if not np.any(w > 0):
        return None
    with np.errstate(divide="ignore", invalid="ignore"):
        sys_x = PayloadSystem(A_r, b_r, w, off_mask)
    if not (np.all(np.isfinite(sys_x.Ar)) and np.all(np.isfinite(sys_x.br))):
        return None
    try:
        phi = solver(sys_x.Ar, sys_x.br)[0]
    except (np.linalg.LinAlgError, ExcitationError, SolverError):
        return None
    return phi if np.all(np.isfinite(phi)) else None


def solve_spd(A: np.ndarray, b: np.ndarray) -> np.ndarray:
    """x with A x = b; the least-squares solution when A is singular."""
    try:
        return np.linalg.solve(A, b)
    except np.linalg.LinAlgError:
        return np.linalg.lstsq(A, b, rcond=None)[0]


def inertia_excitation(A: np.ndarray) -> float:
    """Smallest singular value of the column-equilibrated inertia block after removing the
    mass/CoM directions (Schur complement), relative to the largest of the whole matrix."""
    s = np.sqrt(np.maximum(np.diag(A), 1e-300))
    As = A / np.outer(s, s)
    S = As[4:, 4:] - As[4:, :4] @ np.linalg.pinv(As[:4, :4]) @ As[:4, 4:]
    return float(np.linalg.eigvalsh(S)[0] / np.linalg.eigvalsh(As)[-1])


def sandwich(H: np.ndarray, scores: np.ndarray) -> np.ndarray:
    """H⁻¹ (Σ s sᵀ) H⁻¹ · B/(B − k) for per-block scores (B, k)."""
    B, k = scores.shape
    Hi = np.linalg.pinv(H)
    return Hi @ (scores.T @ scores) @ Hi * (B / max(B - k, 1))


def unconstrained_mass(system: PayloadSystem, phi: np.ndarray, com: np.ndarray) -> float:
    """Least-squares mass with the CoM fixed (at the estimate, or ``com`` when m = 0) and no
    positivity: shows how negative the data would have it when the estimate is clamped at 0."""
    c = phi[1:4] / phi[0] if phi[0] > 0 else com
    g = point_mass_parameters(1.0, c)
    a = float(g @ system.Ar @ g)
    return float(g @ system.br) / a if a > 0 else float("nan")


def offset_inflation(A_r: np.ndarray, b_r: np.ndarray, w: np.ndarray) -> np.ndarray:
    """Per joint: factor by which an offset on that joint alone multiplies the (white-noise)
    variance of the mass, from the mass / first-moment block of the reduced normal equations."""
    rows = A_r.shape[0]

    def var_m(mask) -> float:
        return float(np.linalg.pinv(PayloadSystem(A_r, b_r, w, mask).Ar[:4, :4])[0, 0])

    base = var_m(np.zeros(rows, bool))
    if base <= 0:
        return np.ones(rows)
    return np.array([var_m(np.eye(rows, dtype=bool)[j]) / base for j in range(rows)])


def _scalar_fit(blocks: PayloadBlocks, A_r, b_r, w, u, offsets, rows, hac: bool = True) -> tuple[float, float, dict]:
    """Mass m of the payload shape u from the equations of ``rows`` only (their offsets free
    where ``offsets``), with its HAC standard error: x = [m, o_r …], row r has features T_rᵀ = [Y_r u, e_r]."""
    rows = [r for r in rows]
    off_rows = [r for r in rows if offsets[r]]
    k = 1 + len(off_rows)
    T = {}
    for r in rows:
        Tr = np.zeros((11, k))
        Tr[:10, 0] = u
        if offsets[r]:
            Tr[10, 1 + off_rows.index(r)] = 1.0
        T[r] = Tr
    H = sum(w[r] * T[r].T @ A_r[r] @ T[r] for r in rows)
    g = sum(w[r] * T[r].T @ b_r[r] for r in rows)
    if not rows or H[0, 0] <= 1e-14 * max(np.abs(H).max(), 1e-300):
        return float("nan"), float("inf"), {}
    x = solve_spd(H, g)
    if not hac:
        return float(x[0]), float("nan"), {}
    scores = np.array([sum(w[r] * T[r].T @ (blocks.b[i][r] - blocks.A[i][r] @ (T[r] @ x)) for r in rows)
                       for i in range(len(blocks.n))])
    std = float(np.sqrt(max(sandwich(H, scores)[0, 0], 0.0)))
    return float(x[0]), std, {r: float(x[1 + off_rows.index(r)]) for r in off_rows}


def joint_consistency(blocks: PayloadBlocks, A_r, b_r, w, phi, cov, offsets, joints, flag_sigma, flag_rel, excluded) -> list[JointConsistency]:
    """Per joint: the mass its equation alone implies vs the mass all other informative joints
    (``excluded`` left out) imply, payload shape u = φ/m fixed, offsets free where fitted
    (module docstring). Standard errors: HAC of the scalar fit plus the propagated uncertainty
    of the shape, Σ_k ((m(φ + √λ_k v_k) − m(φ − √λ_k v_k))/2)² over the eigenpairs of the
    covariance of φ (a joint whose payload torque hinges on the CoM, such as a wrist joint,
    gets the CoM's uncertainty). ``share``: the joint's part of the weighted information
    uᵀ(Σ_r w_r Y_rᵀY_r)u."""
    m = float(phi[0])
    R = len(joints)
    if m <= 0:
        return [JointConsistency(j, float("nan"), float("nan"), float("nan"), float("nan"), float("nan"), 0.0,
                                 False, False, None) for j in joints]
    u = phi / m
    info = w * np.einsum("i,rij,j->r", u, A_r[:, :10, :10], u)
    share = info / max(info.sum(), 1e-300)
    lam, vec = np.linalg.eigh(0.5 * (cov + cov.T))
    steps = [np.sqrt(l) * v for l, v in zip(lam, vec.T) if l > 1e-12 * max(lam.max(), 1e-300)]

    def fit(rows):
        mj, sj, off = _scalar_fit(blocks, A_r, b_r, w, u, offsets, rows)
        if not np.isfinite(sj):
            return mj, sj, off
        shape2 = 0.0
        for d in steps:
            up, dn = phi + d, phi - d
            if up[0] <= 0 or dn[0] <= 0:
                continue
            mp = _scalar_fit(blocks, A_r, b_r, w, up / up[0], offsets, rows, hac=False)[0]
            mm = _scalar_fit(blocks, A_r, b_r, w, dn / dn[0], offsets, rows, hac=False)[0]
            shape2 += (0.5 * (mp - mm)) ** 2
        return mj, float(np.hypot(sj, np.sqrt(shape2))), off

    fits = [fit([r]) for r in range(R)]
    informative = [bool(np.isfinite(f[1]) and f[1] < abs(m)) for f in fits]
    out = []
    for r, name in enumerate(joints):
        mj, sj, off = fits[r]
        others = [k for k in range(R) if k != r and informative[k] and not excluded[k]]
        mo, so, _ = fit(others) if others else (float("nan"), float("inf"), {})
        d = mj - mo
        z = d / max(float(np.hypot(sj, so)), 1e-300) if np.isfinite(d) and np.isfinite(so) else 0.0
        flagged = informative[r] and np.isfinite(so) and abs(z) > flag_sigma and abs(d) > flag_rel * abs(m)
        out.append(JointConsistency(name, mj, sj, mo, so, float(z), float(share[r]), informative[r], bool(flagged),
                                    off.get(r)))
    return out
