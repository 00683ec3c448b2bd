"""The coverage metrics and the planar robot of genplan.experiments.benchmarks.coverage."""

import numpy as np

from genplan.experiments.benchmarks import coverage as C


def test_metrics_separate_full_coverage_from_mode_collapse() -> None:
    rng = np.random.default_rng(0)
    centers = np.array([[-3.0, 0.0], [3.0, 0.0], [0.0, 3.0], [0.0, -3.0]])
    data = np.concatenate([c + 0.3 * rng.standard_normal((500, 2)) for c in centers])
    same = np.concatenate([c + 0.3 * rng.standard_normal((500, 2)) for c in centers])
    collapsed = centers[0] + 0.3 * rng.standard_normal((2000, 2))
    assert C.cluster_coverage(data, same, np.random.default_rng(1), k=8) == 1.0
    assert C.cluster_coverage(data, collapsed, np.random.default_rng(1), k=8) <= 0.25
    assert abs(C.mmd(data, same, np.random.default_rng(2))) < 0.01
    assert C.mmd(data, collapsed, np.random.default_rng(2)) > 0.1


def test_planar_collision_check() -> None:
    # straight arm along +x: the obstacles are elsewhere; pointing at the first obstacle: collides
    free = np.array([[0.0, 0.0]])
    toward = np.arctan2(C.PLANAR_OBSTACLES[0, 1], C.PLANAR_OBSTACLES[0, 0])
    hit = np.array([[toward, 0.0]])
    assert C.planar_collision_free(free)[0]
    assert not C.planar_collision_free(hit)[0]
    data = C.planar_data(500, np.random.default_rng(0))
    assert data.shape == (500, 2) and C.planar_collision_free(data).all()


def test_variants_are_valid_configs_and_parsed_by_name() -> None:
    import argparse

    import pytest

    from genplan.samplers.flow import FlowConfig
    from genplan.samplers.gan import GanConfig

    for name in C.VARIANTS:
        family, cfg, overrides = C.variant_config("panda", name, iterations=7)  # validated: every variant trains
        assert isinstance(cfg, FlowConfig if family in ("flow", "distill") else GanConfig), name
        assert cfg.iterations == 7 * C.VARIANTS[name].get("iterations_factor", 1), name
        assert all(getattr(cfg, k) == v for k, v in overrides.items()), name
        if family == "distill":  # the teacher is another variant, a flow of the same robot and data
            teacher_family, teacher, _ = C.variant_config("panda", cfg.teacher, iterations=7)
            assert teacher_family == "flow" and teacher.data_size == cfg.data_size and teacher.steps > cfg.steps
    assert {"flow", "flow_pure"} <= set(C.VARIANTS)
    assert set(C.PAPER_VARIANTS) <= set(C.VARIANTS)
    assert C.variant_list("default, wgan_gp,default") == ["default", "wgan_gp"]
    for bad in ("", "default,bogus"):
        with pytest.raises(argparse.ArgumentTypeError, match="expected comma-separated variants"):
            C.variant_list(bad)



def test_the_shipped_ablations_are_what_quick_trains() -> None:
    """models/<robot>_coverage_<variant>.safetensors: the paper's ablations as `genplan bench
    coverage --quick --seed 0` trains them (the same configuration), each card naming its
    retraining command with --out."""
    import genplan
    from genplan.model_files import models_dir

    for robot in ("panda", "talos"):
        rob = genplan.load(robot)
        for label in C.PAPER_VARIANTS:
            _, cfg, _ = C.variant_config(robot, label, iterations=C.QUICK_ITERATIONS, seed=0)
            model = C.read_variant(rob, label, cfg, models_dir())
            command = model.card["command"]
            assert command.startswith(f"genplan train gan --robot {robot} --seed 0 --iterations {C.QUICK_ITERATIONS}")
            assert command.endswith(f" --out {C.ablation_path(models_dir(), robot, label).name}")


def test_a_model_of_another_configuration_is_refused(panda) -> None:
    """The file's card must hold the configuration the run would train: another seed or number
    of iterations, or another variant, is a ModelFileError naming the file and the fields."""
    import pytest

    from genplan.errors import ModelFileError
    from genplan.model_files import models_dir

    path = C.ablation_path(models_dir(), "panda", "n_net_1")
    _, cfg, _ = C.variant_config("panda", "n_net_1", iterations=2000, seed=3)
    with pytest.raises(ModelFileError) as info:
        C.read_variant(panda, "n_net_1", cfg, models_dir())
    assert str(info.value).startswith(f"{path} was trained with iterations=1500 (this run: 2000), seed=0 (this run: 3): "
                                      "not variant 'n_net_1' of this run; leave --models out to train it")
    _, other, _ = C.variant_config("panda", "n_net_1", iterations=C.QUICK_ITERATIONS, seed=0)
    with pytest.raises(ModelFileError, match=r"panda_coverage_default.safetensors was trained with n_net=10 \(this run: 1\)"):
        C.read_variant(panda, "default", other, models_dir())


def test_a_robot_run_reads_the_shipped_ablation_instead_of_training(panda, monkeypatch) -> None:
    """With a models folder, the variant is measured from its file (the card's training seconds
    and command in the row) and no training starts."""
    import pytest

    import genplan.samplers.gan as gan
    from genplan.model_files import models_dir

    monkeypatch.setattr(gan, "train", lambda *a, **k: pytest.fail("training started"))
    out = C.run_robot("panda", C.QUICK_ITERATIONS, 0, None, False, threads=1, variants=["n_net_1"],
                      model_dir=models_dir())
    row = out["n_net_1"]
    _, cfg, _ = C.variant_config("panda", "n_net_1", iterations=C.QUICK_ITERATIONS, seed=0)
    card = C.read_variant(panda, "n_net_1", cfg, models_dir()).card
    assert row["model_file"] == "panda_coverage_n_net_1.safetensors" and row["train_s_from"] == "the model file's card"
    assert row["train_s"] == card["training"]["seconds"] and row["model_command"] == card["command"]
    assert 0 < row["cluster_coverage"] <= 1 and row["projection_success"] > 0.9
