"""docs/BENCHMARKS.md: generated from benches/results by `genplan report benches/results --benchmarks
docs/BENCHMARKS.md`, and committed as that command writes it."""

from __future__ import annotations

import json
import shutil
from pathlib import Path

import pytest

from genplan.cli import main
from genplan.errors import GenplanError
from genplan.experiments import benchmarks_md as B

REPO = Path(__file__).resolve().parents[2]
RESULTS = REPO / "benches" / "results"
PAGE = REPO / "docs" / "BENCHMARKS.md"
COMMAND = "genplan report benches/results --benchmarks docs/BENCHMARKS.md"


def _checkout(tmp_path: Path) -> Path:
    """A folder laid out as the repository for the page's inputs (benches/ and examples/ linked)."""
    for name in ("benches", "examples"):
        (tmp_path / name).symlink_to(REPO / name)
    (tmp_path / "docs").mkdir()
    return tmp_path


def test_the_committed_page_is_what_the_command_writes(tmp_path: Path) -> None:
    """Run the command as the README says (in a copy of the layout, so the repository is not
    written) and compare byte for byte: a benchmark rerun, or a page edited by hand instead of
    its template, fails here until the command is rerun."""
    root = _checkout(tmp_path)
    assert main(["report", str(root / "benches" / "results"), "--benchmarks", str(root / "docs" / "BENCHMARKS.md")]) == 0
    written = (root / "docs" / "BENCHMARKS.md").read_text()
    assert written == PAGE.read_text(), f"docs/BENCHMARKS.md is not what `{COMMAND}` writes: run it"
    assert COMMAND in (REPO / "README.md").read_text()  # the README says how to regenerate it


def test_every_table_has_its_place_its_json_and_its_command() -> None:
    """Each table of TABLES is in the template, reads files that exist, and the page names its
    command under it."""
    page = PAGE.read_text()
    template = B.TEMPLATE.read_text()
    for name, table in B.TABLES.items():
        assert template.count("{{" + name + "}}") == 1, name
        for file in table.files:
            assert (RESULTS / file).is_file(), file
    assert page.count("\nJSON: [") == len(B.TABLES)
    assert "{{" not in page


def test_the_tables_are_made_from_the_json(tmp_path: Path) -> None:
    """A number changed in a benchmark's JSON changes the page: Table I's first success rate and
    the robots table's FK error."""
    root = tmp_path / "repo"
    root.mkdir()
    shutil.copytree(RESULTS, root / "benches" / "results", ignore=shutil.ignore_patterns("*.png", "*.html"))
    (root / "examples").symlink_to(REPO / "examples")
    table1 = root / "benches" / "results" / "table1_panda_uniform.json"
    data = json.loads(table1.read_text())
    data["projection"]["success_rate"] = 12.3
    table1.write_text(json.dumps(data))
    robots = root / "benches" / "results" / "robots.json"
    data = json.loads(robots.read_text())
    data["rows"][0]["fk_max_error"] = 7.7e-7
    robots.write_text(json.dumps(data))
    page = B.render(root / "benches" / "results", root / "docs" / "BENCHMARKS.md")
    assert "| panda | projection | uniform | 12.3 | 0.021 |" in page
    assert "| panda | 7 | yes | 252 | 7.7e-07 |" in page
    assert page != PAGE.read_text()


def test_a_template_naming_an_unknown_table_or_missing_one_is_refused() -> None:
    text = B.TEMPLATE.read_text()
    with pytest.raises(GenplanError, match="no table named nosuchtable"):
        B.render(RESULTS, PAGE, text + "\n{{nosuchtable}}\n")
    with pytest.raises(GenplanError, match=r"the tables table1 have no \{\{name\}\} line"):
        B.render(RESULTS, PAGE, text.replace("{{table1}}", ""))


def test_a_missing_json_file_or_field_is_named(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    """One line naming the file (and the field), exit code 2, and no page written."""
    results = tmp_path / "results"
    results.mkdir()
    (results / "table1_panda_uniform.json").write_text("{}")
    assert main(["report", str(results), "--benchmarks", str(tmp_path / "B.md")]) == 2
    assert capsys.readouterr().err == f"genplan: error: {results / 'table1_panda_gan.json'}: No such file or directory\n"
    for name in B.TABLES["table1"].files:
        (results / name).write_text("{}")
    assert main(["report", str(results), "--benchmarks", str(tmp_path / "B.md")]) == 2
    err = capsys.readouterr().err
    assert err.startswith(f"genplan: error: {results / 'table1_panda_uniform.json'}: no field 'projection'") and err.count("\n") == 1
    assert not (tmp_path / "B.md").exists()


def test_benchmarks_and_out_are_one_or_the_other(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["report", str(RESULTS), "--benchmarks", str(tmp_path / "B.md"), "--out", str(tmp_path / "r.md")]) == 2
    assert "--benchmarks writes the benchmarks page instead" in capsys.readouterr().err
    assert not (tmp_path / "B.md").exists() and not (tmp_path / "r.md").exists()


def test_the_motion_table_has_a_hybrid_column_when_a_robot_ran_it() -> None:
    """The motion table's columns are the genplan arms the robots' results hold: the committed
    results as they are, and with the Panda's spheres rows copied as a hybrid arm (another time),
    a hybrid column whose Panda cells and geometric mean are read from those rows and a dash for
    the robots that did not run it."""
    res = {name: json.loads((RESULTS / name).read_text()) for name in B.MOTION_FILES}
    before = B.motion(res)
    panda = res["motion.json"]
    hybrid = [dict(r, arm="genplan_hybrid", plan_ms_over_vamp=3.0, plan_ms_median=4.56) for r in panda["rows"]
              if r["arm"] == "genplan_spheres"]
    if not hybrid or any(r["arm"] == "genplan_hybrid" for name in B.MOTION_FILES for r in res[name]["rows"]):
        pytest.skip("the committed results already hold a hybrid arm, or the Panda's no spheres arm")
    assert B.MOTION_ARMS["genplan_hybrid"] not in before
    panda["rows"] = panda["rows"] + hybrid
    after = B.motion(res)
    header = after.splitlines()[0]
    assert header.index(B.MOTION_ARMS["genplan_spheres"]) < header.index(B.MOTION_ARMS["genplan_hybrid"]) \
        < header.index(B.MOTION_ARMS["genplan_exact"])
    lines = after.splitlines()
    assert all(ln.count("|") == header.count("|") for ln in lines if ln.startswith("|"))
    panda_rows = [ln for ln in lines if ln.startswith(f"| {panda['robot']} |")]
    assert panda_rows and all("4.56 + " in ln for ln in panda_rows[:-1])
    assert "**3.00x**" in panda_rows[-1]
    other = [ln for ln in lines if ln.startswith("| ") and not ln.startswith(f"| {panda['robot']} |")][1:]
    assert other and all(ln.split(" | ")[4] == "-" for ln in other)
