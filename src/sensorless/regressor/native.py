"""Optional compiled kernel: Pinocchio's joint-torque regressor over a chunk of samples.

The pure-Python path calls ``pin.computeJointTorqueRegressor`` once per sample and copies the
result into the chunk buffer; the binding overhead is about 40 % of the call on a UR5. The kernel
(``native_kernel.cpp``) runs the same C++ function over a whole chunk straight into the buffer,
without the GIL (ctypes releases it), optionally on several threads. It is built against the
Pinocchio and Eigen headers of the installed wheels (``pin``, ``cmeel-eigen``) by

    python -m sensorless.regressor.native_build      # the Makefile runs it after installing

into ``_native/`` next to this file (or ``~/.cache/sensorless`` when that is read-only). When it is
missing, cannot be built, or a model has a joint type it does not know, everything falls back to
the Python loop with the same results. A model is accepted only after its kernel regressor equals
Pinocchio's Python one on random states (relative 1e-12). ``SENSORLESS_NATIVE=0`` turns it off;
``SENSORLESS_NATIVE_THREADS`` sets its threads (default 1: the fold already runs beside it).
The same library holds the momentum observer's compiled step (``observer_kernel.cpp``,
:mod:`sensorless.estimation.native_observer`), which starts from :func:`tree_model`, and the
batched contact null-space projector (``native_contact.cpp``, used by
:func:`~.contact_kinematics.null_space_projector` through :func:`contact_projector`) and the candidate
friction columns of the law search (``native_friction.cpp``, used by
:meth:`~sensorless.identification.stribeck.StribeckCandidates.joint_features` through :func:`friction_candidates`).
"""

from __future__ import annotations

import ctypes
import functools
import os
import subprocess
import sys
from pathlib import Path

import numpy as np

__all__ = ["NativeRegressor", "available", "build", "contact_projector", "friction_candidates", "library", "library_path", "native_regressor",
           "threads", "tree_model", "unavailable_reason"]

#: the kernel's sources, one library: regressor, observer step, contact projector, friction candidates
_SOURCES = tuple(Path(__file__).with_name(n) for n in ("native_kernel.cpp", "observer_kernel.cpp", "native_contact.cpp",
                                                      "native_friction.cpp"))
_LIB_NAME = "libsensorless_regressor.so"
#: Pinocchio joint model → (kernel type code, fixed unit axis or None) (native_kernel.cpp): an axis-aligned
#: joint is passed as its unaligned form
_E = np.eye(3)
JOINT_CODES = {
    "JointModelRX": (0, _E[0]), "JointModelRY": (0, _E[1]), "JointModelRZ": (0, _E[2]),
    "JointModelRevoluteUnaligned": (0, None),
    "JointModelRUBX": (1, _E[0]), "JointModelRUBY": (1, _E[1]), "JointModelRUBZ": (1, _E[2]),
    "JointModelRevoluteUnboundedUnaligned": (1, None),
    "JointModelPX": (2, _E[0]), "JointModelPY": (2, _E[1]), "JointModelPZ": (2, _E[2]),
    "JointModelPrismaticUnaligned": (2, None),
    "JointModelFreeFlyer": (3, None), "JointModelSpherical": (4, None), "JointModelTranslation": (5, None),
    "JointModelPlanar": (6, None),
}
# Pinocchio's own compile definitions (its CMake targets): the joint variant has more than 20 types
_DEFINES = ["NDEBUG", "BOOST_MPL_LIMIT_LIST_SIZE=30", "BOOST_MPL_LIMIT_VECTOR_SIZE=30",
            "BOOST_MPL_CFG_NO_PREPROCESSED_HEADERS", "BOOST_FUSION_INVOKE_MAX_ARITY=12",
            "PINOCCHIO_ENABLE_TEMPLATE_INSTANTIATION"]


def _candidates() -> list[Path]:
    return [Path(__file__).with_name("_native") / _LIB_NAME, Path.home() / ".cache" / "sensorless" / _LIB_NAME]


def library_path() -> Path | None:
    """The built kernel, if any."""
    return next((p for p in _candidates() if p.exists()), None)


