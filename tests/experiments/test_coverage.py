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

    from genplan.gan.flow import FlowConfig
    from genplan.gan.model import GanConfig

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
