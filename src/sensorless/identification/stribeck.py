"""The low-speed friction law chosen from one compression pass (variable projection on candidates).

Joint j's friction (:mod:`sensorless.regressor.terms`, law "blend") is

    τ_f = fc T + (fs − fc) (T − D) + fv v + o,   T = tanh(v/w),   D = (1 − e^{−(v/vs)²}) sgn v,

non-linear in the transition width w and the Stribeck velocity vs, but T depends on w only and
D on vs only. :class:`StribeckCandidates` compresses, in the same pass as the rest of the model,
G_w width columns T_g (g = 0 is the structure's own ε, the noise-implied width of
:mod:`~.friction`; the others are fitted candidates) and G_s decay columns D_h per joint. They
sit on row j only, so the extra fold per sample is one (row columns × (G_w + G_s)) product. For a
pair (g, h) the model's columns are [T_g, T_g − D_h] = [T_g, D_h] L, L = [[1, 1], [0, −1]], so
their normal equations are linear maps of the candidates' (no second pass). With X the model's
other base columns (the other joints at their current choice) and the candidates Z, the weighted
least-squares residual with every other parameter free is (Frisch–Waugh–Lovell)

    SSE(g, h) = SSE_X − β_Mᵀ R_M⁻¹ β_M,   R = A_ZZ − A_ZX A_XX⁺ A_XZ,   β = b_Z − A_ZX A_XX⁺ b_X,

R_M = Lᵀ R L and β_M = Lᵀ β on the pair's two candidates (one column without a Stribeck term),
whose solution R_M⁻¹ β_M is (fc, fs − fc). Joints are visited in turn (coordinate descent,
:data:`SWEEPS` sweeps).

**Every sample scores the law.** The fit leaves out the equations around velocity reversals
(:meth:`~sensorless.regressor.ModelStructure.fit_mask`: the torque there blends both friction
branches and would bias the parameters), but how the law passes through zero is seen exactly
there. Those equations are compressed apart (``NormalEquations.left_out``), and a candidate is
scored by the residual of the fit to the kept equations on all of them: SSE(g, h) above plus, on
the left-out ones, the residual of that same fit, a quadratic in the candidate coefficients
(:func:`_left_out_score`).

**What the data must support (BIC).** The criterion is that noise-normalised residual plus ln N
per non-linear law parameter it adds (N samples): 2 ln N for a Stribeck term (vs and fs − fc),
ln N for a fitted width (w ≠ ε). A Stribeck term counts only for a physical effect: fs − fc > 0
(static friction above Coulomb), fc ≥ 0 and vs ≥ :data:`MIN_STRIBECK_OVER_WIDTH` · w (the decay
after the rise); a fitted width only with fc > 0. So a joint without a low-speed effect keeps the
simpler law (width ε, no Stribeck term; a negative bump fitted to one log does not carry over to
other motions: on the real KUKA LWR4 logs it raised the held-out NRMSE from 33.6 % to 50.5 %).
The chosen columns are then mapped out of the compressed equations for the final fit (OLS, WLS or
LMI): no second pass over the data, and a cluster (which compresses the same candidates on its
workers) chooses exactly as a local run.
"""

from __future__ import annotations

from typing import Mapping, Sequence

import numpy as np

from ..errors import DataError
from ..regressor.native import friction_candidates as native_friction_candidates
from ..regressor.normal_equations import NormalEquations
from ..regressor.terms import ModelStructure
from .base import base_parameters

__all__ = ["MIN_STRIBECK_OVER_WIDTH", "SWEEPS", "StribeckCandidates", "carry_prior", "choose_stribeck"]

#: coordinate-descent sweeps over the joints
SWEEPS = 2
#: a Stribeck decay must be slower than the rise (vs ≥ this × the width): else friction would
#: fall before it rose, and a narrow decay would only fit the sign chatter of noisy velocities
MIN_STRIBECK_OVER_WIDTH = 3.0
#: samples per block of the candidate columns (:meth:`StribeckCandidates.joint_features`): the scratch
#: (block × joints × candidates floats) stays in the core's cache between the element-wise passes
FEATURE_BLOCK = 256


