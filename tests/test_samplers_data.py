"""genplan.samplers.data: training rows drawn where the sampler is asked (the condition's box),
the share a card reports, and the data set without it unchanged."""

import argparse
import dataclasses

import numpy as np
import pytest

import genplan
from genplan import projection as P
from genplan.errors import SettingsError
from genplan.samplers import data as D
from genplan.samplers.gan import GanConfig, default_config, train

#: a hand box small enough that few uniform projections reach it (Panda's reach is ~1.7 m across)
LOW, HIGH = (0.45, -0.1, 0.55), (0.6, 0.1, 0.7)


@pytest.fixture(scope="module")
def boxed(panda: genplan.Robot) -> P.Task:
    """The paper's Panda IK task under a name of the user's, its condition box a small one."""
    t = P.load_task("panda_ik", panda)
    assert t.condition is not None
    return dataclasses.replace(t, name="hand_in_a_small_box",
                               condition=dataclasses.replace(t.condition, low=LOW, high=HIGH))


def test_rows_drawn_in_the_box_cover_it_and_stay_on_the_manifold(panda: genplan.Robot, boxed: P.Task) -> None:
    plain = D.valid_configurations(panda, 60, 4, use_cache=False, progress=False, task=boxed, shard_size=30)
    rows = D.valid_configurations(panda, 60, 4, use_cache=False, progress=False, task=boxed, shard_size=30, in_box=0.5)
    assert rows.shape == (60, panda.nq)
    # each shard's first half is the data set as it always was (same generator, same rows)
    for a in (0, 30):
        np.testing.assert_array_equal(rows[a:a + 15], plain[a:a + 15])
    # its second half: the hand in the box (within the condition term's 1 mm tolerance)
    hand = panda.frame_positions(rows, "hand")
    boxed_rows = np.r_[15:30, 45:60]
    assert np.all(hand[boxed_rows] >= np.array(LOW) - 1e-3) and np.all(hand[boxed_rows] <= np.array(HIGH) + 1e-3)
    share = D.box_share(panda, boxed, rows)
    assert share["of"] == 60 and share["frame"] == "hand" and share["box"] == [list(LOW), list(HIGH)]
    assert share["share"] >= 0.45 > D.box_share(panda, boxed, plain)["share"]
    # every row on the manifold the sampler covers (the paper's projection task), within the limits
    manifold = P.GaussNewtonProjector(panda, P.manifold_task(boxed, panda))
    assert manifold.solve_batch(rows).success.all()
    assert np.all((rows >= panda.lower) & (rows <= panda.upper))
    # reproducible, and cached apart from the data set without it
    again = D.valid_configurations(panda, 60, 4, use_cache=False, progress=False, task=boxed, shard_size=30, in_box=0.5)
    np.testing.assert_array_equal(rows, again)
    assert D.cache_path(panda, 60, 4, boxed, 30, in_box=0.5) != D.cache_path(panda, 60, 4, boxed, 30)
    assert D.cache_path(panda, 60, 4, boxed, 30, in_box=0.0) == D.cache_path(panda, 60, 4, boxed, 30)


def test_a_share_outside_zero_one_is_refused_naming_it(panda: genplan.Robot, boxed: P.Task) -> None:
    for bad in (-0.1, 1.5, True, "half"):
        with pytest.raises(SettingsError, match="in_box"):
            D.shards(panda, 10, task=boxed, in_box=bad)  # type: ignore[arg-type]
    with pytest.raises(SettingsError, match="data_in_box"):
        default_config(panda, boxed, data_in_box=2.0)
    from genplan.cli import train_gan

    p = argparse.ArgumentParser()
    train_gan.add_arguments(p)
    with pytest.raises(SystemExit):
        p.parse_args(["--robot", "panda", "--data-in-box", "1.5"])


def test_a_users_task_trains_on_half_its_rows_in_the_box_and_the_card_says_so(panda: genplan.Robot,
                                                                               boxed: P.Task) -> None:
    # the papers' shipped tasks keep the papers' data; a task of the user's draws half in its box
    assert default_config(panda).data_in_box == 0.0 == D.default_in_box(P.load_task("panda_ik", panda))
    cfg = default_config(panda, boxed, iterations=2, data_size=40, n_net=2, data_seed=5)
    assert cfg.data_in_box == D.IN_BOX == 0.5
    model = train(cfg, progress=False, robot=panda, task=boxed)
    card = model.card
    inside = card["data"]["in_condition_box"]
    assert inside["of"] == 40 and inside["share"] >= 0.45 and inside["box"] == [list(LOW), list(HIGH)]
    assert "condition's box" in card["data"]["source"]
    # a card written before the field existed reads as the data it was trained on: no rows drawn in the box
    assert GanConfig.ADDED_FIELDS >= {"data_in_box"} and GanConfig.__dataclass_fields__["data_in_box"].default == 0.0
