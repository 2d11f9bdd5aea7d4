"""Every fenced bash/python block of README.md, docs/*.md and examples/*.md runs as printed
(tests/doc_blocks.py: directives, layout), all pages in README order in one shared folder as a user
following the guides does (the journey); every output name belongs to one page and no page reads
another's, so each page also runs alone (run them so with ``-m slow``). The blocks run are listed at
the end of the session (conftest) and in /tmp/sensorless-bench/doc_blocks.json."""

from __future__ import annotations

import json
import os
import re

import pytest

from doc_blocks import (ROOT, blocks, doc_files, environment, hidden_commands, journey_files, outputs, run_block,
                        workspace)

#: files whose blocks are being made runnable (issue #24); each is removed when its doc runs as printed
PENDING: set[str] = set()
FILES = [p for p in doc_files() if blocks(p) and str(p.relative_to(ROOT)) not in PENDING]


def _record(entry: dict) -> None:
    log = os.environ.get("SENSORLESS_DOC_LOG")
    if log:
        with open(log, "a", encoding="utf-8") as fh:
            fh.write(json.dumps(entry) + "\n")


def _run_page(path, work, env, shared: bool, run: str) -> list[str]:
    """Run the blocks of ``path`` in order in ``work``; the failures (the first stops the page: later
    blocks depend on it)."""
    for block in blocks(path):
        entry = {"block": block.where, "lang": block.lang, "run": run}
        if "skip" in block.options:
            _record({**entry, "status": "skipped", "reason": block.options["skip"]})
            continue
        if "../shared/" in block.code and not shared:  # real logs: the blocks that use them say so
            _record({**entry, "status": "skipped", "reason": "../shared is absent"})
            continue
        rc, output, seconds = run_block(block, work, env)
        want = int(block.options.get("exit", 0))
        _record({**entry, "status": "ok" if rc == want else "failed", "exit": rc, "seconds": round(seconds, 2)})
        if rc != want:
            return [f"{block.where} ({block.lang}) exit {rc}, expected {want}:\n{output}"]
    return []


@pytest.mark.slow
@pytest.mark.parametrize("path", FILES, ids=[str(p.relative_to(ROOT)) for p in FILES])
def test_doc_runs_as_printed(path, tmp_path):
    """Each page alone, in a fresh folder (slow: the journey below runs every block once; that no page
    needs another's files is checked by `test_no_page_reads_another_pages_output`)."""
    work = workspace(tmp_path)
    failures = _run_page(path, work, environment(), (tmp_path / "shared").exists(), "alone")
    assert not failures, "\n\n".join(failures)


def test_guides_run_one_after_another_in_one_folder(tmp_path):
    """All pages in README order in ONE folder, as a user following the guides does: a page that
    reuses another's output name fails here (its `--out` refused), not only in the static test below."""
    work = workspace(tmp_path)
    env, shared = environment(), (tmp_path / "shared").exists()
    failures = []
    for path in journey_files():
        if path in FILES:
            failures += _run_page(path, work, env, shared, "journey")
    assert not failures, "\n\n".join(failures)


def uses(code: str, name: str) -> bool:
    """Whether ``code`` refers to the file or folder ``name`` as a path: ``name/...``, an option's value
    (``--model name``) or a quoted string."""
    e = re.escape(name)
    return re.search(rf"(?<![\w./-]){e}/|--[\w-]+[ =]['\"]?{e}(?![\w./-])|['\"]{e}['\"]", code) is not None


def test_no_page_reads_another_pages_output():
    """Each page alone: with every output name owned by one page, a page runs alone as in the journey
    unless it refers to another page's output; none does (a page starts with its own data step)."""
    owner: dict[str, str] = {}
    for path in doc_files():
        for block in blocks(path):
            for name in outputs(block):
                owner.setdefault(name, str(path.relative_to(ROOT)))
    reads = []
    for path in doc_files():
        page = str(path.relative_to(ROOT))
        for block in blocks(path):
            if "skip" in block.options:
                continue
            code = block.runnable_code()
            reads += [f"{block.where}: uses {name!r} of {other}" for name, other in owner.items()
                      if other != page and uses(code, name)]
    assert not reads, "\n".join(reads)


def test_output_names_are_unique_across_pages():
    """Every file or folder a block writes (``--out``, ``>``, ``save``) belongs to one page: followed one
    after another in one folder, no page finds another's output in its way (or writes into it)."""
    owner: dict[str, str] = {}
    clashes = []
    for path in doc_files():
        page = str(path.relative_to(ROOT))
        for block in blocks(path):
            for name in outputs(block):
                if owner.setdefault(name, page) != page:
                    clashes.append(f"{block.where}: {name!r} is also written by {owner[name]}")
    assert owner and not clashes, "\n".join(clashes)


def test_directives_parse_and_quick_texts_exist():
    """Every directive is valid JSON with known keys and every `quick` text is in its block."""
    n = 0
    for path in doc_files():
        for block in blocks(path):
            block.runnable_code()
            n += 1
    assert n > 0


def test_commands_are_in_runnable_blocks():
    """A command shown in indented code or a ``text`` fence would escape the test: none is."""
    hidden = [h for p in doc_files() if str(p.relative_to(ROOT)) not in PENDING for h in hidden_commands(p)]
    assert not hidden, "commands outside ```bash/```python blocks:\n" + "\n".join(hidden)


def test_inline_commands_name_real_commands_and_options():
    """Every `sensorless ...` quoted inline in the docs names an existing command and its options."""
    import re
    import shlex

    import typer

    from sensorless.cli import app

    root = typer.main.get_command(app)
    bad, n = [], 0

    def sub(group, name):  # click's lookup: also the commands other packages register (entry points)
        return group.get_command(typer.Context(group), name)

    for path in doc_files():
        for m in re.finditer(r"`(sensorless [^`]+)`", path.read_text(encoding="utf-8")):
            tokens = [t for t in shlex.split(m.group(1)) if t not in ("...", "…")]
            n += 1
            cmd, i = root, 1
            while i < len(tokens) and hasattr(cmd, "get_command") and sub(cmd, tokens[i]) is not None:
                cmd, i = sub(cmd, tokens[i]), i + 1
            if hasattr(cmd, "get_command"):
                if i < len(tokens) and not tokens[i].startswith("-"):
                    bad.append(f"{path.name}: `{m.group(1)}`: no command '{tokens[i]}'")
                continue
            known = {o for p in cmd.params for o in (*p.opts, *p.secondary_opts)}
            bad += [f"{path.name}: `{m.group(1)}`: no option {t.strip('[]').split('=')[0]}" for t in tokens[i:]
                    if t.strip("[]").startswith("--") and t.strip("[]").split("=")[0] not in known]
    assert n > 30 and not bad, "\n".join(bad)