def _lists(grid, what: str) -> dict[str, np.ndarray]:
    out = {j: np.asarray(g, dtype=float).ravel() for j, g in (grid or {}).items()}
    if any(g.size == 0 or not np.all(np.isfinite(g) & (g > 0)) for g in out.values()):
        raise DataError(f"every candidate {what} must be finite and > 0")
    return out


class StribeckCandidates:
    """A :class:`~sensorless.regressor.ModelStructure` whose joint-term block carries, after the
    model's own terms, G_w width columns tanh(v/w) and G_s decay columns (1 − e^{−(v/vs)²}) sgn v
    per joint (module docstring). ``grid``: candidate Stribeck velocities ``{joint: [vs, …]}``
    (joints with a ``stribeck`` term; the term may be dropped); a Stribeck joint without a grid
    keeps its fixed vs. ``widths``: candidate transition widths ``{joint: [w, …]}`` besides the
    structure's own ε (joints with ``fc`` or ``stribeck``). Lists are padded with their last value;
    rows of joints without candidates are zero. It has the interface :func:`compress` reads.
    """

    def __init__(self, structure: ModelStructure, grid: Mapping[str, Sequence[float]] | None,
                 widths: Mapping[str, Sequence[float]] | None = None):
        if type(structure) is not ModelStructure:
            raise DataError(f"the Stribeck velocity search needs a per-joint model (got {type(structure).__name__}); "
                            "give the Stribeck velocity as a number instead")
        if structure.friction_law != "blend":
            raise DataError(f"the friction law search needs the 'blend' law, not '{structure.friction_law}'")
        joints = list(structure.robot.term_joints)
        unknown = [j for j in (grid or {}) if j not in joints or "stribeck" not in structure.terms_of(j)]
        if unknown:
            raise DataError(f"Stribeck grid given for joints without a 'stribeck' term: {unknown}")
        unknown = [j for j in (widths or {}) if j not in joints
                   or not {"fc", "stribeck"} & set(structure.terms_of(j))]
        if unknown:
            raise DataError(f"transition widths given for joints without an 'fc' or 'stribeck' term: {unknown}")
        vs_lists, w_lists = _lists(grid, "Stribeck velocity"), _lists(widths, "transition width")
        self.structure = structure
        n = len(joints)
        self.width_lists: list[np.ndarray] = []
        self.vs_lists: list[np.ndarray] = []
        self.searched = np.zeros(n, dtype=bool)  # the joint's law is chosen here
        self.vs_searched = np.zeros(n, dtype=bool)  # its Stribeck term may be dropped / its vs chosen
        for k, j in enumerate(joints):
            terms = structure.terms_of(j)
            law = {"fc", "stribeck"} & set(terms)
            self.width_lists.append(np.concatenate([[structure.smoothing_of(j)], w_lists.get(j, [])]) if law
                                    else np.zeros(0))
            fixed = (structure.stribeck_velocity or {}).get(j)
            self.vs_lists.append(vs_lists[j] if j in vs_lists else
                                 (np.array([fixed]) if "stribeck" in terms else np.zeros(0)))
            self.vs_searched[k] = j in vs_lists
            self.searched[k] = bool(law) and (j in vs_lists or j in w_lists)
        Gw = max([w.size for w in self.width_lists] + [1])
        Gs = max([g.size for g in self.vs_lists] + [1])
        self.widths = np.ones((n, Gw))
        self.grid = np.ones((n, Gs))  # (n_act, G_s); rows of joints without candidates are unused
        for k in range(n):
            for arr, lst in ((self.widths, self.width_lists[k]), (self.grid, self.vs_lists[k])):
                if lst.size:
                    arr[k] = np.concatenate([lst, np.full(arr.shape[1] - lst.size, lst[-1])])

    # ---- what compress() reads (the wrapped structure's, plus the candidate columns) ------------
    #: the equations left out of the fit (velocity reversals, rest) are compressed apart, to score a law
    #: on every sample (:func:`choose_stribeck`)
    track_left_out = True
    robot = property(lambda self: self.structure.robot)
    n_rows = property(lambda self: self.structure.n_rows)
    row_names = property(lambda self: self.structure.row_names)
    row_map = property(lambda self: self.structure.row_map)
    n_body_params = property(lambda self: self.structure.n_body_params)
    n_block_params = property(lambda self: self.structure.n_block_params)
    term_rows = property(lambda self: self.structure.term_rows)

    @property
    def n_terms(self) -> int:
        """Columns per joint: the model's joint terms, then G_w widths and G_s decays."""
        return len(self.structure.joint_terms) + self.widths.shape[1] + self.grid.shape[1]

    @property
    def n_params(self) -> int:
        return self.n_block_params + len(self.structure.robot.term_joints) * self.n_terms

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

    def friction_states(self, traj):
        return self.structure.friction_states(traj)

    def joint_features(self, V: np.ndarray, A: np.ndarray, Z: "np.ndarray | None" = None,
                       out: "np.ndarray | None" = None) -> np.ndarray:
        """[model terms | T_g | D_h] per term joint, shape (N, n_term_joints, :attr:`n_terms`), into ``out``
        when given (a strided view will do); the candidate columns by :meth:`candidate_columns`."""
        s = self.structure
        base = s.joint_features(V, A, Z)
        n, J, nm = base.shape
        F = np.empty((n, J, self.n_terms)) if out is None else out
        F[:, :, :nm] = base
        v = V[:, s.robot.term_v_indices]
        self.candidate_columns(v, s.sliding_sign(v), F[:, :, nm:])
        return F

    def candidate_columns(self, v: np.ndarray, sgn: np.ndarray, out: np.ndarray, native: bool = True) -> np.ndarray:
        """The G_w + G_s candidate columns [tanh(v/w_g) | (1 − e^{−(v/vs_h)²}) sgn v] of term-joint velocities
        ``v`` (N, joints; ``sgn`` their sliding sign, 0 at rest) into ``out`` (N, joints, G_w + G_s): 0 at
        rest and on joints not searched; sgn v for a width w = 0. The C++ kernel
        (:func:`~sensorless.regressor.native.friction_candidates`, skips the saturated tanh/expm1 calls)
        when built and ``native``; else NumPy in blocks of :data:`FEATURE_BLOCK` samples with two reused
        scratch arrays (the work stays in cache). The two agree to rounding (a libm call vs NumPy's)."""
        on = self.searched[None, :]
        t_mask = (sgn != 0) * on  # 0 at rest (|v| ≤ δ)
        d_sign = -(sgn * on)  # the sign change of −expm1 folded in (exact)
        if native and native_friction_candidates(v, t_mask, d_sign, self.widths, self.grid, out):
            return out
        n, J = v.shape
        Gw, Gs = self.widths.shape[1], self.grid.shape[1]
        t_mask, d_sign = t_mask[:, :, None], d_sign[:, :, None]
        w = self.widths
        w_pos = bool(np.all(w > 0))
        w_div = np.where(w > 0, w, 1.0)[None]
        grid = self.grid[None]
        B = max(min(FEATURE_BLOCK, n), 1)
        T_buf, D_buf = np.empty((B, J, Gw)), np.empty((B, J, Gs))
        for a in range(0, n, B):
            b = min(a + B, n)
            vb = v[a:b, :, None]
            T = np.divide(vb, w_div, out=T_buf[: b - a])
            np.tanh(T, out=T)  # tanh(v/w), sgn v where w = 0
            if not w_pos:
                T = np.where(w[None] > 0, T, np.sign(vb))
            T *= t_mask[a:b]
            out[a:b, :, :Gw] = T
            D = np.divide(vb, grid, out=D_buf[: b - a])  # stribeck_decay: −expm1(−(v/vs)²) sgn
            np.square(D, out=D)
            np.negative(D, out=D)
            np.expm1(D, out=D)
            D *= d_sign[a:b]
            out[a:b, :, Gw:] = D
        return out

    # ---- from candidate equations to the model's -------------------------------------------------
    def _choice(self, choice) -> np.ndarray:
        """(n_act, 2) [width index, Stribeck index (−1: none)]; a 1-D choice is the Stribeck index
        at the structure's own width."""
        c = np.asarray(choice, dtype=int)
        if c.ndim == 1:
            c = np.column_stack([np.zeros_like(c), c])
        return c

    def _start(self, k: int) -> int:
        return self.n_block_params + k * self.n_terms

    def _term_vector(self, k: int, term: str, choice: np.ndarray) -> "dict[int, float]":
        """Candidate-layout combination {column: coefficient} of joint k's model column ``term``."""
        s = self.structure
        start, nt = self._start(k), len(s.joint_terms)
        if not self.searched[k] or term not in ("fc", "stribeck"):
            return {start + s.joint_terms.index(term): 1.0}
        g, h = choice[k]
        T = start + nt + int(g)
        if term == "fc":
            return {T: 1.0}
        if h < 0:
            return {}
        return {T: 1.0, start + nt + self.widths.shape[1] + int(h): -1.0}

    def select(self, ne: NormalEquations, choice) -> NormalEquations:
        """The normal equations of :meth:`structure_for` ``(choice)`` from the candidates' equations
        (A ↦ Lᵀ A L, b ↦ Lᵀ b with L the candidate-to-model column map; a dropped Stribeck term's
        column is zero or, when no joint keeps one, gone), exactly as compressing that structure."""
        if ne.A.shape[-1] != self.n_params:
            raise DataError(f"the compressed equations have {ne.A.shape[-1]} columns, the Stribeck candidates "
                            f"{self.n_params}: they were not compressed with this grid")
        choice = self._choice(choice)
        final = self.structure_for(choice)
        L = np.zeros((self.n_params, final.n_params))
        L[np.arange(self.n_block_params), np.arange(self.n_block_params)] = 1.0
        col = self.n_block_params
        for k in range(len(final.robot.term_joints)):
            for t in final.joint_terms:
                for i, a in self._term_vector(k, t, choice).items():
                    L[i, col] = a
                col += 1
        A, b = np.einsum("pi,rpq,qj->rij", L, ne.A, L, optimize=True), ne.b @ L
        zero = final.fixed_zero_index  # terms a joint does not have
        A[:, zero, :], A[:, :, zero], b[:, zero] = 0.0, 0.0, 0.0
        return NormalEquations(A, b, ne.c.copy(), ne.y_min, ne.y_max, ne.y_sum, ne.n_samples)

    def structure_for(self, choice) -> ModelStructure:
        """The wrapped structure with the chosen widths and vs; joints with Stribeck index −1 lose
        their Stribeck term."""
        import dataclasses

        s = self.structure
        choice = self._choice(choice)
        joints = list(s.robot.term_joints)
        dropped = {j for k, j in enumerate(joints) if self.searched[k] and choice[k, 1] < 0
                   and "stribeck" in s.terms_of(j)}
        eps = {j: s.smoothing_of(j) for j in joints}
        eps.update({j: float(self.widths[k, choice[k, 0]]) for k, j in enumerate(joints) if self.searched[k]})
        vs = {j: v for j, v in (s.stribeck_velocity or {}).items() if j not in dropped}
        vs.update({j: float(self.grid[k, choice[k, 1]]) for k, j in enumerate(joints)
                   if self.searched[k] and choice[k, 1] >= 0})
        if not dropped:
            return dataclasses.replace(s, coulomb_smoothing=eps, stribeck_velocity=vs or None)
        per = {j: tuple(t for t in s.terms_of(j) if not (t == "stribeck" and j in dropped)) for j in joints}
        return dataclasses.replace(s, joint_terms=s.joint_terms, per_joint_terms=per, coulomb_smoothing=eps,
                                   stribeck_velocity=vs or None)


