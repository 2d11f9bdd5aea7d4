"""Saving and loading networks safely: weights and JSON, never pickled code.

A saved model is a directory with

* ``weights.pt`` — ``torch.save(net.state_dict())``: tensors only;
* ``model.json`` — the architecture (to rebuild the module), normalisation statistics,
  feature settings, hyper-parameters and training history.

Loading rebuilds the module from JSON and reads the weights with
``torch.load(..., weights_only=True)``, which refuses anything but tensors and plain
containers, so a tampered file cannot execute code.
"""

from __future__ import annotations

import json
from pathlib import Path

import torch
from torch import nn

from ..errors import DataError
from ..io import atomic_open, write_json_atomic
from .mlp import build_network

__all__ = ["META", "WEIGHTS", "load_network", "save_network"]

WEIGHTS = "weights.pt"
META = "model.json"


def save_network(directory: str | Path, net: nn.Module, meta: dict) -> Path:
    """Write ``weights.pt`` + ``model.json`` (``meta`` must hold ``architecture``)."""
    if "architecture" not in meta:
        raise DataError("model metadata needs an 'architecture' entry")
    d = Path(directory)
    d.mkdir(parents=True, exist_ok=True)
    state = {k: v.detach().cpu().clone() for k, v in net.state_dict().items()}
    with atomic_open(d / WEIGHTS, "wb") as f:
        torch.save(state, f)
    write_json_atomic(meta, d / META)
    return d


def load_network(directory: str | Path) -> tuple[nn.Module, dict]:
    """Rebuild the module from ``model.json`` and load ``weights.pt`` (weights only)."""
    d = Path(directory)
    meta_path, w_path = d / META, d / WEIGHTS
    if not meta_path.exists() or not w_path.exists():
        raise DataError(f"not a saved sensorless network (need {META} and {WEIGHTS})", str(d))
    try:
        meta = json.loads(meta_path.read_text())
        arch = meta["architecture"]
    except (ValueError, KeyError) as exc:
        raise DataError(f"unreadable model description: {exc}", str(meta_path)) from None
    net = build_network(arch)
    try:
        state = torch.load(w_path, map_location="cpu", weights_only=True)
        net.load_state_dict(state)
    except Exception as exc:  # noqa: BLE001 - torch raises many kinds (UnpicklingError, RuntimeError)
        raise DataError(f"weights could not be loaded safely: {type(exc).__name__}: {exc}", str(w_path)) from None
    net.eval()
    return net, meta
