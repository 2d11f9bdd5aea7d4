"""Small networks and their deterministic training loop (PyTorch, CPU).

* :class:`MLP` — shared network, features → all outputs.
* :class:`PerJointMLP` — one independent MLP per output, evaluated as batched matrix
  products (weights (G, in, out), ``torch.baddbmm``), so G nets cost one pass.
* :class:`LSTMRegressor` — optional sequence model over the feature window.

Training (:func:`train_network`): MSE on standardised targets, Adam, learning rate ×
``lr_factor`` after ``lr_patience`` epochs without validation improvement
(ReduceLROnPlateau), early stopping after ``patience`` such epochs, best validation
weights restored. The validation set is made of contiguous blocks of samples (random
blocks, seeded), so neighbouring, nearly identical samples do not leak across the split.
Determinism: ``torch.manual_seed``, a seeded generator for shuffling,
``torch.use_deterministic_algorithms(True)`` and a fixed thread count, all restored on exit.
"""

from __future__ import annotations

import contextlib
import copy
import time
from dataclasses import asdict, dataclass
from typing import Iterator, Sequence

import numpy as np
import torch
from torch import nn

from ..errors import DataError, SensorlessError

__all__ = [
    "ACTIVATIONS",
    "MLP",
    "LSTMRegressor",
    "PerJointMLP",
    "TrainConfig",
    "build_network",
    "deterministic_torch",
    "predict_network",
    "train_network",
]

ACTIVATIONS = {"relu": nn.ReLU, "leakyrelu": nn.LeakyReLU, "tanh": nn.Tanh}


def _activation(name: str) -> nn.Module:
    try:
        return ACTIVATIONS[name.lower()]()
    except KeyError:
        raise SensorlessError(f"unknown activation '{name}'; choose from {sorted(ACTIVATIONS)}") from None


class MLP(nn.Module):
    """in_dim → hidden… → out_dim, one activation after every hidden layer."""

    def __init__(self, in_dim: int, out_dim: int, hidden: Sequence[int] = (256, 256), activation: str = "relu") -> None:
        super().__init__()
        layers: list[nn.Module] = []
        d = in_dim
        for h in hidden:
            layers += [nn.Linear(d, int(h)), _activation(activation)]
            d = int(h)
        layers.append(nn.Linear(d, out_dim))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return self.net(x)


class _GroupedLinear(nn.Module):
    """G independent linear maps: (G, B, in) → (G, B, out)."""

    def __init__(self, groups: int, in_dim: int, out_dim: int) -> None:
        super().__init__()
        bound = 1.0 / np.sqrt(in_dim)  # same init as nn.Linear
        self.weight = nn.Parameter(torch.empty(groups, in_dim, out_dim).uniform_(-bound, bound))
        self.bias = nn.Parameter(torch.empty(groups, 1, out_dim).uniform_(-bound, bound))

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        return torch.baddbmm(self.bias, x, self.weight)


class PerJointMLP(nn.Module):
    """One MLP per output (all see the same features), evaluated in one batched pass."""

    def __init__(self, in_dim: int, out_dim: int, hidden: Sequence[int] = (256, 256), activation: str = "relu") -> None:
        super().__init__()
        self.out_dim = out_dim
        layers: list[nn.Module] = []
        d = in_dim
        for h in hidden:
            layers += [_GroupedLinear(out_dim, d, int(h)), _activation(activation)]
            d = int(h)
        layers.append(_GroupedLinear(out_dim, d, 1))
        self.net = nn.Sequential(*layers)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        y = self.net(x.unsqueeze(0).expand(self.out_dim, -1, -1))  # (G, B, 1)
        return y[..., 0].transpose(0, 1)


class LSTMRegressor(nn.Module):
    """LSTM over the window: input (B, window·step_dim [+ extra]) → last hidden state → linear."""

    def __init__(self, in_dim: int, out_dim: int, window: int, hidden: Sequence[int] = (128,), activation: str = "tanh") -> None:
        super().__init__()
        if in_dim % window:
            raise SensorlessError(f"LSTM input of {in_dim} features is not a whole number of {window} window steps")
        self.window, self.step = window, in_dim // window
        self.lstm = nn.LSTM(self.step, int(hidden[0]), num_layers=max(1, len(hidden)), batch_first=True)
        self.head = nn.Linear(int(hidden[0]), out_dim)

    def forward(self, x: torch.Tensor) -> torch.Tensor:
        out, _ = self.lstm(x.reshape(x.shape[0], self.window, self.step))
        return self.head(out[:, -1])


def build_network(arch: dict) -> nn.Module:
    """A network from its JSON-able architecture description (see ``architecture`` keys)."""
    kind = arch.get("kind", "mlp")
    common = dict(in_dim=int(arch["in_dim"]), out_dim=int(arch["out_dim"]), hidden=tuple(arch["hidden"]),
                  activation=arch.get("activation", "relu"))
    if kind == "mlp":
        return MLP(**common)
    if kind == "per_joint":
        return PerJointMLP(**common)
    if kind == "lstm":
        return LSTMRegressor(window=int(arch["window"]), **common)
    raise SensorlessError(f"unknown network kind '{kind}' (mlp, per_joint, lstm)")


@dataclass
class TrainConfig:
    """Training hyper-parameters (all stored with the model)."""

    epochs: int = 200
    batch_size: int = 256
    lr: float = 1e-3
    weight_decay: float = 0.0
    val_fraction: float = 0.2
    val_blocks: int = 20
    patience: int = 20
    lr_patience: int = 6
    lr_factor: float = 0.5
    min_lr: float = 1e-5
    seed: int = 0
    num_threads: int = 1
    deterministic: bool = True

    def to_dict(self) -> dict:
        return asdict(self)


