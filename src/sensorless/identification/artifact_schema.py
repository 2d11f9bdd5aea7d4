"""The schema of a model folder's ``result.json``: typed checks that name the key path.

Every check raises :class:`~sensorless.errors.ParameterError` as one line,
``result.json: settings.preprocessing.rate: expected a number, got a string``; a message
shows at most a short summary of the offending value (its type, a number, or the first
characters of a short string), never a file's content. :mod:`.artifact` applies them.
"""

from __future__ import annotations

import math
import os
from pathlib import Path
from typing import Any, Mapping

from ..data.angles import ANGLE_UNITS
from ..errors import ParameterError

__all__ = ["Checker", "summary", "check_friction_law", "check_preprocessing_settings", "check_robot_settings",
           "check_structure_settings",
           "check_verdicts"]

#: bounds of the stored preprocessing (outside them no log can be processed sensibly)
MIN_RATE, MAX_RATE = 1e-3, 1e6
MIN_LOWPASS = 1e-3
MAX_SAVGOL_WINDOW = 10_001
MAX_DECIMATE = 100_000
MAX_GAP = 1e6
MIN_GAIN, MAX_GAIN = 1e-6, 1e5
MAX_SMOOTHING = 1e3  # [rad/s or m/s]: Coulomb smoothing, Stribeck and rest velocities
TIME_UNITS = ("s", "ms", "us", "ns", "tick")
VELOCITY = ("logged", "from-q")
BASE_VELOCITY = ("auto", "from-pose", "logged")
REST = ("auto", "off")
ROWS = ("actuated", "all")


def summary(value: Any) -> str:
    """A short description of ``value`` for an error: its JSON type, and a number or short string."""
    if value is None:
        return "null"
    if isinstance(value, bool):
        return f"a boolean ({str(value).lower()})"
    if isinstance(value, (int, float)):
        return f"{value:.6g}"
    if isinstance(value, str):
        return f"the string '{value}'" if len(value) <= 24 and value.isprintable() else f"a string of {len(value)} characters"
    if isinstance(value, list):
        return f"a list of {len(value)} item(s)"
    if isinstance(value, dict):
        return f"an object of {len(value)} key(s)"
    return f"a {type(value).__name__}"


class Checker:
    """Typed checks of values at key paths of one file (``src``, e.g. ``/m/result.json``)."""

    def __init__(self, src: str | os.PathLike, folder: Path | None = None) -> None:
        self.src, self.folder = str(src), folder

    def fail(self, key: str, what: str) -> ParameterError:
        return ParameterError(f"{self.src}: {key}: {what}")

    def number(self, key: str, value: Any, lo: float = -math.inf, hi: float = math.inf, *, lo_open: bool = False,
               integer: bool = False) -> float:
        """A finite JSON number (not a boolean, not a string) in [lo, hi] ((lo, hi] with ``lo_open``)."""
        kind = "an integer" if integer else "a number"
        if isinstance(value, bool) or not isinstance(value, (int, float)):
            raise self.fail(key, f"expected {kind}, got {summary(value)}")
        if not math.isfinite(value):
            raise self.fail(key, f"expected a finite number, got {summary(value)}")
        if integer and value != int(value):
            raise self.fail(key, f"expected an integer, got {summary(value)}")
        if value < lo or value > hi or (lo_open and value == lo):
            rng = f"{'(' if lo_open else '['}{lo:g}, {hi:g}]"
            raise self.fail(key, f"{summary(value)} is outside the range {rng}")
        return int(value) if integer else float(value)

    def string(self, key: str, value: Any, choices: tuple[str, ...] | None = None, max_len: int = 4096) -> str:
        if not isinstance(value, str):
            raise self.fail(key, f"expected a string, got {summary(value)}")
        if len(value) > max_len:
            raise self.fail(key, f"a string of {len(value)} characters is longer than {max_len}")
        if choices is not None and value not in choices:
            raise self.fail(key, f"expected one of {', '.join(choices)}, got {summary(value)}")
        return value

    def mapping(self, key: str, value: Any) -> dict:
        if not isinstance(value, dict):
            raise self.fail(key, f"expected an object, got {summary(value)}")
        return value

    def strings(self, key: str, value: Any) -> list[str]:
        if not isinstance(value, list):
            raise self.fail(key, f"expected a list of strings, got {summary(value)}")
        return [self.string(f"{key}[{i}]", v, max_len=256) for i, v in enumerate(value)]

    def per_joint(self, key: str, value: Any, lo: float, hi: float, lo_open: bool = False) -> dict[str, float]:
        """A ``{joint: number}`` object."""
        return {j: self.number(f"{key}.{j}", v, lo, hi, lo_open=lo_open) for j, v in self.mapping(key, value).items()}

    def inside(self, key: str, value: str) -> Path:
        """A path stored in the model: relative, and inside the model folder (never followed elsewhere)."""
        if self.folder is None:
            raise self.fail(key, "a file path is not allowed here")
        p = Path(value)
        if p.is_absolute() or value.startswith("~"):
            raise self.fail(key, "an absolute path is refused (a model refers only to files inside its folder)")
        real, base = Path(os.path.realpath(self.folder / p)), Path(os.path.realpath(self.folder))
        if ".." in p.parts or not (real == base or base in real.parents):
            raise self.fail(key, "a path leading outside the model folder is refused")
        return self.folder / p