def _pinv_psd(A: np.ndarray, rcond: float = 1e-12) -> np.ndarray:
    """Pseudo-inverse of a symmetric PSD matrix, equilibrated (columns of very different scale)."""
    d = np.sqrt(np.maximum(np.diag(A), 0.0))
    d = np.where(d > 0, 1.0 / np.where(d > 0, d, 1.0), 0.0)
    lam, U = np.linalg.eigh(d[:, None] * A * d[None, :])
    keep = lam > rcond * max(float(lam.max(initial=0.0)), 1e-300)
    return (d[:, None] * (U[:, keep] / lam[keep]) @ U[:, keep].T) * d[None, :]


def _gain(R: np.ndarray, beta: np.ndarray, L: np.ndarray, raw: np.ndarray) -> tuple[float, np.ndarray]:
    """(β_Mᵀ R_M⁻¹ β_M, R_M⁻¹ β_M) for the model columns Z L (module docstring); (0, 0) when a
    column is dead (nothing left after projecting out X; ``raw``: diag A_ZZ, the scale)."""
    RM, bM = L.T @ R @ L, L.T @ beta
    dRM = np.diag(RM)
    if np.any(dRM <= 1e-12 * np.maximum(np.abs(L).T @ raw, 1e-300)):
        return 0.0, np.zeros(L.shape[1])
    d = 1.0 / np.sqrt(dRM)
    coef = d * np.linalg.lstsq(d[:, None] * RM * d[None, :], d * bM, rcond=1e-12)[0]
    return float(bM @ coef), coef


