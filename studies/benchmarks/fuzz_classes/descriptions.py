"""Class ``descriptions``: hostile robot descriptions loaded with ``sensorless.robot.load_robot`` (no trust).

xacro files with code-execution payloads (a ``${...}`` sandbox escape through
``python.vars(python.type)['__subclasses__']``, ``$(eval exec("import os; os.system(...)", {}))`` and ``$(eval open(...))``), includes of the
planted secret, ``${9**9**9}`` and exponential macros; URDFs whose mesh paths escape
(``../..``, absolute, ``package://``) to the secret; MJCF ``<include file=secret>``; entity
bombs; random mutations of tests/data/two_link.urdf (and an MJCF twin) with negative, NaN and
huge masses and inertias or missing tags. ``executed``: the payload's marker file exists;
``disclosure``: the secret is in the error, a warning, the loaded model's names or its expanded
URDF; ``garbage``: a negative/NaN mass or inertia accepted without a warning.
"""

from __future__ import annotations

import math
import warnings
from pathlib import Path

from .common import TWO_LINK, leaked, one_line, plant_secret

ROBOT = '<robot name="evil" xmlns:xacro="http://www.ros.org/wiki/xacro">{}</robot>'
BODY = TWO_LINK.split("<robot name=\"two\">", 1)[1].rsplit("</robot>", 1)[0]


def _xacro_payload(kind: str, marker: Path, secret: Path) -> str:
    cmd = f"touch {marker}"
    obj = "python.type.mro(python.int)[-1]"  # object, without a dunder name
    ga = f"python.vars({obj})['__getattribute__']"
    if kind == "subclasses":  # the ${...} sandbox escape: object.__subclasses__ → os._wrap_close → os.system
        expr = (f"[{ga}(python.vars(c)['__init__'], '__globals__')['system']('{cmd}') "
                f"for c in python.vars(python.type)['__subclasses__']({obj}) "
                f"if {ga}(c, '__name__') == '_wrap_close'][0] and 'l0' or 'l0'")
        return ROBOT.format(f'<link name="${{{expr}}}"/>{BODY}')
    rp = '<xacro:property name="rp" value=")"/>'  # $(eval ...) ends at the first ")": spell it ${rp}
    if kind == "eval_import":
        return ROBOT.format(rp + f'<link name="$(eval exec(&quot;import os; os.system(&apos;{cmd}&apos;${{rp}}&quot;, {{}}${{rp}} '
                            f"or 'l0')\"/>{BODY}")
    if kind == "eval_open":
        return ROBOT.format(rp + f"<link name=\"$(eval open('{marker}', 'w'${{rp}}.write('x'${{rp}} and 'l0')\"/>{BODY}")
    if kind == "read_secret":
        return ROBOT.format(rp + f"<link name=\"$(eval open('{secret}'${{rp}}.read(${{rp}}.split(':'${{rp}}[0])\"/>{BODY}")
    if kind == "include_secret":
        return ROBOT.format(f'<xacro:include filename="{secret}"/>{BODY}')
    if kind == "env":
        return ROBOT.format(f'<link name="$(env FUZZ_SECRET)"/>{BODY}')
    if kind == "bigpow":
        return ROBOT.format(f'<xacro:property name="x" value="${{9**9**9}}"/>{BODY}')
    if kind == "macros":  # 2**40 expansions
        defs = '<xacro:macro name="m0"><link name="x"/></xacro:macro>' + "".join(
            f'<xacro:macro name="m{i}"><xacro:m{i - 1}/><xacro:m{i - 1}/></xacro:macro>' for i in range(1, 41))
        return ROBOT.format(defs + "<xacro:m40/>" + BODY)
    raise ValueError(kind)


def _mesh(path: str) -> str:
    vis = f'<visual><geometry><mesh filename="{path}"/></geometry></visual>'
    return TWO_LINK.replace('<link name="l2">', f'<link name="l2">{vis}<collision><geometry><mesh filename="{path}"/>'
                            "</geometry></collision>")