@contextlib.contextmanager
def deterministic_torch(seed: int | None, num_threads: int = 1, deterministic: bool = True) -> Iterator[None]:
    """Seed torch (``seed=None``: no seeding), fix its thread count and request deterministic
    kernels; the global RNG state, thread count and determinism flag are restored on exit."""
    prev_threads = torch.get_num_threads()
    prev_det = torch.are_deterministic_algorithms_enabled()
    prev_warn = torch.is_deterministic_algorithms_warn_only_enabled()
    with torch.random.fork_rng(devices=[]):
        if seed is not None:
            torch.manual_seed(seed)
        torch.set_num_threads(max(1, int(num_threads)))
        if deterministic:
            torch.use_deterministic_algorithms(True, warn_only=True)
        try:
            yield
        finally:
            torch.set_num_threads(prev_threads)
            torch.use_deterministic_algorithms(prev_det, warn_only=prev_warn)


def _validation_mask(n: int, cfg: TrainConfig, rng: np.random.Generator) -> np.ndarray:
    mask = np.zeros(n, dtype=bool)
    if cfg.val_fraction <= 0:
        return mask
    blocks = np.array_split(np.arange(n), max(2, min(cfg.val_blocks, n // 2)))
    k = max(1, int(round(cfg.val_fraction * len(blocks))))
    for b in rng.choice(len(blocks), size=k, replace=False):
        mask[blocks[b]] = True
    return mask


def train_network(net: nn.Module, X: np.ndarray, Y: np.ndarray, cfg: TrainConfig,
                  validation: tuple[np.ndarray, np.ndarray] | None = None) -> dict:
    """Fit ``net`` to standardised (X, Y) in place; return the training history.

    ``validation`` = (X_val, Y_val), standardised alike (e.g. another trajectory), replaces the
    block split of ``X`` for early stopping: every sample of ``X`` is then trained on.
    Call inside :func:`deterministic_torch` (and build ``net`` there) for reproducible weights.
    """
    X = np.asarray(X, dtype=np.float32)
    Y = np.asarray(Y, dtype=np.float32)
    if X.shape[0] != Y.shape[0]:
        raise DataError(f"features have {X.shape[0]} samples, targets {Y.shape[0]}")
    if X.shape[0] < 4:
        raise DataError(f"too few samples to train a network ({X.shape[0]})")
    rng = np.random.default_rng(cfg.seed)
    if validation is None:
        val = _validation_mask(X.shape[0], cfg, rng)
        Xt, Yt = torch.from_numpy(X[~val]), torch.from_numpy(Y[~val])
        Xv, Yv = torch.from_numpy(X[val]), torch.from_numpy(Y[val])
    else:
        Xt, Yt = torch.from_numpy(X), torch.from_numpy(Y)
        Xv, Yv = (torch.from_numpy(np.asarray(a, dtype=np.float32)) for a in validation)
    opt = torch.optim.Adam(net.parameters(), lr=cfg.lr, weight_decay=cfg.weight_decay)
    sched = torch.optim.lr_scheduler.ReduceLROnPlateau(opt, factor=cfg.lr_factor, patience=cfg.lr_patience, min_lr=cfg.min_lr)
    gen = torch.Generator().manual_seed(cfg.seed)
    loss_fn = nn.MSELoss()
    best, best_state, since = np.inf, copy.deepcopy(net.state_dict()), 0
    hist: dict = {"train_loss": [], "val_loss": [], "lr": []}
    t0 = time.perf_counter()
    n = Xt.shape[0]
    for epoch in range(cfg.epochs):
        net.train()
        perm = torch.randperm(n, generator=gen)
        total = 0.0
        for s in range(0, n, cfg.batch_size):
            idx = perm[s : s + cfg.batch_size]
            opt.zero_grad()
            loss = loss_fn(net(Xt[idx]), Yt[idx])
            loss.backward()
            opt.step()
            total += loss.item() * len(idx)
        net.eval()
        with torch.no_grad():
            vloss = float(loss_fn(net(Xv), Yv)) if len(Xv) else total / n
        hist["train_loss"].append(total / n)
        hist["val_loss"].append(vloss)
        hist["lr"].append(opt.param_groups[0]["lr"])
        sched.step(vloss)
        if not np.isfinite(best) or vloss < best - 1e-7 * abs(best):
            best, best_state, since = vloss, copy.deepcopy(net.state_dict()), 0
            hist["best_epoch"] = epoch
        else:
            since += 1
            if since >= cfg.patience:
                break
    net.load_state_dict(best_state)
    net.eval()
    hist.update(best_val_loss=float(best), epochs_run=epoch + 1, stopped_early=epoch + 1 < cfg.epochs,
                seconds=time.perf_counter() - t0, n_train=int(n), n_val=int(len(Xv)))
    return hist


def predict_network(net: nn.Module, X: np.ndarray, batch: int = 65536) -> np.ndarray:
    """Evaluate ``net`` on standardised features (no grad, batched), float64 output."""
    net.eval()
    out = []
    with torch.no_grad():
        for s in range(0, X.shape[0], batch):
            out.append(net(torch.from_numpy(np.asarray(X[s : s + batch], dtype=np.float32))).numpy())
    return np.concatenate(out).astype(float) if out else np.zeros((0, 0))
