"""``genplan bench adapt``'s options: the rows it runs and the obstacle case's starts."""

import argparse

import pytest

from genplan.experiments.benchmarks import adapt


def _parser() -> argparse.ArgumentParser:
    p = argparse.ArgumentParser()
    adapt.add_arguments(p)
    return p


def test_rows_and_obstacle_starts_parse_and_default() -> None:
    base = ["--model", __file__, "--data", ".", "--held-out", "."]
    args = _parser().parse_args(base)
    assert args.rows == adapt.ROWS and args.obstacle_starts == adapt.OBSTACLE_STARTS
    args = _parser().parse_args([*base, "--rows", "obstacle, latent", "--obstacle-starts", "2"])
    assert args.rows == ("obstacle", "latent") and args.obstacle_starts == 2


@pytest.mark.parametrize("extra", [["--rows", "obstacles"], ["--rows", ","], ["--obstacle-starts", "0"]])
def test_bad_rows_and_starts_are_refused(extra, capsys) -> None:
    with pytest.raises(SystemExit):
        _parser().parse_args(["--model", __file__, "--data", ".", "--held-out", ".", *extra])
    assert extra[0] in capsys.readouterr().err
