"""Every ```python block of every docs/*.md page runs, in order, as written, in one namespace per
page (what a reader pasting a page's blocks one after the other into a session gets), in a fresh
folder holding ``examples`` (a link to the repository's), as in a checkout. A block may be skipped
only with its reason, written on the line before it: ``<!-- test: skip (the reason) -->``."""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import pytest

ROOT = Path(__file__).resolve().parents[1]
DOCS = sorted((ROOT / "docs").glob("*.md"))
#: a block, with the line before it (where a skip and its reason are written)
BLOCK = re.compile(r"(?:^(?P<before>[^\n]*)\n)?^```python\n(?P<code>.*?)^```", re.S | re.M)
SKIP = re.compile(r"<!--\s*test:\s*skip\b(?:\s*\((?P<reason>[^)]*)\))?\s*-->")


def python_blocks(text: str) -> list[tuple[str, str | None]]:
    """``(code, reason to skip)`` of every ```python block of a Markdown ``text``: the reason is None
    for a block that runs, "" for a skip that gives none."""
    out = []
    for m in BLOCK.finditer(text):
        skip = SKIP.search(m.group("before") or "")
        out.append((m.group("code"), (skip.group("reason") or "").strip() if skip else None))
    return out


CASES = [(page, i) for page in DOCS for i in range(len(python_blocks(page.read_text())))]


def test_python_blocks_are_found_and_skips_need_a_reason() -> None:
    text = "a\n```python\nx = 1\n```\n<!-- test: skip (needs a GPU) -->\n```python\ny = 2\n```\n"
    assert python_blocks(text) == [("x = 1\n", None), ("y = 2\n", "needs a GPU")]
    assert python_blocks("<!-- test: skip -->\n```python\nz = 3\n```\n") == [("z = 3\n", "")]
    assert {page.name for page, _ in CASES} >= {"API.md", "PLANNING.md", "SAMPLERS.md", "TASKS.md"}


@pytest.fixture(scope="module")
def pages(tmp_path_factory: pytest.TempPathFactory) -> dict[str, dict]:
    """One namespace and one folder per page (filled as its blocks run)."""
    return {"tmp": tmp_path_factory}  # type: ignore[dict-item]


@pytest.mark.parametrize("page, index", CASES, ids=[f"{p.stem}-block{i + 1}" for p, i in CASES])
def test_docs_block_runs(page: Path, index: int, pages: dict) -> None:
    code, reason = python_blocks(page.read_text())[index]
    if reason is not None:
        assert reason, f"docs/{page.name} block {index + 1}: a skipped block states why: <!-- test: skip (reason) -->"
        pytest.skip(reason)
    if page.name not in pages:
        folder = pages["tmp"].mktemp(page.stem)
        (folder / "examples").symlink_to(ROOT / "examples")
        pages[page.name] = {"namespace": {"__name__": f"docs_{page.stem.lower()}"}, "folder": folder, "failed": None}
    state = pages[page.name]
    if state["failed"] is not None:
        pytest.skip(f"{page.name} block {state['failed'] + 1} failed")
    state["failed"] = index
    before = os.getcwd()
    os.chdir(state["folder"])
    try:
        with warnings.catch_warnings():
            # the J1 flip of the pancake block runs a hair over the UR5's wrist speed limit: it warns
            from genplan.control import LimitWarning

            warnings.simplefilter("ignore", LimitWarning)
            # dont_inherit: the block is compiled as a session would, without this file's __future__ imports
            exec(compile(code, f"docs/{page.name} python block {index + 1}", "exec", dont_inherit=True),
                 state["namespace"])
    finally:
        os.chdir(before)
    state["failed"] = None
