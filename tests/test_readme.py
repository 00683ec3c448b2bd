"""Every ```python block of the README runs, in order, as written, in one namespace (what a user
pasting them one after the other into a session gets). The blocks keep their counts small so
this stays quick; the slowest is "Your own robot"'s 200-iteration GAN training (about half a
minute). The pages of docs/ are run the same way by tests/test_docs.py."""

from __future__ import annotations

import os
import re
import warnings
from pathlib import Path

import pytest

README = Path(__file__).resolve().parents[1] / "README.md"
BLOCKS = re.findall(r"^```python\n(.*?)^```", README.read_text(), re.S | re.M)


def test_the_readme_has_python_blocks() -> None:
    """At least the two main jobs' examples: planning with a learned sampler, and a robot of
    one's own (train, then plan)."""
    assert len(BLOCKS) >= 2
    assert any('sampler="gan"' in b for b in BLOCKS) and any("train(" in b for b in BLOCKS)


@pytest.fixture(scope="module")
def namespace(tmp_path_factory: pytest.TempPathFactory):  # type: ignore[no-untyped-def]
    """The blocks run in a fresh folder holding ``examples`` (a link to the repository's), as in a
    checkout: what they write (e.g. ``cup.safetensors``) lands there, not in the repository."""
    folder = tmp_path_factory.mktemp("readme")
    (folder / "examples").symlink_to(README.parent / "examples")
    before = os.getcwd()
    os.chdir(folder)
    try:
        yield {"__name__": "readme"}
    finally:
        os.chdir(before)


@pytest.mark.parametrize("index", range(len(BLOCKS)), ids=[f"block{i + 1}" for i in range(len(BLOCKS))])
def test_readme_block_runs(index: int, namespace: dict) -> None:
    if namespace.get("failed") is not None:
        pytest.skip(f"block {namespace['failed'] + 1} failed")
    namespace["failed"] = index
    with warnings.catch_warnings():
        # the J1 flip of the control block runs a hair over the UR5's wrist speed limit: it warns
        from genplan.control import LimitWarning

        warnings.simplefilter("ignore", LimitWarning)
        exec(compile(BLOCKS[index], f"README.md python block {index + 1}", "exec"), namespace)
    namespace["failed"] = None
