"""``genplan bench adapt``'s options: the rows it runs and the obstacle case's starts."""

import argparse
from types import SimpleNamespace

import numpy as np
import pytest

from genplan.cli import args as A
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
    assert args.skip == 0 and args.obstacle_start_spread is None
    args = _parser().parse_args([*base, "--skip", "60", "--obstacle-start-spread", "1.5"])
    assert args.skip == 60 and args.obstacle_start_spread == 1.5


@pytest.mark.parametrize("extra", [["--rows", "obstacles"], ["--rows", ","], ["--obstacle-starts", "0"],
                                   ["--skip", "-1"], ["--obstacle-start-spread", "0"]])
def test_bad_rows_and_starts_are_refused(extra, capsys) -> None:
    with pytest.raises(SystemExit):
        _parser().parse_args(["--model", __file__, "--data", ".", "--held-out", ".", *extra])
    assert extra[0] in capsys.readouterr().err


class _Set(SimpleNamespace):
    """A stand-in trajectory set: its positions and their count."""

    def __len__(self) -> int:
        return len(self.positions)


class _Robot:
    """A stand-in whose frame position is a configuration's first three joints."""

    def frame_positions(self, q, frame):
        return np.asarray(q)[..., :3]


def test_problems_skip_leaves_out_the_first_held_out_goals() -> None:
    rng = np.random.default_rng(0)
    data = _Set(positions=rng.normal(size=(50, 6, 7)))
    held_out = _Set(positions=data.positions[[7, 3, 11, 42, 5]] + 1e-6)
    targets, x_in, idx = adapt.problems(data, held_out, _Robot(), "hand", 2, skip=2)
    assert idx.tolist() == [11, 42]
    np.testing.assert_allclose(targets, held_out.positions[2:4, -1, :3])
    np.testing.assert_array_equal(x_in, data.positions[[11, 42]])
    with pytest.raises(A.UsageError, match="--skip"):
        adapt.problems(data, held_out, _Robot(), "hand", 2, skip=4)