def _prefix() -> Path:
    """The cmeel prefix of the installed Pinocchio wheel (headers in include/, libraries in lib/)."""
    import pinocchio

    for parent in Path(pinocchio.__file__).resolve().parents:
        if parent.name == "cmeel.prefix":
            return parent
    raise FileNotFoundError("pinocchio is not installed from a cmeel wheel (pip install pin): no headers found")


def build(verbose: bool = False) -> Path:
    """Compile ``native_kernel.cpp`` and ``observer_kernel.cpp`` (g++ or $CXX, C++17). Returns the library path; raises
    RuntimeError with the compiler output on failure."""
    prefix = _prefix()
    include = prefix / "include"
    eigen = include / "eigen3"
    if not (include / "pinocchio").is_dir() or not eigen.is_dir():
        raise RuntimeError(f"Pinocchio or Eigen headers missing under {include} (pip install pin cmeel-eigen)")
    cxx = os.environ.get("CXX", "g++")
    errors = []
    for target in _candidates():
        try:
            target.parent.mkdir(parents=True, exist_ok=True)
        except OSError as exc:
            errors.append(f"{target.parent}: {exc}")
            continue
        tmp = target.with_suffix(f".{os.getpid()}.tmp")
        cmd = [cxx, "-O3", "-std=c++17", "-shared", "-fPIC", *(f"-D{d}" for d in _DEFINES), f"-I{include}",
               f"-I{eigen}", *map(str, _SOURCES), "-o", str(tmp), f"-L{prefix / 'lib'}", "-lpinocchio_default",
               f"-Wl,-rpath,{prefix / 'lib'}", "-pthread"]
        if verbose:
            print(" ".join(cmd), file=sys.stderr)
        try:
            res = subprocess.run(cmd, capture_output=True, text=True)
        except OSError as exc:
            raise RuntimeError(f"cannot run the C++ compiler '{cxx}': {exc}") from None
        if res.returncode != 0:
            tmp.unlink(missing_ok=True)
            raise RuntimeError(f"compiling {', '.join(p.name for p in _SOURCES)} failed:\n{res.stderr[-4000:]}")
        os.replace(tmp, target)
        _lib.cache_clear()
        return target
    raise RuntimeError("no writable place for the kernel: " + "; ".join(errors))


@functools.lru_cache(maxsize=None)
def _lib():
    path = library_path()
    if path is None or os.environ.get("SENSORLESS_NATIVE", "1") == "0":
        return None
    try:
        lib = ctypes.CDLL(str(path))
    except OSError:
        return None
    p, i = ctypes.c_void_p, ctypes.c_int
    lib.slr_model_new.restype = p
    lib.slr_model_new.argtypes = [i, p, p, p, p]
    lib.slr_model_free.argtypes = [p]
    lib.slr_regressor.restype = i
    lib.slr_regressor.argtypes = [p, i, p, p, p, i, p, p, i]
    if hasattr(lib, "slr_regressor_strided"):  # absent from a library built before it existed
        lib.slr_regressor_strided.restype = i
        lib.slr_regressor_strided.argtypes = [p, i, p, p, p, i, p, p, ctypes.c_long, ctypes.c_long, i]
    if hasattr(lib, "slr_null_space_projector"):  # absent from a library built before it existed
        d = ctypes.c_double
        lib.slr_null_space_projector.restype = None
        lib.slr_null_space_projector.argtypes = [ctypes.c_long, i, i, p, d, d, p, p]
    if hasattr(lib, "slr_friction_candidates"):
        L = ctypes.c_long
        lib.slr_friction_candidates.restype = None
        lib.slr_friction_candidates.argtypes = [L, i, p, p, p, i, p, i, p, p, L, L]
    return lib


def library() -> "ctypes.CDLL | None":
    """The loaded kernel (None when it is not built, cannot be loaded or ``SENSORLESS_NATIVE=0``); other
    modules declare the signatures of the functions they call (e.g. the observer step)."""
    return _lib()


def available() -> bool:
    """True when the kernel is built and enabled."""
    return _lib() is not None