ENTITY_BOMB = ('<?xml version="1.0"?><!DOCTYPE r [<!ENTITY a "aaaaaaaaaa">' + "".join(
    f'<!ENTITY {chr(98 + i)} "{("&" + chr(97 + i) + ";") * 10}">' for i in range(9)) + ']><robot name="&j;">'
    + BODY + "</robot>")


def mjcf(mass1="2", mass2="1", inertia="0.02 0.02 0.005", extra="") -> str:
    return (f'<mujoco model="two">{extra}<worldbody><body name="l1"><joint name="j1" type="hinge" axis="0 1 0"/>'
            f'<inertial pos="0 0 0.2" mass="{mass1}" diaginertia="{inertia}"/>'
            f'<body name="l2" pos="0 0 0.4"><joint name="j2" type="hinge" axis="0 1 0"/>'
            f'<inertial pos="0.15 0 0" mass="{mass2}" diaginertia="0.004 0.01 0.01"/></body></body></worldbody></mujoco>')


BAD_NUMBERS = ["-50", "-1e-9", "nan", "NaN", "inf", "-inf", "1e150", "1e308", "0", "abc", "", "1e-300", "-0"]


def _mutate_urdf(rng, text: str) -> tuple[str, bool]:
    """(mutated URDF, True when it declares an impossible inertial the loader must not accept silently)."""
    bad = False
    for _ in range(int(rng.integers(1, 4))):
        op = int(rng.integers(6))
        if op == 0:  # a mass
            val = str(rng.choice(BAD_NUMBERS))
            text = text.replace('mass value="2"', f'mass value="{val}"', 1)
            bad |= val in ("-50", "-1e-9", "nan", "NaN", "inf", "-inf")
        elif op == 1:  # an inertia entry
            key = str(rng.choice(["ixx", "iyy", "izz", "ixy"]))
            val = str(rng.choice(BAD_NUMBERS))
            text = text.replace(f'{key}="0.0', f'{key}="{val}', 1) if f'{key}="0.0' in text else text
            bad |= val in ("-50", "nan", "NaN", "inf", "-inf") and key != "ixy"
        elif op == 2:  # drop a tag
            tag = str(rng.choice(["<inertial>", "<mass ", "<axis ", "<parent ", "<child ", "<limit "]))
            i = text.find(tag)
            if i >= 0:
                j = text.find(">", i) if not tag.endswith(">") else text.find("</inertial>", i) + len("</inertial>") - 1
                text = text[:i] + text[j + 1:]
        elif op == 3:  # truncate
            text = text[: int(rng.integers(0, len(text)))]
        elif op == 4:  # a huge or odd number in an origin / limit
            text = text.replace('xyz="0 0 0.4"', f'xyz="0 0 {rng.choice(BAD_NUMBERS)}"', 1)
        else:  # flip characters
            chars = list(text)
            for k in rng.integers(0, len(chars), size=int(rng.integers(1, 6))):
                chars[int(k)] = chr(int(rng.integers(32, 127)))
            text = "".join(chars)
    return text, bad and _declares_impossible(text)


def _declares_impossible(text: str) -> bool:
    """Whether the final text still holds a negative (< −1e-9) or non-finite mass or diagonal inertia
    (a later mutation may have dropped the tag an earlier one broke)."""
    import re

    for m in re.finditer(r'\b(mass value|ixx|iyy|izz)="([^"]*)"', text):
        try:
            v = float(m.group(2))
        except ValueError:
            continue  # not a number at all: the loader's parse error, not an impossible value
        if not math.isfinite(v) or v < -1e-9:
            return True
    return False