# ---- settings.preprocessing -----------------------------------------------------------------
def _columns(c: Checker, key: str, value: Any):
    from ..data.prepare import parse_columns
    from ..data.readers import FIELDS

    if value is None:
        return None
    if isinstance(value, str):  # the command-line form 'q=0:7;tau=14:21'
        try:
            value = parse_columns(c.string(key, value))
        except ValueError:
            raise c.fail(key, "not a column map FIELD=SPEC;FIELD=SPEC") from None
    cols = c.mapping(key, value)
    for field, entry in cols.items():
        k = f"{key}.{field}"
        if field not in FIELDS:
            raise c.fail(k, f"unknown log field (expected one of {', '.join(FIELDS)})")
        items = entry if isinstance(entry, list) else [entry]
        if isinstance(entry, list) and not entry:
            raise c.fail(k, "expected a column name, a column range or a list of them, got an empty list")
        for i, item in enumerate(items):
            where = f"{k}[{i}]" if isinstance(entry, list) else k
            if isinstance(item, bool) or not isinstance(item, (str, int)):
                raise c.fail(where, f"expected a column name or index, got {summary(item)}")
            if isinstance(item, int) and not 0 <= item < 1_000_000:
                raise c.fail(where, f"column index {item} is out of range")
            if isinstance(item, str) and ":gain=" in c.string(where, item, max_len=256):
                raise c.fail(where, "a ':gain=' suffix is not stored in a model's column map "
                                    "(settings.preprocessing.gains holds the gains)")
    return cols


def _gains(c: Checker, key: str, value: Any):
    if value is None:
        return None
    if isinstance(value, (int, float)) and not isinstance(value, bool):
        return _gain(c, key, value)
    if isinstance(value, list):
        if not value:
            raise c.fail(key, "expected gains, got an empty list")
        return [_gain(c, f"{key}[{i}]", v) for i, v in enumerate(value)]
    if isinstance(value, dict):
        return {j: _gain(c, f"{key}.{j}", v) for j, v in value.items()}
    text = c.string(key, value)
    if text.strip().lower() in ("off", "none"):
        return None
    if any(ch in text for ch in "/\\") or Path(text).suffix.lower() in (".json", ".csv", ".txt"):
        return str(c.inside(key, text))  # a gains file: only inside the model folder
    parts = [p.split("=", 1)[-1].strip() for p in text.replace(";", ",").split(",") if p.strip()]
    if not parts:
        raise c.fail(key, "expected gains, got an empty string")
    for i, p in enumerate(parts):
        try:
            _gain(c, f"{key}[{i}]", float(p))
        except ValueError:
            raise c.fail(f"{key}[{i}]", "expected a number") from None
    return text


def _gain(c: Checker, key: str, value: Any) -> float:
    g = c.number(key, value)
    if not MIN_GAIN <= abs(g) <= MAX_GAIN:
        raise c.fail(key, f"drive gain {summary(value)} is implausible (|gain| must be in [{MIN_GAIN:g}, {MAX_GAIN:g}])")
    return g


def _resample(c: Checker, key: str, value: Any):
    if value is None:
        return None
    if isinstance(value, str):
        s = value.strip().lower()
        if s in ("auto", "off", "none", "no", "false"):
            return value
        try:
            rate = float(s.removesuffix("hz"))
        except ValueError:
            raise c.fail(key, f"expected 'auto', 'off' or a rate in Hz, got {summary(value)}") from None
        c.number(key, rate, MIN_RATE, MAX_RATE)
        return value
    return c.number(key, value, MIN_RATE, MAX_RATE)


def _trim(c: Checker, key: str, value: Any):
    if value is None:
        return None
    from ..data.trims import TrimWindow

    if not isinstance(value, (str, list)):
        raise c.fail(key, f"expected a time window 'START:END', got {summary(value)}")
    if isinstance(value, str):
        c.string(key, value, max_len=256)
    try:
        TrimWindow.parse(value)
    except (ValueError, TypeError):
        raise c.fail(key, f"{summary(value)} is not a time window START:END in seconds") from None
    return value


