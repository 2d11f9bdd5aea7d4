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

from pathlib import Path

import torch
from torch import nn

from ..errors import DataError, SensorlessError
from ..io import atomic_open, check_input_file, read_json, write_json_atomic
from ..outdir import warn_if_edited
from .mlp import build_network

__all__ = ["META", "WEIGHTS", "MAX_NETWORK_PARAMETERS", "check_architecture", "load_network", "save_network"]

WEIGHTS = "weights.pt"
META = "model.json"
#: Largest network a model.json may describe (parameters); beyond it loading would allocate
#: gigabytes on the word of a JSON file. The project's networks have < 10⁶.
MAX_NETWORK_PARAMETERS = 50_000_000
_MAX_DIM = 1_000_000
_MAX_LAYERS = 64
_MAX_META_BYTES = 64 * 1024 * 1024


def _positive_int(arch: dict, key: str, value, src: str) -> int:
    if isinstance(value, bool) or not isinstance(value, (int, float)) or value != int(value) or not 1 <= value <= _MAX_DIM:
        raise DataError(f"architecture '{key}' must be an integer in [1, {_MAX_DIM}], got {value!r}", src)
    return int(value)


def check_architecture(arch, src: str = "model.json") -> dict:
    """DataError unless ``arch`` describes a network of bounded size (≤ :data:`MAX_NETWORK_PARAMETERS`)."""
    if not isinstance(arch, dict):
        raise DataError(f"'architecture' must be an object, got {type(arch).__name__}", src)
    for key in ("in_dim", "out_dim", "hidden"):
        if key not in arch:
            raise DataError(f"architecture lacks '{key}'", src)
    i = _positive_int(arch, "in_dim", arch["in_dim"], src)
    o = _positive_int(arch, "out_dim", arch["out_dim"], src)
    hidden = arch["hidden"]
    if not isinstance(hidden, (list, tuple)) or len(hidden) > _MAX_LAYERS:
        raise DataError(f"architecture 'hidden' must be a list of at most {_MAX_LAYERS} layer sizes", src)
    hs = [_positive_int(arch, "hidden", h, src) for h in hidden]
    kind = arch.get("kind", "mlp")
    if kind == "lstm":
        w = _positive_int(arch, "window", arch.get("window"), src)
        h = hs[0] if hs else 1
        n = 4 * h * (i // max(w, 1) + h + 2) * max(1, len(hs)) + (h + 1) * o
    else:
        dims = [i, *hs, o]
        groups = o if kind == "per_joint" else 1
        n = groups * sum((a + 1) * b for a, b in zip(dims[:-1], dims[1:]))
    if n > MAX_NETWORK_PARAMETERS:
        raise DataError(f"architecture describes a network of {n:.3g} parameters "
                        f"(more than {MAX_NETWORK_PARAMETERS:.0e}); refusing to allocate it", src)
    return arch


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
    meta = read_json(meta_path, "model description (model.json)", _MAX_META_BYTES, error=DataError)
    warn_if_edited(meta_path, "model description")
    warn_if_edited(w_path, "weights file")
    if not isinstance(meta, dict) or "architecture" not in meta:
        raise DataError("unreadable model description: no 'architecture' object", str(meta_path))
    arch = meta["architecture"]
    check_input_file(w_path, "weights file")
    check_architecture(arch, str(meta_path))
    try:
        net = build_network(arch)
    except SensorlessError:
        raise
    except (TypeError, ValueError, KeyError, RuntimeError) as exc:
        raise DataError(f"cannot build the network: {_first_line(exc)}", str(meta_path)) from None
    try:
        state = torch.load(w_path, map_location="cpu", weights_only=True)
        net.load_state_dict(state)
    except Exception as exc:  # noqa: BLE001 - torch raises many kinds (UnpicklingError, RuntimeError)
        raise DataError(f"weights could not be loaded safely: {type(exc).__name__}: {_first_line(exc)}",
                        str(w_path)) from None
    net.eval()
    return net, meta


def _first_line(exc: BaseException) -> str:
    """torch's messages span many lines (tracebacks of the unpickler, key lists): keep one."""
    lines = [ln.strip() for ln in str(exc).splitlines() if ln.strip()]
    return (lines[0] if lines else type(exc).__name__)[:300] + (" ..." if len(lines) > 1 else "")
