"""genplan.experiments.common: output files are written whole or not at all."""

from __future__ import annotations

import json

import pytest

from genplan.experiments.common import atomic_path, save_figure, write_json, write_text


def test_write_json_creates_folders_and_leaves_no_temporary_file(tmp_path, capsys) -> None:
    path = tmp_path / "a" / "b" / "x.json"
    write_json(path, {"k": 1})
    assert json.loads(path.read_text()) == {"k": 1}
    assert [p.name for p in path.parent.iterdir()] == ["x.json"]
    assert capsys.readouterr().out == f"wrote {path}\n"


def test_a_failed_write_keeps_the_old_file(tmp_path) -> None:
    path = tmp_path / "report.md"
    write_text(path, "old\n")
    with pytest.raises(RuntimeError, match="interrupted"):
        with atomic_path(path) as tmp:
            tmp.write_text("half a rep")
            raise RuntimeError("interrupted")
    assert path.read_text() == "old\n" and [p.name for p in tmp_path.iterdir()] == ["report.md"]
    with pytest.raises(TypeError):
        write_json(path.with_suffix(".json"), {"not json": object()})
    assert [p.name for p in tmp_path.iterdir()] == ["report.md"]


def test_save_figure_writes_a_png_by_its_suffix(tmp_path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, ax = plt.subplots()
    ax.plot([0, 1], [0, 1])
    path = save_figure(fig, tmp_path / "figs" / "f.png", dpi=50)
    plt.close(fig)
    assert path.read_bytes()[:8] == b"\x89PNG\r\n\x1a\n" and [p.name for p in path.parent.iterdir()] == ["f.png"]