def check_preprocessing_settings(c: Checker, pre: Any, key: str = "settings.preprocessing") -> dict:
    """The validated ``settings.preprocessing`` (missing keys None; a stored gains file resolved in the folder)."""
    if pre is None:
        return {}
    pre = c.mapping(key, pre)
    out = dict(pre)
    k = lambda name: f"{key}.{name}"  # noqa: E731
    opt = lambda name, f: None if pre.get(name) is None else f(k(name), pre[name])  # noqa: E731
    out["columns"] = _columns(c, k("columns"), pre.get("columns"))
    out["gains"] = _gains(c, k("gains"), pre.get("gains"))
    out["rate"] = opt("rate", lambda kk, v: c.number(kk, v, MIN_RATE, MAX_RATE))
    out["resample"] = _resample(c, k("resample"), pre.get("resample"))
    out["lowpass"] = opt("lowpass", lambda kk, v: c.number(kk, v, MIN_LOWPASS, MAX_RATE))
    nyquist = [r / 2 for r in (out["rate"], out["resample"]) if isinstance(r, float)]
    if out["lowpass"] is not None and nyquist and out["lowpass"] >= min(nyquist):
        raise c.fail(k("lowpass"), f"cut-off {out['lowpass']:g} Hz is not below the Nyquist frequency "
                                   f"{min(nyquist):g} Hz of the stored rate")
    out["savgol_window"] = opt("savgol_window", lambda kk, v: c.number(kk, v, 5, MAX_SAVGOL_WINDOW, integer=True))
    if out["savgol_window"] is not None and out["savgol_window"] % 2 == 0:
        raise c.fail(k("savgol_window"), f"expected an odd number of samples, got {out['savgol_window']}")
    out["velocity"] = opt("velocity", lambda kk, v: c.string(kk, v, VELOCITY))
    out["max_gap"] = opt("max_gap", lambda kk, v: c.number(kk, v, 0, MAX_GAP, lo_open=True))
    out["rest"] = opt("rest", lambda kk, v: c.string(kk, v, REST))
    out["time_unit"] = opt("time_unit", lambda kk, v: c.string(kk, v, TIME_UNITS))
    out["base_velocity"] = opt("base_velocity", lambda kk, v: c.string(kk, v, BASE_VELOCITY))
    out["pose_max_gap"] = opt("pose_max_gap", lambda kk, v: c.number(kk, v, 1, MAX_GAP, lo_open=True))
    out["wrench_frames"] = opt("wrench_frames", lambda kk, v: {c.string(f"{kk} key", f, max_len=256):
                                                               c.string(f"{kk}.{f}", s, max_len=256)
                                                               for f, s in c.mapping(kk, v).items()})
    out["angle_unit"] = opt("angle_unit", lambda kk, v: c.string(kk, v, ANGLE_UNITS))
    out["decimate"] = opt("decimate", lambda kk, v: c.number(kk, v, 1, MAX_DECIMATE, integer=True))
    out["trim"] = _trim(c, k("trim"), pre.get("trim"))
    if pre.get("trims") is not None:  # each log's own window (sensorless.data.trims.LogTrims.settings)
        out["trims"] = {log: _trim(c, f"{k('trims')}.{log}", w) for log, w in c.mapping(k("trims"), pre["trims"]).items()}
    return out


# ---- settings.robot (how the robot description was loaded) -----------------------------------
def check_robot_settings(c: Checker, value: Any, key: str = "settings.robot") -> dict:
    """``{"floating_base": bool, "lock": [joint], "passive": [joint], "frames": [[name, parent, xyz, rpy]]}``
    (each key optional; an empty dict for a model written before it existed)."""
    if value is None:
        return {}
    v = c.mapping(key, value)
    out: dict = {}
    if v.get("floating_base") is not None:
        if not isinstance(v["floating_base"], bool):
            raise c.fail(f"{key}.floating_base", f"expected true or false, got {summary(v['floating_base'])}")
        out["floating_base"] = v["floating_base"]
    for name in ("lock", "passive"):
        out[name] = c.strings(f"{key}.{name}", v.get(name, []))
    frames = v.get("frames", [])
    if not isinstance(frames, list) or len(frames) > 1000:
        raise c.fail(f"{key}.frames", f"expected a list of frames, got {summary(frames)}")
    out["frames"] = []
    for i, f in enumerate(frames):
        k = f"{key}.frames[{i}]"
        if not isinstance(f, list) or len(f) != 4:
            raise c.fail(k, f"expected [name, parent, [x, y, z], [r, p, y]], got {summary(f)}")
        name, parent = c.string(f"{k}[0]", f[0], max_len=256), c.string(f"{k}[1]", f[1], max_len=256)
        vecs = []
        for j in (2, 3):
            if not isinstance(f[j], list) or len(f[j]) != 3:
                raise c.fail(f"{k}[{j}]", f"expected 3 numbers, got {summary(f[j])}")
            vecs.append([c.number(f"{k}[{j}][{n}]", x, -1e3, 1e3) for n, x in enumerate(f[j])])
        out["frames"].append([name, parent, *vecs])
    return out


