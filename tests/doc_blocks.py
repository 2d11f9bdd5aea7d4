"""Fenced ``bash`` and ``python`` blocks of the docs, and running them as a user would.

A block runs as printed unless the line just above its fence is a directive, a JSON object in an
HTML comment (invisible on GitHub)::

    <!-- doc-test {"quick": [["--seeds 20", "--seeds 2"]], "timeout": 600} -->

- ``quick``: ``[old, new]`` text replacements applied before the test runs it (a slow command
  run with its quick option; the doc shows the full one);
- ``exit``: the expected exit code (default 0; a documented refusal);
- ``timeout``: seconds (default 300);
- ``skip``: the reason the block cannot run here (counted and listed, never silent).

Blocks of one file run in order in one directory, as a user following the page would, and all pages
run in README order in one shared directory, as a user following the guides one after another would
(``journey_files``; every page's output names are its own, ``outputs``): bash with
``set -euo pipefail`` and the environment's ``bin`` first on PATH (an activated venv), Python by
that environment's interpreter. The directory holds copies of ``examples/``, ``studies/benchmarks/`` and
``docs/`` and a link ``../shared`` as beside a clone, so repository-relative paths work and
nothing writes into the repository.
"""

from __future__ import annotations

import json
import os
import re
import shutil
import signal
import subprocess
import sys
import time
from dataclasses import dataclass, field
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]
LANGS = {"bash": "bash", "sh": "bash", "shell": "bash", "python": "python", "py": "python"}
_FENCE = re.compile(r"^(?P<indent>[ ]{0,3})(?P<fence>```+)(?P<lang>[A-Za-z0-9_+-]*)[^\n]*$")
_DIRECTIVE = re.compile(r"^\s*<!--\s*doc-test\s+(?P<json>\{.*\})\s*-->\s*$")


@dataclass
class Block:
    path: Path
    line: int  # 1-based line of the opening fence
    lang: str  # "bash" | "python"
    code: str
    options: dict = field(default_factory=dict)

    @property
    def where(self) -> str:
        return f"{self.path.relative_to(ROOT)}:{self.line}"

    def runnable_code(self) -> str:
        code = self.code
        for old, new in self.options.get("quick", ()):
            if old not in code:
                raise AssertionError(f"{self.where}: doc-test quick text {old!r} is not in the block")
            code = code.replace(old, new)
        return code


def doc_files() -> list[Path]:
    """README.md, docs/*.md and examples/*.md."""
    return [ROOT / "README.md", *sorted((ROOT / "docs").glob("*.md")), *sorted((ROOT / "examples").glob("*.md"))]


def journey_files() -> list[Path]:
    """The pages in the order a user meets them: README.md, then the docs in the order README.md first
    links them, then the other pages (``doc_files`` order)."""
    readme = (ROOT / "README.md").read_text(encoding="utf-8")
    rest = doc_files()[1:]
    first = {p: readme.find(str(p.relative_to(ROOT))) for p in rest}
    linked = sorted((p for p in rest if first[p] >= 0), key=first.get)
    return [ROOT / "README.md", *linked, *(p for p in rest if first[p] < 0)]


_OUT = (re.compile(r"--out[ =]['\"]?([^\s'\";]+)"),                        # any command's output option
        re.compile(r"(?<![<0-9&])[12]?>\s*([A-Za-z0-9_.][^\s;|&)]*)"),      # a shell redirection to a file
        re.compile(r"\.(?:save|savez|savez_compressed|to_feather|to_parquet|savetxt)\(\s*f?['\"]([^'\"{]+)"),
        re.compile(r"write_npz\([^\n]*,\s*['\"]([^'\"]+)['\"]\)"))


def outputs(block: Block) -> set[str]:
    """The top-level names (file or folder, relative to the page's directory) ``block`` writes to:
    ``--out``, shell redirections, ``save``/``savez``/``write_npz`` calls."""
    code = block.runnable_code()
    patterns = _OUT
    if block.lang == "bash":
        code = re.sub(r"<<-?'?(\w+)'?\n.*?\n\1\n", "\n", code, flags=re.S)  # here-documents are input
        code = re.sub(r"(^|\s)# .*", "", code)                                  # comments
    else:
        patterns = [p for p in _OUT if p is not _OUT[1]]  # no shell redirection in Python
    names = set()
    for pattern in patterns:
        for m in pattern.finditer(code):
            path = m.group(1).rstrip("/")
            if path and not path.startswith(("/", "$", "-")) and path not in (".", "&1", "&2", "/dev/null"):
                names.add(path.split("/")[0])
    return names


