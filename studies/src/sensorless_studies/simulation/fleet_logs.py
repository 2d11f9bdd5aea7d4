"""Many Parquet logs of one simulated arm: the data of fleet-scale identification (docs/fleet.md).

The logs are consecutive pieces of one synthetic log: true torques τ = Y(q, v, v̇) π_true + τ_f
(Pinocchio RNEA of a perturbed truth with friction, :func:`~.synthetic.perturbed_truth`) along a
Fourier excitation, plus white noise per file. The excitation has an integer number of samples per
period, so the torques are computed for one period and tiled. Columns ``t``, ``q_<joint>``,
``tau_<joint>`` (v and v̇ come from the reader's Savitzky–Golay step, as for a real log).
"""

from __future__ import annotations

from pathlib import Path

import numpy as np

__all__ = ["write_fleet_logs"]


def write_fleet_logs(
    robot,
    directory: str | Path,
    n_files: int,
    samples_per_file: int,
    *,
    rate: float = 1000.0,
    base_freq: float = 0.05,
    noise_std: float = 0.1,
    seed: int = 0,
    subdirs: int = 1,
) -> list[Path]:
    """Write ``n_files`` consecutive pieces of one synthetic log as Parquet files.

    Ground truth: :func:`~sensorless_studies.simulation.perturbed_truth` (seed), excitation
    :func:`~sensorless.excitation.random_fourier` (seed + 1). ``rate / base_freq`` must be
    an integer (samples per period). Files go to ``directory/robot_<k>/log_<i>.parquet``
    (``k = i mod subdirs``) so a recursive glob has something to find.
    """
    import pandas as pd

    from sensorless.excitation import random_fourier
    from sensorless.testing import perturbed_truth

    period = rate / base_freq
    if abs(period - round(period)) > 1e-9:
        raise ValueError(f"rate / base_freq must be an integer number of samples, got {period}")
    period = int(round(period))
    truth = perturbed_truth(robot, rng=seed)
    fourier = random_fourier(robot, rng=seed + 1, base_freq=base_freq)
    q1, v1, a1 = fourier.evaluate(np.arange(period) / rate)
    r = truth.robot
    tau1 = truth.torques(r.full_configuration(q1), r.full_velocity(v1), r.full_velocity(a1))
    act = [r.joint_names.index(j) for j in r.actuated_joints]
    directory = Path(directory)
    paths = []
    for i in range(n_files):
        k = i * samples_per_file + np.arange(samples_per_file)
        q, _, _ = fourier.evaluate(k / rate)
        tau = np.zeros((samples_per_file, len(r.joint_names)))
        noise = np.random.default_rng([seed, i]).normal(size=(samples_per_file, len(act))) * noise_std
        tau[:, act] = tau1[k % period] + noise
        cols = {"t": k / rate}
        cols.update({f"q_{j}": q[:, n] for n, j in enumerate(r.joint_names)})
        cols.update({f"tau_{j}": tau[:, n] for n, j in enumerate(r.joint_names)})
        path = directory / f"robot_{i % subdirs}" / f"log_{i:04d}.parquet"
        path.parent.mkdir(parents=True, exist_ok=True)
        pd.DataFrame(cols).to_parquet(path)
        paths.append(path)
    return paths