# ---- settings (the model structure) ---------------------------------------------------------
def check_structure_settings(c: Checker, s: Mapping) -> None:
    """Types and ranges of the structure keys of ``settings`` (the constructors check the rest)."""
    from ..regressor.joint_terms import JOINT_TERMS
    from ..regressor.joint_terms.stribeck import FRICTION_LAWS

    if s.get("structure") == "transmission":
        for name in ("coordinates", "tree_joints", "bodies"):
            c.strings(f"settings.{name}", s.get(name))
        rows = s.get("G")
        if not isinstance(rows, list) or not rows or len(rows) > 1000:
            raise c.fail("settings.G", f"expected a matrix (list of rows), got {summary(rows)}")
        for i, row in enumerate(rows):
            if not isinstance(row, list) or len(row) > 1000:
                raise c.fail(f"settings.G[{i}]", f"expected a row of numbers, got {summary(row)}")
            for j, v in enumerate(row):
                c.number(f"settings.G[{i}][{j}]", v, -1e6, 1e6)
        offset = s.get("offset")
        if not isinstance(offset, list):
            raise c.fail("settings.offset", f"expected a list of numbers, got {summary(offset)}")
        for i, v in enumerate(offset):
            c.number(f"settings.offset[{i}]", v, -1e6, 1e6)
        drives = s.get("drives")
        if not isinstance(drives, list) or not all(isinstance(d, dict) for d in drives):
            raise c.fail("settings.drives", f"expected a list of objects, got {summary(drives)}")
        c.number("settings.coulomb_smoothing", s.get("coulomb_smoothing", 0.0), 0, MAX_SMOOTHING)
        return
    terms = c.strings("settings.joint_terms", s.get("joint_terms"))
    for i, t in enumerate(terms):
        if t not in JOINT_TERMS:
            raise c.fail(f"settings.joint_terms[{i}]", f"unknown joint term {summary(t)} "
                                                         f"(expected {', '.join(JOINT_TERMS)})")
    c.number("settings.coulomb_smoothing", s.get("coulomb_smoothing", 0.0), 0, MAX_SMOOTHING)
    if s.get("joint_terms_by_joint") is not None:
        for j, ts in c.mapping("settings.joint_terms_by_joint", s["joint_terms_by_joint"]).items():
            for i, t in enumerate(c.strings(f"settings.joint_terms_by_joint.{j}", ts)):
                if t not in JOINT_TERMS:
                    raise c.fail(f"settings.joint_terms_by_joint.{j}[{i}]", f"unknown joint term {summary(t)}")
    for name, lo_open in (("coulomb_smoothing_by_joint", False), ("stribeck_velocity", True), ("rest_velocity", False)):
        if s.get(name) is not None:
            c.per_joint(f"settings.{name}", s[name], 0, MAX_SMOOTHING, lo_open=lo_open)
    if s.get("friction_law") is not None:
        c.string("settings.friction_law", s["friction_law"], FRICTION_LAWS)
    if s.get("presliding") is not None:  # {joint: {"k": 1/presliding distance > 0, "play": h >= 0}}
        for j, p in c.mapping("settings.presliding", s["presliding"]).items():
            p = c.mapping(f"settings.presliding.{j}", p)
            c.number(f"settings.presliding.{j}.k", p.get("k"), 0, 1e12, lo_open=True)
            c.number(f"settings.presliding.{j}.play", p.get("play", 0.0), 0, 1e3)
    if s.get("rows") is not None:
        c.string("settings.rows", s["rows"], ROWS)
    if s.get("contact_frames"):
        c.strings("settings.contact_frames", s["contact_frames"])
        for i, d in enumerate(s.get("contact_dims") or []):
            c.number(f"settings.contact_dims[{i}]", d, 1, 6, integer=True)
        for name in ("contact_offset", "rcond"):
            if s.get(name) is not None:
                c.number(f"settings.{name}", s[name], -1e3, 1e3)


