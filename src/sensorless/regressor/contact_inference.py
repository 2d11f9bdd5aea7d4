"""Contact flags from measured normal forces (wrench mode without 'contact' flags).

A foot carries load when its measured normal force (world z of ``contact_forces``) stands out
of the sensor's noise. Per foot, the unloaded level and the noise come from the log itself:

* the low cluster: samples within 5 % of the foot's load scale (99th percentile of |f_z|)
  above its 5th percentile; when its median is below 10 % of the scale it is the foot in the
  air (flight or swing, possibly with a sensor bias): centre = its median, σ = 1.4826 · MAD;
* otherwise the foot is loaded throughout: centre 0, σ from the MAD of the first differences
  (/√2), an upper bound of the noise;
* threshold = centre + max(k σ, floor), floor = ``floor_rel`` × scale (a noise-free log).

Unlike foot height and speed, this misses no loaded sample whose force is above the noise.
"""

from __future__ import annotations

import numpy as np

__all__ = ["contact_summary", "infer_contacts", "normal_forces"]

K_SIGMA = 5.0
FLOOR_REL = 1e-3


def normal_forces(forces: np.ndarray, dims) -> np.ndarray:
    """World-z force (N, n_contacts) of measured wrenches (N, Σ dims) [f; τ] per contact."""
    starts = np.concatenate([[0], np.cumsum(dims)])[:-1]
    return np.asarray(forces, float)[:, starts + 2]


def _threshold(fz: np.ndarray, k: float, floor_rel: float) -> tuple[float, float, float]:
    """(threshold, centre, σ) of one foot's normal force (module docstring)."""
    scale = float(np.percentile(np.abs(fz), 99)) if fz.size else 0.0
    if scale <= 0:
        return 0.0, 0.0, 0.0
    low = fz <= np.percentile(fz, 5) + 0.05 * scale
    centre = float(np.median(fz[low]))
    if low.sum() >= 10 and abs(centre) < 0.1 * scale:
        sigma = 1.4826 * float(np.median(np.abs(fz[low] - centre)))
    else:
        centre = 0.0
        d = np.diff(fz)
        sigma = 1.4826 * float(np.median(np.abs(d - np.median(d)))) / np.sqrt(2) if d.size else 0.0
    return centre + max(k * sigma, floor_rel * scale), centre, sigma


def infer_contacts(fz: np.ndarray, *, k: float = K_SIGMA, floor_rel: float = FLOOR_REL) -> tuple[np.ndarray, dict]:
    """Flags (N, n_contacts) where the normal force ``fz`` (N, n_contacts) exceeds its noise
    threshold, and per contact the threshold, centre and σ [N] (module docstring)."""
    fz = np.asarray(fz, float)
    flags = np.zeros(fz.shape, bool)
    info = {"threshold": [], "centre": [], "sigma": [], "k_sigma": k, "floor_rel": floor_rel}
    for c in range(fz.shape[1]):
        thr, centre, sigma = _threshold(fz[:, c], k, floor_rel)
        flags[:, c] = fz[:, c] > thr
        info["threshold"].append(thr)
        info["centre"].append(centre)
        info["sigma"].append(sigma)
    return flags, info


def contact_summary(structure, traj) -> dict:
    """Per contact frame: where the flags come from, the fraction of samples in contact and,
    with measured forces, the threshold and the loaded samples the flags leave out."""
    flags = structure.contacts(traj)
    frames = list(structure.contact_frames)
    out = {"source": "log" if traj.extras.get(structure.contact_key) is not None else
           ("normal force" if structure.mode == "wrench" else "foot height and speed"),
           "fraction": dict(zip(frames, map(float, flags.mean(axis=0)))), "n_samples": int(len(traj))}
    if structure.mode == "wrench":
        loaded, info = infer_contacts(normal_forces(structure.measured_wrenches(traj), structure.contact_dims))
        out["normal_force_threshold"] = dict(zip(frames, map(float, info["threshold"])))
        out["noise_sigma"] = dict(zip(frames, map(float, info["sigma"])))
        out["loaded_unflagged"] = dict(zip(frames, map(int, (loaded & ~flags).sum(axis=0))))
    return out