def make(rng, d: Path, secret: Path, marker: Path) -> tuple[Path, bool]:
    """A hostile or mutated robot file in ``d``; (path, declares an impossible inertial)."""
    u = rng.random()
    if u < 0.35:
        kind = str(rng.choice(["subclasses", "eval_import", "eval_open", "read_secret", "include_secret", "env",
                               "bigpow", "macros"], p=[.2, .2, .15, .12, .1, .1, .05, .08]))
        f = d / f"evil_{kind}.urdf.xacro"
        f.write_text(_xacro_payload(kind, marker, secret))
        return f, False
    if u < 0.5:
        where = str(rng.choice([f"../../../../../..{secret}", str(secret), f"file://{secret}", "package://evil/../../"
                                + str(secret).lstrip("/"), f"package://{secret.parent.name}/{secret.name}"]))
        f = d / "mesh.urdf"
        f.write_text(_mesh(where))
        return f, False
    if u < 0.6:
        f = d / "inc.xml"
        f.write_text(str(rng.choice([mjcf(extra=f'<include file="{secret}"/>'),
                                     mjcf(extra=f'<include file="../../../../..{secret}"/>'),
                                     mjcf(extra=f'<asset><mesh name="m" file="{secret}"/></asset>')])))
        return f, False
    if u < 0.65:
        f = d / "bomb.urdf"
        f.write_text(ENTITY_BOMB if rng.random() < 0.7 else
                     f'<?xml version="1.0"?><!DOCTYPE r [<!ENTITY x SYSTEM "file://{secret}">]><robot name="&x;">{BODY}</robot>')
        return f, False
    if u < 0.8:
        m1, m2 = str(rng.choice(BAD_NUMBERS + ["2"])), str(rng.choice(["1", "-50", "1e150"]))
        inertia = str(rng.choice(["0.02 0.02 0.005", "-1 0.02 0.005", "nan 1 1", "1e300 1 1"]))
        f = d / "two.xml"
        f.write_text(mjcf(m1, m2, inertia))
        impossible = m1 in ("-50", "-1e-9", "nan", "NaN", "inf", "-inf") or m2 == "-50" or inertia[:2] in ("-1", "na")
        return f, impossible
    text, bad = _mutate_urdf(rng, TWO_LINK)
    f = d / "mut.urdf"
    f.write_text(text)
    return f, bad


def setup(d: Path, scale: float) -> dict:
    import os

    secret, s = plant_secret(d)
    os.environ["FUZZ_SECRET"] = s
    os.environ["XDG_CACHE_HOME"] = str(d / "cache")  # the xacro cache stays in the worker's folder
    return {"secret": secret, "s": s}


def case(rng, d: Path, ctx: dict) -> tuple[str, str]:
    from sensorless.errors import SensorlessError
    from sensorless.robot import load_robot

    import shutil

    shutil.rmtree(d / "cache", ignore_errors=True)
    case_dir = d / "case"
    case_dir.mkdir()
    marker = case_dir / "EXECUTED"
    f, impossible = make(rng, case_dir, ctx["secret"], marker)
    texts, files, outcome, msg = [], [], "ok", ""
    try:
        with warnings.catch_warnings(record=True) as caught:
            warnings.simplefilter("always")
            robot = load_robot(f)
        texts += [str(w.message) for w in caught]
        texts += [robot.name, " ".join(robot.model.names), " ".join(fr.name for fr in robot.model.frames)]
        if getattr(robot, "urdf_path", None):
            files.append(robot.urdf_path)
        masses = [robot.model.inertias[i].mass for i in range(1, robot.model.njoints)]
        if (impossible or not all(m == m and 0 <= m < 1e6 for m in masses)) and not caught:
            outcome, msg = "garbage", f"descriptions/{f.name}: loaded impossible inertials (masses {masses}) silently"
    except SensorlessError as exc:
        outcome = "typed"
        texts.append(str(exc))
    except Exception as exc:  # noqa: BLE001
        outcome, msg = "generic", f"descriptions/{f.name}: {type(exc).__name__}: {one_line(exc)}"
        texts.append(str(exc))
    cache = d / "cache"
    if marker.exists():
        return "executed", f"descriptions/{f.name}: the payload ran (marker written)"
    if leaked(ctx["s"], *texts, files=[*files, *([cache] if cache.exists() else [])]):
        return "disclosure", f"descriptions/{f.name}: the planted secret appears in the model or its messages"
    return outcome, msg