VERDICTS = ("data", "prior", "undetermined")
#: at most this many joints in a stored kinematic tree
MAX_KINEMATICS_JOINTS = 4096


def check_kinematics(c: Checker, v: Any, key: str = "robot.kinematics") -> dict | None:
    """``robot.kinematics`` (optional; files before it have none), written by
    :func:`~sensorless.robot.kinematics_summary`: ``{"fingerprint": hex, "joints": [[name, type, parent,
    x, y, z, R00 … R22], …]}``."""
    if v is None:
        return None
    v = c.mapping(key, v)
    c.string(f"{key}.fingerprint", v.get("fingerprint"), max_len=64)
    rows = v.get("joints")
    if not isinstance(rows, list) or len(rows) > MAX_KINEMATICS_JOINTS:
        raise c.fail(f"{key}.joints", f"expected a list of at most {MAX_KINEMATICS_JOINTS} joints, got {summary(rows)}")
    for i, row in enumerate(rows):
        k = f"{key}.joints[{i}]"
        if not isinstance(row, list) or len(row) != 15:
            raise c.fail(k, f"expected [name, type, parent, x, y, z, 9 rotation entries], got {summary(row)}")
        for j in range(3):
            c.string(f"{k}[{j}]", row[j], max_len=256)
        for j in range(3, 15):
            c.number(f"{k}[{j}]", row[j], -1e6, 1e6)
    return v


def check_verdicts(c: Checker, v: Any, key: str = "diagnostics.verdicts") -> None:
    """``diagnostics.verdicts`` (optional; files before it have none), written by
    :mod:`~sensorless.identification.verdicts`::

        {"bodies": {body: {quantity: entry}},   # mass, com_x/y/z, ixx, ixy, iyy, ixz, iyz, izz
         "joints": {joint: {term: entry}},       # fv, fc, stribeck, offset, armature
         "robot": {"total_mass": entry},
         "counts": {verdict: number of body masses}, "settings": {...thresholds},
         "active_bounds": {"bodies": {body: [bound]}, "joint_terms_at_zero": [...]}}   # LMI only
        entry = {"value", "prior", "std_data" (null: the data alone cannot determine it),
                 "std_resampled" (blocked jackknife; null: not resampled or unseen by a part),
                 "std" (the larger: the verdict's), "interval" ([lo, hi] at 95 %, or null),
                 "linear_too_narrow" (resampled > 2× linear), "prior_share" (null: no regulariser),
                 "verdict": "data" | "prior" | "undetermined"}
    """
    if v is None:
        return
    c.mapping(key, v)
    for group in ("bodies", "joints"):
        for name, entries in c.mapping(f"{key}.{group}", v.get(group, {})).items():
            for q, e in c.mapping(f"{key}.{group}.{name}", entries).items():
                k = f"{key}.{group}.{name}.{q}"
                c.mapping(k, e)
                c.string(f"{k}.verdict", e.get("verdict"), VERDICTS)
                for s in ("std_data", "std_resampled", "std"):
                    if e.get(s) is not None:
                        c.number(f"{k}.{s}", e[s], 0.0)
                if e.get("prior_share") is not None:
                    c.number(f"{k}.prior_share", e["prior_share"], 0.0, 1.0)


#: bounds of a stored friction law: amplitudes [N·m, N·m·s/rad, kg·m²], k [1/rad], play [rad]
MAX_FRICTION_TERM = 1e6
MAX_PRESLIDING_K = 1e9


def check_friction_law(c: Checker, key: str, d: Any):
    """A friction law of a friction-only model (:class:`~sensorless.regressor.friction_state.FrictionLaw`), checked key by key."""
    from ..regressor.friction_state import LAW_KINDS, LAW_TERMS, FrictionLaw

    d = c.mapping(key, d)
    kind = c.string(f"{key}.kind", d.get("kind"), LAW_KINDS)
    coef = c.mapping(f"{key}.coef", d.get("coef"))
    for t, v in coef.items():
        if t not in LAW_TERMS:
            raise c.fail(f"{key}.coef.{t[:40]}", f"unknown friction term (expected {', '.join(LAW_TERMS)})")
        c.number(f"{key}.coef.{t}", v, -MAX_FRICTION_TERM, MAX_FRICTION_TERM)
    nums = {name: c.number(f"{key}.{name}", d.get(name, 0.0), 0, hi)
            for name, hi in (("eps", MAX_SMOOTHING), ("vs", MAX_SMOOTHING), ("k", MAX_PRESLIDING_K), ("play", 1e3))}
    try:
        return FrictionLaw(kind, dict(coef), **nums)
    except ParameterError as exc:
        raise c.fail(key, str(exc)) from None
