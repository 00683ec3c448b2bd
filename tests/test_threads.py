"""genplan._threads: torch's thread count per workload, its overrides, and that every entry point
restores the caller's setting. (The policy's numbers: benches/threads_under_load.py.)"""

import threading

import numpy as np
import pytest
import torch

from genplan._threads import ENV, POLICY, resolve, torch_threads
from genplan.errors import SettingsError, UnknownNameError


@pytest.fixture(autouse=True)
def caller_threads(monkeypatch):
    """Each test starts with torch at 2 threads and no override, and ends restored."""
    monkeypatch.delenv(ENV, raising=False)
    before = torch.get_num_threads()
    torch.set_num_threads(2)
    yield 2
    torch.set_num_threads(before)


def test_resolve_policy_environment_keyword(monkeypatch) -> None:
    assert resolve("small") == POLICY["small"] == 1
    assert resolve("training") == POLICY["training"]
    monkeypatch.setenv(ENV, "3")
    assert resolve("small") == 3 and resolve("training") == 3
    assert resolve("small", threads=2) == 2  # the keyword beats the environment
    monkeypatch.setenv(ENV, "many")
    with pytest.raises(SettingsError, match=f"{ENV} must be a positive integer, got 'many'"):
        resolve("small")
    monkeypatch.setenv(ENV, "0")
    with pytest.raises(SettingsError, match=f"{ENV} must be a positive integer, got '0'"):
        resolve("small")
    for bad in (0, -1, 1.5, True, "2"):
        with pytest.raises(SettingsError, match="threads must be a positive integer"):
            resolve("small", bad)  # type: ignore[arg-type]
    with pytest.raises(UnknownNameError, match="unknown torch workload 'huge'"):
        resolve("huge")


def test_context_sets_and_restores_nested() -> None:
    with torch_threads("small") as n:
        assert n == 1 and torch.get_num_threads() == 1
        with torch_threads("small", threads=3):
            assert torch.get_num_threads() == 3
        assert torch.get_num_threads() == 1  # the enclosing call's value
    assert torch.get_num_threads() == 2
    with pytest.raises(RuntimeError):
        with torch_threads("small"):
            raise RuntimeError("boom")
    assert torch.get_num_threads() == 2  # restored on error too


def test_overlapping_calls_from_threads_restore_the_original() -> None:
    barrier = threading.Barrier(2)
    seen: list[int] = []

    def work(k: int) -> None:
        with torch_threads("small", threads=k):
            barrier.wait()
            seen.append(torch.get_num_threads())
            barrier.wait()

    ts = [threading.Thread(target=work, args=(k,)) for k in (1, 3)]
    for t in ts:
        t.start()
    for t in ts:
        t.join()
    assert len(seen) == 2 and torch.get_num_threads() == 2


def _threads_seen_by_adjust(**kwargs) -> int:
    from genplan.pancake import adjust, s_curve

    seen = []

    def objective(r):
        seen.append(torch.get_num_threads())
        return (r.p[:, -1, 0] - 0.1) ** 2

    adjust(s_curve(np.zeros(3), [0.1, 0.0, 0.0]), objective, updates=1, **kwargs)
    return seen[0]


def test_latent_updates_run_on_one_thread_unless_told(monkeypatch) -> None:
    """Before: torch's default (2 threads here), 40x slower with the other core busy."""
    assert _threads_seen_by_adjust() == 1
    assert torch.get_num_threads() == 2
    assert _threads_seen_by_adjust(threads=2) == 2
    monkeypatch.setenv(ENV, "2")
    assert _threads_seen_by_adjust() == 2
    assert torch.get_num_threads() == 2
    with pytest.raises(SettingsError, match="threads must be a positive integer"):
        _threads_seen_by_adjust(threads=0)


def test_gan_sampling_and_training_threads(monkeypatch, tmp_path) -> None:
    import genplan
    from genplan.samplers.gan import default_config, train
    from genplan.samplers.sampler import GanSampler

    panda = genplan.load("panda")
    data = panda.random_configurations(200, 0)  # training mechanics only: any configurations do
    cfg = default_config("panda", iterations=2, n_net=2, data_size=200)
    model = train(cfg, data=data, progress=False)
    assert model.card["training"]["threads"] == POLICY["training"]
    assert train(cfg, data=data, progress=False, threads=2).card["training"]["threads"] == 2
    assert torch.get_num_threads() == 2

    seen = []
    forward = model.generator.forward

    def recording(x):
        seen.append(torch.get_num_threads())
        return forward(x)

    monkeypatch.setattr(model.generator, "forward", recording)
    GanSampler(panda, model, seed=0).sample(3)
    GanSampler(panda, model, seed=0, threads=2).sample_for(np.zeros((2, 3)))
    assert seen == [1, 2] and torch.get_num_threads() == 2
    with pytest.raises(SettingsError, match="threads must be a positive integer"):
        GanSampler(panda, model, threads=-1)
