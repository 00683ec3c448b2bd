"""The genplan command line."""

import subprocess
import sys

from genplan.cli import main


def test_help_lists_commands(capsys) -> None:
    assert main([]) == 2
    assert "info" in capsys.readouterr().out


def test_info_prints_versions_and_robots() -> None:
    out = subprocess.run(
        [sys.executable, "-m", "genplan", "info"], capture_output=True, text=True, check=True
    ).stdout
    assert "parry3d-f64 0.25" in out and "pin " in out
    for line in ("panda  nq=7", "talos  nq=35", "ur5    nq=6"):
        assert line in out, out