def blocks(path: Path) -> list[Block]:
    """The runnable fenced blocks of ``path``, with their directives."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out: list[Block] = []
    i = 0
    while i < len(lines):
        m = _FENCE.match(lines[i])
        if not m:
            i += 1
            continue
        fence, lang = m["fence"], m["lang"].lower()
        j = i + 1
        while j < len(lines) and not lines[j].strip().startswith(fence):
            j += 1
        if lang in LANGS:
            options = {}
            k = i - 1
            while k >= 0 and not lines[k].strip():
                k -= 1
            d = _DIRECTIVE.match(lines[k]) if k >= 0 else None
            if d:
                options = json.loads(d["json"])
                unknown = set(options) - {"quick", "exit", "timeout", "skip"}
                if unknown:
                    raise AssertionError(f"{path.name}:{k + 1}: unknown doc-test keys {sorted(unknown)}")
            indent = len(m["indent"])
            code = "\n".join(ln[indent:] if ln[:indent].isspace() else ln for ln in lines[i + 1:j]) + "\n"
            out.append(Block(path, i + 1, LANGS[lang], code, options))
        i = j + 1
    return out


_COMMAND = re.compile(r"^\s*(\$ )?(sensorless|python3?|\.venv/bin/\S+|make|pip)\s")


def hidden_commands(path: Path) -> list[str]:
    """Commands a user would copy that no test runs: in indented code or in a fence of another
    language (``text``, ``console``...). Each as ``file:line: text``."""
    lines = path.read_text(encoding="utf-8").splitlines()
    out, fence, lang, prev_blank = [], None, "", True
    for i, line in enumerate(lines):
        m = _FENCE.match(line)
        if fence is None and m:
            fence, lang = m["fence"], m["lang"].lower()
            continue
        if fence is not None:
            if line.strip().startswith(fence):
                fence = None
            elif lang not in LANGS and _COMMAND.match(line):
                out.append(f"{path.relative_to(ROOT)}:{i + 1}: {line.strip()}")
            continue
        if line.startswith("    ") and _COMMAND.match(line) and (prev_blank or lines[i - 1].startswith("    ")):
            out.append(f"{path.relative_to(ROOT)}:{i + 1}: {line.strip()}")
        prev_blank = not line.strip()
    return out


def workspace(tmp: Path) -> Path:
    """A directory laid out like a fresh clone's root, with ``../shared`` beside it."""
    work = tmp / "repo"
    work.mkdir()
    for name in ("examples", "studies/benchmarks", "docs"):
        shutil.copytree(ROOT / name, work / name, ignore=shutil.ignore_patterns("__pycache__"))
    shared = ROOT.parent / "shared"
    if shared.exists():
        (tmp / "shared").symlink_to(shared, target_is_directory=True)
    return work


def environment() -> dict:
    """The user's shell after ``source .venv/bin/activate``: this interpreter's bin first on PATH."""
    env = dict(os.environ)
    bindir = str(Path(sys.executable).parent)
    env["PATH"] = bindir + os.pathsep + env.get("PATH", "")
    env["VIRTUAL_ENV"] = str(Path(sys.executable).parents[1])
    env.update(MPLBACKEND="Agg", PYTHONHASHSEED="0", COLUMNS="120")
    return env


def run_block(block: Block, cwd: Path, env: dict) -> tuple[int, str, float]:
    """Run one block; (exit code, combined output tail, seconds)."""
    code = block.runnable_code()
    if block.lang == "bash":
        cmd = ["bash", "-c", "set -euo pipefail\n" + code]
        stdin = None
    else:
        cmd = [sys.executable, "-"]
        stdin = code
    start = time.perf_counter()
    timeout = float(block.options.get("timeout", 300))
    # its own process group: at the timeout the block and everything it started (a background
    # listener, a pipe's other end) is killed, so nothing holds the output pipes open
    p = subprocess.Popen(cmd, cwd=cwd, env=env, stdin=subprocess.PIPE if stdin else subprocess.DEVNULL,
                         stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True, start_new_session=True)
    try:
        output, _ = p.communicate(stdin, timeout=timeout)
        rc = p.returncode
    except subprocess.TimeoutExpired:
        os.killpg(p.pid, signal.SIGKILL)
        output, _ = p.communicate()
        rc, output = -9, f"timed out after {timeout:g} s\n" + (output or "")
    finally:
        try:  # a background job left running by a block that exited
            os.killpg(p.pid, signal.SIGKILL)
        except ProcessLookupError:
            pass
    return rc, output[-4000:], time.perf_counter() - start
