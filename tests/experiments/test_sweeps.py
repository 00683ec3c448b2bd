"""genplan.experiments.sweeps: the median across seeds of every numeric field."""

from genplan.experiments.sweeps import median_of


def test_median_of_nested_rows() -> None:
    rows = [{"a": 1.0, "b": {"c": 3, "d": None}, "name": "x", "n": 5, "mixed": 1},
            {"a": 3.0, "b": {"c": 1, "d": 2.0}, "name": "x", "n": 5, "mixed": "two"},
            {"a": 2.0, "b": {"c": 2, "d": 1.0}, "name": "x", "n": 5, "mixed": 3}]
    assert median_of(rows) == {"a": 2.0, "b": {"c": 2.0}, "name": "x", "n": 5}
    assert median_of(rows[:2])["a"] == 2.0  # an even count: the mean of the middle two