class NativeRegressor:
    """The kernel's copy of a Pinocchio model (its kinematic tree): :meth:`__call__` fills
    ``out[i] = Y(Q[i], V[i], A[i])[rows]``. Build it with :func:`native_regressor`."""

    @property
    def strided(self) -> bool:
        """True when ``out`` may be any view whose last axis is contiguous (else it must be C-contiguous)."""
        return hasattr(self._lib, "slr_regressor_strided")

    def __init__(self, lib, handle: int, nq: int, nv: int, n_body_params: int):
        self._lib, self._handle = lib, handle
        self.nq, self.nv, self.n_body_params = nq, nv, n_body_params

    def __del__(self):
        if getattr(self, "_handle", None):
            self._lib.slr_model_free(self._handle)
            self._handle = None

    def __call__(self, Q: np.ndarray, V: np.ndarray, A: np.ndarray, rows: np.ndarray, out: np.ndarray,
                 threads: int = 1) -> np.ndarray:
        Q, V, A = (np.ascontiguousarray(x, dtype=float) for x in (Q, V, A))
        rows = np.ascontiguousarray(rows, dtype=np.int32)
        n = Q.shape[0]
        e = out.itemsize
        layout = out.flags.c_contiguous or (self.strided and out.ndim == 3 and out.strides[2] == e
                                            and out.strides[0] % e == 0 and out.strides[1] % e == 0)
        if not (Q.shape == (n, self.nq) and V.shape == A.shape == (n, self.nv)
                and out.shape == (n, rows.size, self.n_body_params) and layout and out.dtype == np.float64):
            raise ValueError(f"native regressor: shape or layout mismatch (Q {Q.shape}, V {V.shape}, A {A.shape}, "
                             f"rows {rows.size}, out {out.shape} {out.dtype} strides {out.strides}; "
                             f"model nq {self.nq}, nv {self.nv}, {self.n_body_params} body parameters)")
        if out.flags.c_contiguous:
            self._lib.slr_regressor(self._handle, n, Q.ctypes.data, V.ctypes.data, A.ctypes.data, rows.size,
                                    rows.ctypes.data, out.ctypes.data, int(threads))
        else:
            self._lib.slr_regressor_strided(self._handle, n, Q.ctypes.data, V.ctypes.data, A.ctypes.data, rows.size,
                                            rows.ctypes.data, out.ctypes.data, out.strides[0] // e,
                                            out.strides[1] // e, int(threads))
        return out


_MODELS: dict[int, tuple[object, "NativeRegressor | None"]] = {}


def native_regressor(model) -> "NativeRegressor | None":
    """The kernel for a ``pin.Model`` (cached per model object), or None when the kernel is not
    available, the model has a joint type the kernel lacks, or its regressor differs from Pinocchio's."""
    lib = _lib()
    if lib is None:
        return None
    hit = _MODELS.get(id(model))
    if hit is not None and hit[0] is model:
        return hit[1]
    reg = _make(lib, model)
    _MODELS[id(model)] = (model, reg)  # the model is kept alive, so its id is not reused
    return reg


def tree_model(model) -> "int | str":
    """The kernel's copy of the kinematic tree of a ``pin.Model`` (a handle the caller owns: the
    observer kernel takes it over), or the reason it cannot be made (a joint type the kernel lacks)."""
    lib = _lib()
    if lib is None:
        return unavailable_reason()
    n = model.njoints - 1
    try:
        kinds = [JOINT_CODES[model.joints[j].shortname()] for j in range(1, model.njoints)]
    except KeyError:
        bad = sorted({model.joints[j].shortname() for j in range(1, model.njoints)} - set(JOINT_CODES))
        return f"the kernel has no joint type {', '.join(bad)}"
    codes = np.array([c for c, _ in kinds], dtype=np.int32)
    parents = np.array([model.parents[j] for j in range(1, model.njoints)], dtype=np.int32)
    placements = np.array([np.concatenate([model.jointPlacements[j].rotation.ravel(), model.jointPlacements[j].translation])
                           for j in range(1, model.njoints)]).reshape(n, 12)
    axes = np.zeros((n, 3))
    for k, (j, (_, fixed)) in enumerate(zip(range(1, model.njoints), kinds)):
        axis = fixed if fixed is not None else getattr(model.joints[j].extract(), "axis", None)
        if axis is not None:
            axes[k] = np.asarray(axis, dtype=float).ravel()[:3]
    placements, axes = np.ascontiguousarray(placements), np.ascontiguousarray(axes)
    handle = lib.slr_model_new(n, codes.ctypes.data, parents.ctypes.data, placements.ctypes.data, axes.ctypes.data)
    return handle or "the kernel could not rebuild the kinematic tree"


def unavailable_reason() -> str:
    """Why :func:`library` is None (or "" when the kernel is loaded)."""
    if os.environ.get("SENSORLESS_NATIVE", "1") == "0":
        return "the C++ kernel is turned off (SENSORLESS_NATIVE=0)"
    if library_path() is None:
        return "the C++ kernel is not built (python -m sensorless.regressor.native_build)"
    return "" if _lib() is not None else f"the C++ kernel {library_path()} cannot be loaded"


def _make(lib, model) -> "NativeRegressor | None":
    import pinocchio as pin

    n = model.njoints - 1
    handle = tree_model(model)
    if isinstance(handle, str):
        return None
    reg = NativeRegressor(lib, handle, model.nq, model.nv, 10 * n)
    # accepted only if it reproduces Pinocchio's Python regressor
    rng = np.random.default_rng(0)
    data = model.createData()
    lo = np.where(np.isfinite(model.lowerPositionLimit), model.lowerPositionLimit, -1.0)
    hi = np.where(np.isfinite(model.upperPositionLimit), model.upperPositionLimit, 1.0)
    Q = np.array([pin.randomConfiguration(model, np.minimum(lo, hi), np.maximum(lo, hi)) for _ in range(3)])
    V, A = rng.standard_normal((3, model.nv)), rng.standard_normal((3, model.nv))
    ref = np.array([pin.computeJointTorqueRegressor(model, data, Q[i], V[i], A[i]) for i in range(3)])
    out = np.empty((3, model.nv, 10 * n))
    reg(Q, V, A, np.arange(model.nv), out)
    if not np.allclose(out, ref, rtol=1e-12, atol=1e-12 * max(np.abs(ref).max(), 1.0)):
        return None
    return reg


def contact_projector():
    """The kernel's batched projector ``f(n, m, nv, J, rcond, max_cond, P, ok)`` (``native_contact.cpp``),
    or None when the kernel is not built, disabled, or built before the projector was added."""
    lib = _lib()
    return getattr(lib, "slr_null_space_projector", None) if lib is not None else None


def friction_candidates(v: np.ndarray, t_mask: np.ndarray, d_sign: np.ndarray, widths: np.ndarray, vs: np.ndarray,
                        out: np.ndarray) -> bool:
    """The candidate columns of ``native_friction.cpp`` into ``out`` (n, joints, G_w + G_s), any strides
    whose last is one element: [tanh(v/w_g)·t_mask | expm1(−(v/vs_h)²)·d_sign] for velocities, masks
    (n, joints) and per-joint ``widths`` (joints, G_w), ``vs`` (joints, G_s). False (``out`` untouched)
    when the kernel is not built, disabled, or built before this function was added."""
    lib = _lib()
    fn = getattr(lib, "slr_friction_candidates", None) if lib is not None else None
    if fn is None:
        return False
    n, J = v.shape
    Gw, Gs = widths.shape[1], vs.shape[1]
    v, t_mask, d_sign, widths, vs = (np.ascontiguousarray(x, dtype=float) for x in (v, t_mask, d_sign, widths, vs))
    e = out.itemsize
    if not (out.dtype == np.float64 and out.shape == (n, J, Gw + Gs) and out.strides[2] == e
            and t_mask.shape == d_sign.shape == (n, J) and widths.shape[0] == vs.shape[0] == J
            and out.strides[0] % e == 0 and out.strides[1] % e == 0):
        raise ValueError(f"native friction candidates: shape or layout mismatch (v {v.shape}, out {out.shape} "
                         f"strides {out.strides}, widths {widths.shape}, vs {vs.shape})")
    fn(n, J, v.ctypes.data, t_mask.ctypes.data, d_sign.ctypes.data, Gw, widths.ctypes.data, Gs, vs.ctypes.data,
       out.ctypes.data, out.strides[0] // e, out.strides[1] // e)
    return True


def threads() -> int:
    """Kernel threads (``SENSORLESS_NATIVE_THREADS``, default 1)."""
    try:
        return max(1, int(os.environ.get("SENSORLESS_NATIVE_THREADS", "1")))
    except ValueError:
        return 1
