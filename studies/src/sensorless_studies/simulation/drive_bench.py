"""A drive on a test bench: motor current in, output torque measured, friction between (issue #44).

Ground truth for the drive terms of :mod:`sensorless.regressor.friction_state`. The bench imposes a
velocity profile on the output (:func:`~.lugre.velocity_profile`: many reversals, slow segments and
rests) and a load torque τ_out independent of the motion (a level plus two slow sines, so |τ_out| and
sgn v vary apart). The motor supplies

    m = τ_out + (fc + μ |τ_out|) tanh(v/ε) + fv v + J v̇ + o,

the transmission's Coulomb friction growing with the transmitted torque (a strain-wave gear, a cable
under tension), and its current is u = m / (K + ΔK w), w = max(0, −sgn(m) tanh(v/ε)): the torque per
ampere differs when the output drives the motor back (directional efficiency; w is 0 at rest). An elastic transmission (``stiffness`` k) puts
the motor-side encoder at q_m = q + τ_out/k. The log is what a lab records
(:class:`sensorless.testing.RealArtefacts`): both encoders quantized, white noise on the current and
on the output torque, no logged velocity (it comes from q).
"""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np

from sensorless.data.trajectory import Trajectory
from sensorless.testing import RealArtefacts, with_real_artefacts

from .lugre import velocity_profile

__all__ = ["DriveBench", "drive_noise", "simulate_drive_bench", "write_drive_csv"]


@dataclasses.dataclass(frozen=True)
class DriveBench:
    """A drive's truth [N·m, N·m/A, rad/s, N·m·s/rad, kg·m²] and its bench (module docstring).
    ``truth()`` gives the coefficients as the friction law names them."""

    gain: float = 0.5
    gain_back: float = 0.0
    fc: float = 0.04
    load: float = 0.0
    fv: float = 0.02
    inertia: float = 0.0
    offset: float = 0.0
    eps: float = 0.02
    load_level: float = 0.3
    load_swing: float = 0.4
    stiffness: float = np.inf
    q_step: float = 2 * np.pi / 2**17
    noise_current: float = 0.004
    noise_out: float = 0.003

    def truth(self) -> dict:
        """{law term: true value} of the terms this bench has (the law's sum is τ_f − K u = −τ_out)."""
        out = {"fc": self.fc, "fv": self.fv, "offset": self.offset, "gain": self.gain}
        if self.inertia:
            out["inertia"] = self.inertia
        if self.gain_back:
            out["gain_back"] = self.gain_back
        if self.load:
            out["load"] = self.load
        return out


def drive_noise(bench: DriveBench) -> float:
    """The std of the output torque a perfect model predicts from the noisy current, against the noisy
    output torque: √(σ_out² + (K σ_u)²) (the floor of any held-out error)."""
    return float(np.hypot(bench.noise_out, bench.gain * bench.noise_current))


def simulate_drive_bench(bench: DriveBench = DriveBench(), *, duration: float = 30.0, rate: float = 500.0,
                         seed: int = 0, joint: str = "joint") -> Trajectory:
    """A bench log of ``bench`` (module docstring): t, quantized q, extras current, tau_out (and
    q_motor with a finite stiffness); no v (a lab's log)."""
    rng = np.random.default_rng(seed + 7)
    profile = velocity_profile(duration, seed, v_max=1.5, v_slow=0.02)
    t = np.arange(int(duration * rate)) / rate
    q, v, a = profile(t)
    ph = rng.uniform(0, 2 * np.pi, 2)
    tau_out = (bench.load_level + bench.load_swing * (np.sin(2 * np.pi * t / 7.3 + ph[0])
                                                      + 0.6 * np.sin(2 * np.pi * t / 2.9 + ph[1])))
    m = (tau_out + (bench.fc + bench.load * np.abs(tau_out)) * np.tanh(v / bench.eps) + bench.fv * v
         + bench.inertia * a + bench.offset)
    u = m / (bench.gain + bench.gain_back * np.maximum(0.0, -np.sign(m) * np.tanh(v / bench.eps)))
    extras = {"current": (u + rng.normal(0, bench.noise_current, t.size))[:, None],
              "tau_out": (tau_out + rng.normal(0, bench.noise_out, t.size))[:, None]}
    if np.isfinite(bench.stiffness):
        qm = q + tau_out / bench.stiffness
        extras["q_motor"] = (np.round(qm / bench.q_step) * bench.q_step)[:, None]
    clean = Trajectory(t=t, q=q[:, None], joint_names=(joint,), extras=extras, source=f"<drive bench seed {seed}>")
    return with_real_artefacts(clean, RealArtefacts(q_step=bench.q_step), rng)


def write_drive_csv(traj: Trajectory, path: "str | Path") -> Path:
    """A single-joint bench CSV with bare columns ``t, q, current, tau_out[, q_motor]`` (what
    ``sensorless friction`` reads as a drive)."""
    import pandas as pd

    path = Path(path)
    cols = {"t": traj.t, "q": traj.q[:, 0]}
    cols.update({k: np.asarray(traj.extras[k])[:, 0] for k in ("current", "tau_out", "q_motor") if k in traj.extras})
    pd.DataFrame(cols).to_csv(path, index=False, float_format="%.9g")
    return path