#: a 2×2 system of :func:`_gains` is solved in closed form (within ~κ·eps of the SVD's least squares)
#: when its condition number κ is at most this, by :func:`_gain` otherwise
CLOSED_FORM_COND = 1e4


def _gains(R, beta, raw, i, j, two: bool) -> tuple[np.ndarray, np.ndarray]:
    """:func:`_gain` of Z L for L = [e_i, e_i − e_j] (``two``), [e_i − e_j] or [e_i] (j None), at once
    for broadcast index arrays i, j: gains and coefficients (…, columns). L's entries are 0, ±1, so
    R_M, β_M are sums of two entries, and the equilibrated D R_M D x = D β_M (D = diag R_M^−½) is
    1×1 or 2×2: Cramer's rule where κ ≤ :data:`CLOSED_FORM_COND`, else :func:`_gain` (rare). (One
    ``lstsq`` call per pair cost 0.17 s of ``identify`` on a 600-sample UR5 log, 4056 pairs.)"""
    rii = R[i, i]
    rm, bm, sc = [rii], [beta[i]], [raw[i]]
    if j is not None:
        ti, tj = rii - R[j, i], R[i, j] - R[j, j]  # (e_i − e_j)ᵀ R at columns i and j
        rm, bm, sc = [ti - tj], [beta[i] - beta[j]], [raw[i] + raw[j]]
        if two:
            rm, bm, sc = [rii, rii - R[i, j], ti, rm[0]], [beta[i], bm[0]], [raw[i], sc[0]]
    n = len(bm)
    X = np.moveaxis(np.array(np.broadcast_arrays(*rm, *bm, *sc)), 0, -1)
    RM, bM = X[..., :n * n].reshape(X.shape[:-1] + (n, n)), X[..., n * n:n * n + n]
    dRM = np.diagonal(RM, axis1=-2, axis2=-1)
    dead = np.any(dRM <= 1e-12 * np.maximum(X[..., n * n + n:], 1e-300), axis=-1)
    with np.errstate(all="ignore"):
        d = 1.0 / np.sqrt(np.where(dead[..., None], 1.0, dRM))
        M, r = d[..., :, None] * RM * d[..., None, :], d * bM
        if n == 1:
            x, well = r / M[..., 0], ~dead
        else:
            m00, m01, m10, m11 = M[..., 0, 0], M[..., 0, 1], M[..., 1, 0], M[..., 1, 1]
            det = m00 * m11 - m01 * m10
            x = np.stack([m11 * r[..., 0] - m01 * r[..., 1], m00 * r[..., 1] - m10 * r[..., 0]], axis=-1)
            x /= det[..., None]
            well = det * CLOSED_FORM_COND >= (m00 + m11) ** 2  # κ ≤ tr²/det for a PSD 2×2; False for NaN
        coef = d * x
        gain = np.sum(bM * coef, axis=-1)
    coef[dead], gain[dead] = 0.0, 0.0
    redo = np.argwhere(~well & ~dead)  # (two columns only)
    I, J = np.broadcast_arrays(i, j) if len(redo) else (None, None)
    for idx in map(tuple, redo):
        L = np.zeros((R.shape[0], n))
        L[I[idx], :], L[J[idx], -1] = 1.0, -1.0
        gain[idx], coef[idx] = _gain(R, beta, L, raw)
    return gain, coef


