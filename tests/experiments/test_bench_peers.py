"""genplan bench peers (issue 18, item 5): the side-by-side run, its success test, the peers as an
optional extra (skipped with the install command when missing)."""

import json
import sys

import numpy as np
import pytest

import genplan
from genplan.cli import main
from genplan.errors import MissingExtraError
from genplan.experiments.benchmarks import peers as bench
from genplan.experiments.common import write_json
from genplan.experiments.peers import ik as K
from genplan.experiments.peers import ikpy, pink, placo, pytorch_kinematics
from genplan.projection import load_task

PEERS = {"pink": pink, "placo": placo, "ikpy": ikpy, "pytorch_kinematics": pytorch_kinematics}


@pytest.fixture(scope="module")
def panda_problems() -> K.IKProblems:
    panda = genplan.load("panda")
    task = load_task("panda_ik", panda)
    from genplan.samplers.data import valid_configurations

    valid = valid_configurations(panda, 6, 2000, progress=False, task=task)
    return K.problems(panda, task, valid, panda.random_configurations(6, 3000))


def test_the_success_test_accepts_the_targets_own_configurations_and_nothing_off_them(panda_problems) -> None:
    pb = panda_problems
    q = genplan.solve_ik(pb.robot, pb.task, pb.positions, init=pb.starts, restarts=20, parallel=False).q
    ok = K.success(pb, q)
    assert ok.any()
    off = q.copy()
    off[:, 0] += 0.05  # moves the hand by centimetres
    assert not K.success(pb, off).any()
    beyond = q.copy()
    beyond[:, 3] = pb.robot.upper[3] + 1e-3  # outside a joint limit
    assert not K.success(pb, beyond).any()
    nan = q.copy()
    nan[0, 0] = np.nan
    assert not K.success(pb, nan)[0]
    # the free axis: a rotation of the hand about it keeps the orientation term satisfied
    assert pb.free_axis == (0, -1.0)
    local, world = pb.axis
    assert np.allclose(pb.rotations @ local, world, atol=1e-3)


def test_a_missing_peer_names_the_extra(panda_problems, monkeypatch) -> None:
    for name in ("pink", "daqp", "ikpy", "pytorch_kinematics"):
        monkeypatch.setitem(sys.modules, name, None)  # import raises ImportError
    for mod in (pink, ikpy, pytorch_kinematics):
        assert not mod.available()
        with pytest.raises(MissingExtraError, match=r"genplan\[peers\]"):
            mod.solve(panda_problems.take(np.arange(1)))
    monkeypatch.setenv(placo.ENV, "/nonexistent/python")
    assert not placo.available()
    with pytest.raises(MissingExtraError, match="placo-python"):
        placo.solve(panda_problems.take(np.arange(1)))


def test_quick_run_without_the_peers_skips_them_with_the_extra(monkeypatch, tmp_path) -> None:
    for mod in PEERS.values():
        monkeypatch.setattr(mod, "available", lambda *a: False)
    out, md = tmp_path / "peers.json", tmp_path / "peers.md"
    assert main(["bench", "peers", "--quick", "--repeats", "1", "--only", "ik,plan", "--out", str(out),
                 "--markdown", str(md)]) == 0
    payload = json.loads(out.read_text())
    assert set(payload["skipped"]) == set(PEERS)
    assert all("genplan[peers]" in v or "placo" in v for v in payload["skipped"].values())
    ik = payload["ik"]["panda"]["solvers"]
    assert list(ik) == ["genplan", "genplan_paper_solver", "genplan_retries"] and ik["genplan"]["problems"] == bench.QUICK.ik_targets
    assert list(payload["ik"]["talos"]["solvers"]) == ["genplan", "genplan_paper_solver", "genplan_retries"]
    # solve_ik's retries (uniform redraws) solve about what one attempt from the same start does, or
    # more (one target of slack: its 5 ms budget may cut the retries on a loaded machine)
    assert ik["genplan_retries"]["success_percent"] >= ik["genplan"]["success_percent"] - 100 / bench.QUICK.ik_targets
    assert payload["ik"]["talos"]["starts"].startswith("GAN")
    plan = payload["plan"]
    assert plan["same_answers"] and plan["same_plans"]
    assert plan["obstacles"][str(bench.QUICK.obstacles[1])] == plan["obstacles"]["0"] + bench.QUICK.obstacles[1]
    text = md.read_text()
    assert "skipped" in text and "genplan[peers]" in text and "extra boxes" in text


def test_quick_run_with_the_installed_peers(tmp_path) -> None:
    pytest.importorskip("pink")
    pytest.importorskip("daqp")
    out = tmp_path / "peers.json"
    payload = bench.run(list(bench.SECTIONS), bench.QUICK, repeats=1, seed=0)
    solvers = payload["ik"]["panda"]["solvers"]
    assert "pink" in solvers and 0 <= solvers["pink"]["success_percent"] <= 100
    assert solvers["genplan"]["success_percent"] > 0
    assert "pink" in payload["ik"]["talos"]["solvers"]  # the whole-body task: soles as constraints
    if placo.available():  # placo runs in its own interpreter ($GENPLAN_PLACO_PYTHON)
        assert "placo" in solvers and "placo" in payload["ik"]["talos"]["solvers"]
    fk = payload["fk"]
    assert {"genplan", "pinocchio"} == set(fk["panda_hand_single"])
    assert {"genplan_1_thread", "genplan_2_thread", "genplan_1_thread_out", "genplan_2_thread_out",
            "pinocchio_loop"} == set(fk["talos_all_links_batch"])
    for name in ("panda", "talos"):
        col = payload["collision"][name]
        assert col["agreement_hulls"]["agreement"] >= 0.99
        assert all(abs(d["distance"]) <= 1e-3 for d in col["agreement_hulls"]["disagreements"])
        timings = col["timings_us_per_config"]
        assert "coal_hulls_broad_phase_2_thread" in timings and "coal_meshes_python_loop" in timings
        assert all(v["median"] > 0 for v in timings.values())
    assert payload["collision"]["panda"]["pairs"]["obstacles"] == 1  # the shelf scene's table
    rows = bench.summary_rows(payload)
    assert any(r[0].startswith("Panda hand FK, one call") for r in rows)
    write_json(out, payload)
    assert json.loads(out.read_text())["benchmark"] == "peers"


def test_the_table_is_the_scene_files_and_coal_gets_the_same_pairs() -> None:
    panda = genplan.load("panda")
    world = bench.collision_world(panda)
    geom = bench.coal_model(panda, hulls=True)
    assert world.obstacle_names == [bench.TABLE]
    robot_geoms = geom.ngeoms - 1
    assert len(geom.collisionPairs) == len(world.self_pairs) + robot_geoms


def test_only_takes_known_sections(capsys) -> None:
    assert main(["bench", "peers", "--only", "fk,bogus"]) == 2
    assert "fk,collision,ik,plan" in capsys.readouterr().err