def _left_out_quadratic(Ao, bo, co, LX, theta_x0, U, Z):
    """(s₀, g, H): θ_Z ↦ s₀ + 2 gᵀθ_Z + θ_Zᵀ H θ_Z is the residual sum of squares, on the left-out
    equations (Ao, bo, co), of the fit of the kept ones with candidate coefficients θ_Z: the other
    columns are then θ_X = θ_X0 − U θ_Z, so the full vector is π = π₀ + D θ_Z with π₀ = L_X θ_X0
    and D = E_Z − L_X U (module docstring)."""
    pi0 = LX @ theta_x0
    D = -LX @ U
    D[Z, np.arange(len(Z))] += 1.0
    s0 = float(pi0 @ Ao @ pi0 - 2.0 * bo @ pi0 + co)
    return s0, D.T @ (Ao @ pi0 - bo), D.T @ (Ao @ D)


def _left_out_score(quad, i, ti, j, tj) -> np.ndarray:
    """That quadratic, floored at 0, at θ_Z = t_i e_i + t_j e_j (elementwise over arrays)."""
    s0, g, H = quad
    lin = g[i] * ti + g[j] * tj
    return np.maximum(s0 + 2.0 * lin + (H[i, i] * ti * ti + (H[i, j] + H[j, i]) * ti * tj + H[j, j] * tj * tj), 0.0)


def _finite(x) -> list:
    """A list for result.json (strict JSON): non-finite values as None."""
    return [float(v) if np.isfinite(v) else None for v in np.ravel(x)]


def choose_stribeck(cand: StribeckCandidates, ne: NormalEquations, weights) -> tuple[np.ndarray, dict]:
    """Choose each joint's transition width and Stribeck velocity (or no Stribeck term) from
    candidate equations ``ne`` (module docstring).

    The criterion is the noise-normalised residual Σ_r SSE_r/σ_r² (σ_r given in ``weights``, else
    the two-step σ of the starting choice: width ε, the middle of every vs grid) plus the BIC
    penalties; every (width, vs) pair of a joint is scored at once (:func:`_gains`), the smallest
    wins (ties: the smallest width index, then no Stribeck term, then the smallest vs index).
    Returns the choice, (n_act, 2) [width index, Stribeck index or −1], for
    :meth:`StribeckCandidates.select` / :meth:`~StribeckCandidates.structure_for`, and a record per
    searched joint (last sweep): ``grid`` (vs), ``widths`` (index 0: ε), ``sse`` and ``coefficient``
    (fs − fc) per vs at the chosen width, ``sse_without`` (no Stribeck term, chosen width),
    ``sse_width`` (best per width), ``vs`` and ``width`` (None: dropped / the simpler width ε).
    """
    from .least_squares import two_step_sigma

    s = cand.structure
    joints = list(s.robot.term_joints)
    n = len(joints)
    choice = np.zeros((n, 2), dtype=int)
    for k in range(n):
        choice[k, 1] = cand.vs_lists[k].size // 2 if cand.vs_lists[k].size else -1
    sigma = (np.asarray(weights, dtype=float) if isinstance(weights, np.ndarray)
             else two_step_sigma(cand.select(ne, choice)))
    A, b, c = ne.total(1.0 / sigma**2)
    Ao, bo, co = ne.left_out.total(1.0 / sigma**2) if ne.left_out is not None else (None, None, 0.0)
    ln_n = np.log(max(ne.n_samples, 2))
    base = base_parameters(s).independent
    nb, nt = cand.n_block_params, len(s.joint_terms)
    Gw = cand.widths.shape[1]
    record = {}
    for _ in range(SWEEPS):
        for k in np.flatnonzero(cand.searched):
            j = joints[k]
            cols = []  # the other base columns (other joints at their current choice), as candidate combinations
            for i in base:
                if i < nb:
                    cols.append({int(i): 1.0})
                    continue
                q, t = divmod(int(i) - nb, nt)
                term = s.joint_terms[t]
                if q == k and term in ("fc", "stribeck"):
                    continue
                vec = cand._term_vector(q, term, choice)
                if vec:
                    cols.append(vec)
            LX = np.zeros((cand.n_params, len(cols)))
            for m, vec in enumerate(cols):
                for i, a in vec.items():
                    LX[i, m] = a
            start = cand._start(k) + nt
            widths, vs = cand.width_lists[k], cand.vs_lists[k]
            nw, ns = widths.size, vs.size
            Z = np.concatenate([start + np.arange(nw), start + Gw + np.arange(ns)])
            AXX, AXZ, bX = LX.T @ A @ LX, LX.T @ A[:, Z], LX.T @ b
            P = _pinv_psd(AXX)
            U = P @ AXZ
            sse_x = c - bX @ P @ bX
            R = A[np.ix_(Z, Z)] - AXZ.T @ U
            beta = b[Z] - U.T @ bX
            raw = np.diag(A)[Z]
            quad = _left_out_quadratic(Ao, bo, co, LX, P @ bX, U, Z) if Ao is not None else None
            terms = s.terms_of(j)
            has_fc, has_st = "fc" in terms, "stribeck" in terms
            G, H = np.arange(nw), nw + np.arange(ns)  # Z's T_g and D_h
            pen_w = ln_n * (G > 0)
            crit = np.full((nw, ns + 1), np.inf)  # [g, 0]: no Stribeck term; [g, 1 + h]: vs h (inf: not admissible)
            sse_without = np.full(nw, np.inf)
            if has_fc and (not has_st or cand.vs_searched[k]):  # model columns [T_g]
                gain, coef = _gains(R, beta, raw, G, None, False)
                sse_without = sse_x - gain + (_left_out_score(quad, G, coef[:, 0], G, 0.0) if quad else 0.0)
                crit[:, 0] = np.where((G == 0) | (coef[:, 0] > 0), sse_without + pen_w, np.inf)
            gain, coef = _gains(R, beta, raw, G[:, None], H, has_fc)  # [T_g, T_g − D_h] ([T_g − D_h] without fc)
            th = (coef[..., 0] + coef[..., 1], -coef[..., 1]) if has_fc else (coef[..., 0], -coef[..., 0])
            sse = sse_x - gain + (_left_out_score(quad, G[:, None], th[0], H, th[1]) if quad else 0.0)
            coef_st = coef[..., -1]
            ok = (vs >= MIN_STRIBECK_OVER_WIDTH * widths[:, None]) & (coef_st > 0)
            ok &= (coef[..., 0] >= 0) | (not has_fc)
            ok |= not cand.vs_searched[k]  # a fixed vs is kept whatever its sign
            crit[:, 1:] = np.where(ok, sse + pen_w[:, None] + 2 * ln_n * cand.vs_searched[k], np.inf)
            g, h = np.unravel_index(np.argmin(np.where(np.isnan(crit), np.inf, crit)), crit.shape)
            # no admissible candidate (stribeck without fc, none physical): the term is dropped
            g, h = (int(g), int(h) - 1) if np.isfinite(crit[g, h]) else (0, -1)
            choice[k] = g, h
            record[j] = {"grid": vs.tolist(), "widths": widths.tolist(),
                         "sse": _finite(sse[g]), "sse_without": _finite([sse_without[g] if has_fc else sse_x])[0],
                         "coefficient": coef_st[g].tolist(),
                         "sse_width": _finite(np.minimum(sse.min(axis=1, initial=np.inf), sse_without)),
                         "vs": float(vs[h]) if h >= 0 else None,
                         "width": float(widths[g]) if g > 0 else None,
                         "penalty_per_parameter": float(ln_n)}
    return choice, record


def carry_prior(prior, before: ModelStructure, after: ModelStructure):
    """A prior vector of ``before`` moved onto ``after`` (the structure chosen by the Stribeck
    search, which may have dropped terms): values by parameter label, ``after``'s own prior for a
    label ``before`` lacks. None stays None."""
    if prior is None:
        return None
    prior = np.asarray(prior, dtype=float)
    if prior.shape != (len(before.labels),) or list(before.labels) == list(after.labels):
        return prior  # (a wrong shape is reported by the solver that uses it)
    given = dict(zip(before.labels, prior))
    own = after.prior()
    return np.array([given.get(lab, own[i]) for i, lab in enumerate(after.labels)])
