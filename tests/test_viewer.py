"""The HTML path viewer: a short Panda path exported to one self-contained file (nothing it
references is outside the file), with the robot's meshes, the obstacles and the animation inside,
the animation's poses matching Pinocchio's; bad input raises clear errors; viser's server is
stopped whatever happens."""

from __future__ import annotations

import base64
import json
import os
import re
import shutil
import signal
import subprocess
import threading
import time
from pathlib import Path
from typing import Any

import numpy as np
import pinocchio as pin
import pytest

pytest.importorskip("viser")
zstandard = pytest.importorskip("zstandard")
msgspec = pytest.importorskip("msgspec")

from genplan import viewer  # noqa: E402
from genplan.errors import GenplanError, NonFiniteError, SettingsError, ShapeError, UnknownNameError  # noqa: E402
from genplan.planning import environment  # noqa: E402

N_STATES = 5
FPS = 10.0


def decode_scene(page: str) -> dict[str, Any]:
    """The scene recording embedded in the page (viser's format: base64 of [u64 size][zstd of
    [u64 msgpack length][msgpack][binary buffers]])."""
    m = re.search(r'window\.__VISER_EMBED_DATA__="([A-Za-z0-9+/=]*)"', page)
    assert m, "no embedded scene in the page"
    raw = base64.b64decode(m.group(1))
    size = int.from_bytes(raw[:8], "little")
    inner = zstandard.ZstdDecompressor().decompress(raw[8:], max_output_size=size)
    n = int.from_bytes(inner[:8], "little")
    return msgspec.msgpack.decode(inner[8 : 8 + n])


def short_path(panda) -> np.ndarray:
    q0 = panda.q_default
    return np.linspace(q0, q0 + np.array([0.4, -0.3, 0.2, 0.3, -0.2, 0.4, 0.1]), N_STATES)


@pytest.fixture(scope="module")
def exported(panda, tmp_path_factory):
    env = environment("panda_shelf")
    out = tmp_path_factory.mktemp("viewer") / "sub" / "plan.html"
    threads_before = threading.active_count()
    t0 = time.perf_counter()
    path = short_path(panda)
    result = viewer.export_html(panda, path, out, boxes=env.boxes, halfspaces=env.halfspaces, fps=FPS,
                                title="panda <test>")
    elapsed = time.perf_counter() - t0
    page = out.read_text(encoding="utf-8")
    return result, out, page, decode_scene(page), path, env, elapsed, threads_before


def test_writes_one_html_file(exported):
    result, out, page, _, _, _, elapsed, _ = exported
    assert result == out and out.is_file()
    assert page.lstrip().lower().startswith("<!doctype html>")
    assert "<title>panda &lt;test&gt;</title>" in page
    assert 'id="genplan-legend"' in page
    assert 0.5e6 < out.stat().st_size < 8e6, out.stat().st_size
    assert elapsed < 15.0
    umask = os.umask(0)
    os.umask(umask)
    assert out.stat().st_mode & 0o777 == 0o666 & ~umask  # a normal file, not mkstemp's private one


def test_is_self_contained(exported):
    """Nothing outside the file: no src/href but data: URIs, no http(s) URL except XML namespace
    ids, no URL in the scene data; the client code and the scene are inline."""
    _, _, page, scene, _, _, _, _ = exported
    refs = re.findall(r"""\b(?:src|href)\s*=\s*["']?([^"'\s>]+)""", page, flags=re.I)
    assert all(r.startswith("data:") or r.startswith("#") for r in refs), refs
    urls = set(re.findall(r"https?://[^\s\"'<>)]+", page))
    assert urls <= {"http://www.w3.org/2000/svg"}, urls
    assert "@import" not in page
    assert not re.search(r"url\(\s*['\"]?(?!data:|#)", page)
    assert "http" not in json.dumps(scene["messages"])
    assert page.count("<script") >= 2 and "</script>" in page  # the packed client and the scene data


def test_contains_robot_obstacles_and_animation(exported, panda):
    _, _, _, scene, path, env, _, _ = exported
    messages = [(t, m) for t, m in scene["messages"]]
    by_type: dict[str, list[tuple[float, dict]]] = {}
    for t, m in messages:
        by_type.setdefault(m["type"], []).append((t, m))

    # obstacles: every box with its size and centre, the floor as a grid at z = -0.5
    boxes = {m["name"]: m for _, m in by_type["BoxMessage"]}
    positions0 = {m["name"]: m["position"] for t, m in by_type["SetPositionMessage"] if t == 0.0}
    for b in env.boxes:
        assert np.allclose(boxes[f"/environment/{b.name}"]["props"]["dimensions"], 2 * np.array(b.half_extents))
        assert np.allclose(positions0[f"/environment/{b.name}"], b.center)
    assert np.allclose(positions0["/environment/floor"], [0, 0, -0.5])

    # robot: meshes under every link's joint, with real triangle data
    meshes = [m["name"] for _, m in by_type["MeshMessage"]]
    for link in ["panda_link0", *[f"panda_link{i}" for i in range(1, 8)], "panda_hand", "panda_leftfinger"]:
        assert any(f"/{link}_0" in n for n in meshes), (link, meshes)
    assert sum(scene["binaryBufferLengths"]) > 1e6  # vertices + triangles of ~135k-triangle meshes

    # animation: N_STATES - 1 steps of 1 / FPS, each moving the joints to Pinocchio's placements
    assert scene["durationSeconds"] == pytest.approx(N_STATES / FPS)
    times = sorted({t for t, m in messages if t > 0})
    assert len(times) == N_STATES - 1
    assert times == pytest.approx([(i + 1) / FPS for i in range(N_STATES - 1)])
    last = {m["name"]: m for t, m in messages if t == times[-1] and m["type"] == "SetPositionMessage"}
    data = panda.model.createData()
    pin.forwardKinematics(panda.model, data, path[-1])
    for j in range(2, panda.model.njoints):  # joint 1 turns about its axis: its origin stays put
        name = f"/robot/{panda.model.names[j]}"
        if name in last:
            assert np.allclose(last[name]["position"], data.oMi[j].translation, atol=1e-9)
    assert f"/robot/{panda.model.names[7]}" in last

    # the hand's trail, start and goal markers
    assert by_type["LineSegmentsMessage"][0][1]["name"] == "/trail/path"
    pin.framesForwardKinematics(panda.model, data, path[-1])
    assert np.allclose(positions0["/trail/goal"], data.oMf[panda.frame_id("hand")].translation)


def test_server_threads_stopped(exported):
    *_, threads_before = exported
    assert threading.active_count() <= threads_before


def test_server_stopped_on_error(panda, tmp_path, monkeypatch):
    import viser

    def boom(self):  # noqa: ANN001
        raise RuntimeError("boom")

    monkeypatch.setattr(viser.ViserServer, "get_scene_serializer", boom)
    before = threading.active_count()
    with pytest.raises(RuntimeError, match="boom"):
        viewer.export_html(panda, short_path(panda)[:2], tmp_path / "x.html")
    assert threading.active_count() <= before
    assert not (tmp_path / "x.html").exists()
    assert list(tmp_path.iterdir()) == []


def test_bad_input(panda, tmp_path):
    path = short_path(panda)
    with pytest.raises(ShapeError, match="expected shape"):
        viewer.export_html(panda, path[:, :5], tmp_path / "a.html")
    bad = path.copy()
    bad[2, 3] = np.nan
    with pytest.raises(NonFiniteError, match=r"element \(2, 3\) is not finite"):
        viewer.export_html(panda, bad, tmp_path / "a.html")
    with pytest.raises(ShapeError, match="no configuration"):
        viewer.export_html(panda, np.zeros((0, panda.nq)), tmp_path / "a.html")
    with pytest.raises(SettingsError, match="fps"):
        viewer.export_html(panda, path, tmp_path / "a.html", fps=0)
    with pytest.raises(SettingsError, match="max_frames"):
        viewer.export_html(panda, path, tmp_path / "a.html", max_frames=1)
    with pytest.raises(GenplanError, match="is a directory"):
        viewer.export_html(panda, path, tmp_path)
    (tmp_path / "file").write_text("x")
    with pytest.raises(OSError, match="cannot create the folder"):
        viewer.export_html(panda, path, tmp_path / "file" / "a.html")
    with pytest.raises(GenplanError, match=r"boxes\[0\]"):
        viewer.export_html(panda, path, tmp_path / "a.html", boxes=[object()])
    with pytest.raises(GenplanError, match=r"halfspaces\[0\]"):
        viewer.export_html(panda, path, tmp_path / "a.html", halfspaces=[("f", (0, 0, 0), 1.0)])
    with pytest.raises(UnknownNameError, match="geometry"):
        viewer.export_html(panda, path, tmp_path / "a.html", geometry="nope")
    assert sorted(p.name for p in tmp_path.iterdir()) == ["file"]


def test_subsample_path():
    idx = viewer.subsample_path(np.zeros((1000, 3)), 150)
    assert len(idx) == 150 and idx[0] == 0 and idx[-1] == 999 and np.all(np.diff(idx) > 0)
    assert list(viewer.subsample_path(np.zeros((4, 3)), 150)) == [0, 1, 2, 3]


@pytest.mark.skipif(shutil.which("chromium") is None, reason="chromium is not installed")
def test_opens_offline_in_a_browser(exported, tmp_path):
    """Headless Chromium with every outside address unreachable: the page makes no request but
    for itself and data: URIs, throws no error, and draws a WebGL canvas."""
    websockets_sync = pytest.importorskip("websockets.sync.client")
    _, out, *_ = exported
    proc = subprocess.Popen(
        ["chromium", "--headless=new", "--no-sandbox", "--enable-unsafe-swiftshader", "--use-angle=swiftshader",
         "--window-size=800,600", "--remote-debugging-port=0", "--proxy-server=127.0.0.1:9",
         f"--user-data-dir={tmp_path / 'profile'}", "about:blank"],
        stdout=subprocess.DEVNULL, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )
    try:
        ws_url = None
        deadline = time.monotonic() + 20
        while time.monotonic() < deadline and ws_url is None:
            line = proc.stderr.readline()
            m = re.search(r"DevTools listening on (ws://\S+)", line)
            ws_url = m.group(1) if m else None
        assert ws_url, "chromium did not start"
        import urllib.request

        host = ws_url.split("/")[2]
        tabs = json.load(urllib.request.urlopen(f"http://{host}/json"))
        page_ws = next(t["webSocketDebuggerUrl"] for t in tabs if t["type"] == "page")
        with websockets_sync.connect(page_ws, max_size=2**26) as ws:
            events: list[dict] = []
            ids = iter(range(1, 10**6))

            def call(method: str, **params: Any) -> dict:
                i = next(ids)
                ws.send(json.dumps({"id": i, "method": method, "params": params}))
                while True:
                    msg = json.loads(ws.recv(timeout=30))
                    if msg.get("id") == i:
                        return msg
                    events.append(msg)

            for domain in ("Network", "Runtime", "Page"):
                call(f"{domain}.enable")
            call("Page.navigate", url=out.as_uri())
            drawn_at = None
            end = time.monotonic() + 20
            while time.monotonic() < end and (drawn_at is None or time.monotonic() < drawn_at + 1.5):
                canvas = call("Runtime.evaluate", expression="document.querySelectorAll('canvas').length")
                if drawn_at is None and canvas["result"]["result"].get("value", 0) >= 1:
                    drawn_at = time.monotonic()  # then 1.5 s more for anything loaded late
                try:
                    events.append(json.loads(ws.recv(timeout=0.25)))
                except TimeoutError:
                    pass
        requests = [e["params"]["request"]["url"] for e in events if e.get("method") == "Network.requestWillBeSent"]
        assert requests and all(u == out.as_uri() or u.startswith("data:") for u in requests), requests
        failed = [e["params"] for e in events if e.get("method") == "Network.loadingFailed"]
        assert not failed, failed
        exceptions = [e["params"] for e in events if e.get("method") == "Runtime.exceptionThrown"]
        assert not exceptions, exceptions
        assert canvas["result"]["result"]["value"] >= 1
    finally:
        os.killpg(proc.pid, signal.SIGTERM)
        try:
            proc.wait(10)
        except subprocess.TimeoutExpired:
            os.killpg(proc.pid, signal.SIGKILL)
            proc.wait()


def test_genplan_view_plans_a_paper_environment_and_writes_its_view(tmp_path, capsys) -> None:
    """`genplan view ENV --out F.html`: one query of the environment planned and drawn."""
    from genplan.cli import main

    out = tmp_path / "view" / "shelf.html"
    assert main(["view", "panda_shelf", "--out", str(out), "--sampler", "hybrid", "--seed", "0",
                 "--max-frames", "20"]) == 0
    assert out.is_file() and out.stat().st_size > 100_000
    assert f"{out} (" in capsys.readouterr().out
    assert main(["view", "no_such_env", "--out", str(out)]) == 2  # a usage error, one line
    assert "invalid choice: 'no_such_env'" in capsys.readouterr().err


def test_python_m_genplan_viewer_is_the_deprecated_spelling_of_genplan_view() -> None:
    import sys

    proc = subprocess.run([sys.executable, "-m", "genplan.viewer", "--help"], capture_output=True, text=True)
    assert proc.returncode == 0 and proc.stdout.startswith("usage: genplan view"), proc.stdout + proc.stderr
    assert "DeprecationWarning: python -m genplan.viewer is deprecated" in proc.stderr


@pytest.fixture(scope="module")
def run(panda):
    """A 1 s Panda motion executed without the observer under an unknown load: mm of error."""
    import genplan
    from genplan.control import ControllerSettings
    from tests.test_control import MOTION, UNKNOWN

    log = genplan.execute(panda, MOTION, controller=ControllerSettings(frame="hand", dob=False),
                          disturbances=UNKNOWN, settle=0.1)
    return MOTION, log


def test_a_run_is_drawn_beside_its_plan(panda, run, tmp_path):
    """The executed motion: a second, translucent robot and its own trail, on the plan's clock;
    each frame's poses are Pinocchio's of the plan's and of the run's state at that time."""
    motion, log = run
    out = viewer.export_execution_html(panda, log, tmp_path / "run.html", planned=motion, scene="panda_shelf",
                                       fps=FPS)
    page = out.read_text(encoding="utf-8")
    scene = decode_scene(page)
    assert f"largest error {log.max_tracking_error_mm:.2f} mm" in page and "executed hand path" in page
    messages = scene["messages"]
    meshes = {m["name"]: m for _, m in messages if m["type"] == "MeshMessage"}
    ghost = {n: m for n, m in meshes.items() if n.startswith("/executed/")}
    solid = {n: m for n, m in meshes.items() if n.startswith("/robot/")}
    assert len(ghost) == len(solid) > 10
    assert all(m["props"]["opacity"] == pytest.approx(0.45) for m in ghost.values())
    assert all(m["props"].get("opacity") is None for m in solid.values())
    trails = {m["name"]: m for _, m in messages if m["type"] == "LineSegmentsMessage"}
    assert set(trails) == {"/trail/path", "/executed_trail/path"}

    # the frames: every 1 / FPS over the motion (1 s), the plan's and the run's state at that time
    assert scene["durationSeconds"] == pytest.approx(motion.duration + 1 / FPS)
    times = sorted({t for t, m in messages if t > 0})
    assert times == pytest.approx([(i + 1) / FPS for i in range(int(round(motion.duration * FPS)))])
    last = {m["name"]: m for t, m in messages if t == times[-1] and m["type"] == "SetPositionMessage"}
    data = panda.model.createData()
    a, b = log.motion_start, log.motion_end
    for name, q in (("/robot", motion.q[-1]), ("/executed", log.q[b - 1])):
        pin.forwardKinematics(panda.model, data, q)
        j = 7
        assert np.allclose(last[f"{name}/{panda.model.names[j]}"]["position"], data.oMi[j].translation, atol=1e-9)
    mid = {m["name"]: m for t, m in messages if t == pytest.approx(0.5) and m["type"] == "SetPositionMessage"}
    pin.forwardKinematics(panda.model, data, log.q[a + int(np.searchsorted(log.t[a:b] - log.t[a], 0.5 - 1e-12))])
    assert np.allclose(mid[f"/executed/{panda.model.names[7]}"]["position"], data.oMi[7].translation, atol=1e-9)

    # the run's error shows: the executed hand is mm away from the planned one mid-motion
    pin.forwardKinematics(panda.model, data, motion.q[int(np.searchsorted(motion.t, 0.5 - 1e-12))])
    gap = np.linalg.norm(np.asarray(mid[f"/executed/{panda.model.names[7]}"]["position"]) - data.oMi[7].translation)
    assert 1e-4 < gap < 2e-2

    # without the plan, the run's reference is drawn as the plan: the same motion at 1 kHz
    ref = viewer.export_execution_html(panda, log, tmp_path / "ref.html", fps=FPS)
    last_ref = {m["name"]: m for t, m in decode_scene(ref.read_text(encoding="utf-8"))["messages"]
                if t == times[-1] and m["type"] == "SetPositionMessage"}
    pin.forwardKinematics(panda.model, data, log.q_ref[b - 1])
    assert np.allclose(last_ref[f"/robot/{panda.model.names[7]}"]["position"], data.oMi[7].translation, atol=1e-9)


def test_configurations_beside_configurations(panda, tmp_path):
    """Two untimed paths of other lengths: matched by the fraction of their length."""
    path = short_path(panda)
    other = np.linspace(path[0], path[-1] + 0.05, 9)
    out = viewer.export_html(panda, path, tmp_path / "two.html", executed=other, fps=FPS, ground=False)
    messages = decode_scene(out.read_text(encoding="utf-8"))["messages"]
    times = sorted({t for t, m in messages if t > 0})
    assert len(times) == len(other) - 1  # the longer one's states
    last = {m["name"]: m for t, m in messages if t == times[-1] and m["type"] == "SetPositionMessage"}
    data = panda.model.createData()
    pin.forwardKinematics(panda.model, data, other[-1])
    assert np.allclose(last[f"/executed/{panda.model.names[7]}"]["position"], data.oMi[7].translation, atol=1e-9)


def test_bad_executed_motions(panda, ur5, run, tmp_path):
    motion, log = run
    path = short_path(panda)
    with pytest.raises(SettingsError, match="executed: a timed motion .* got a timed motion beside configurations"):
        viewer.export_html(panda, path, tmp_path / "a.html", executed=log)
    with pytest.raises(SettingsError, match="executed: .* got configurations beside a timed path"):
        viewer.export_html(panda, motion, tmp_path / "a.html", executed=path)
    with pytest.raises(ShapeError, match=r"executed\.q: expected shape"):
        viewer.export_html(panda, motion, tmp_path / "a.html", executed={"t": motion.t, "q": motion.q[:, :6]})
    with pytest.raises(ShapeError, match="executed: a mapping needs 't' and 'q'"):
        viewer.export_html(panda, motion, tmp_path / "a.html", executed={"q": motion.q})
    with pytest.raises(NonFiniteError, match=r"executed\.t"):
        viewer.export_html(panda, motion, tmp_path / "a.html", executed={"t": motion.t * np.nan, "q": motion.q})
    with pytest.raises(ShapeError, match="log: a run of the joints .* not robot 'ur5'"):
        viewer.export_execution_html(ur5, log, tmp_path / "a.html")
    with pytest.raises(SettingsError, match="log: expected an ExecutionLog"):
        viewer.export_execution_html(panda, motion, tmp_path / "a.html")
    assert list(tmp_path.iterdir()) == []


def test_attached_objects_are_drawn_on_their_links(panda):
    """A rod held by the hand is a part on the hand's joint whose vertices, placed by Pinocchio,
    are the rod's corners where the Rust kinematics put the hand."""
    from genplan.scene import Box, Pose

    held = panda.with_attached("rod", Box("rod", (0.015, 0.015, 0.1)), "panda_hand", Pose(position=(0, 0, 0.25)))
    (part,) = viewer._attached_parts(held)
    assert part.name == "rod"
    q = panda.random_configurations(1, rng=3)[0]
    data = panda.model.createData()
    pin.forwardKinematics(panda.model, data, q)
    m = data.oMi[part.joint] * part.placement
    world = part.vertices.astype(np.float64) @ m.rotation.T + m.translation
    hand = held.link_poses(q, ["panda_hand"])[0]
    local = (world - hand[:3, 3]) @ hand[:3, :3]  # in the hand's frame
    assert np.allclose(local.min(axis=0), [-0.015, -0.015, 0.15], atol=1e-6)
    assert np.allclose(local.max(axis=0), [0.015, 0.015, 0.35], atol=1e-6)


def scene_buffers(page: str) -> list[bytes]:
    """The binary buffers after the embedded recording's msgpack (arrays such as a point cloud's
    positions), in the order of ``binaryBufferLengths``, each 8-byte aligned."""
    m = re.search(r'window\.__VISER_EMBED_DATA__="([A-Za-z0-9+/=]*)"', page)
    assert m
    raw = base64.b64decode(m.group(1))
    inner = zstandard.ZstdDecompressor().decompress(raw[8:], max_output_size=int.from_bytes(raw[:8], "little"))
    n = int.from_bytes(inner[:8], "little")
    out, offset = [], 8 + n
    for length in msgspec.msgpack.decode(inner[8 : 8 + n])["binaryBufferLengths"]:
        offset += -offset % 8  # each buffer starts 8-byte aligned (viser's computeBinaryOffsets)
        out.append(inner[offset : offset + length])
        offset += length
    return out


def drawn_clouds(page: str) -> dict[str, tuple[np.ndarray, np.ndarray, float]]:
    """Each point cloud of the page: its points (float32), colours (uint8) and drawn size."""
    buffers = scene_buffers(page)
    out = {}
    for _, m in decode_scene(page)["messages"]:
        if m["type"] == "PointCloudMessage":
            p = m["props"]
            pts = np.frombuffer(buffers[p["points"]["__binary_index"]], dtype=p["points"]["dtype"]).reshape(-1, 3)
            rgb = np.frombuffer(buffers[p["colors"]["__binary_index"]], dtype=p["colors"]["dtype"]).reshape(-1, 3)
            out[m["name"]] = (pts, rgb, p["point_size"])
    return out


def test_point_clouds_are_drawn(panda, tmp_path, monkeypatch):
    """A camera's cloud given as ``clouds`` and a scene's ``[[points]]`` are drawn as point clouds
    in the file: every point where it was given (float32), coloured from low to high, the
    scene's as wide as its balls; a cloud above MAX_CLOUD_POINTS is strided down to it; the
    legend names them."""
    from genplan.scene import HalfSpace, Points, Scene

    pts = np.random.default_rng(0).uniform([0.3, -0.2, 0.0], [0.6, 0.2, 0.4], (1000, 3))
    scene = Scene("with_points", (Points("seen", 0.02, points=tuple(map(tuple, pts[:10].tolist()))),
                                  HalfSpace("floor", (0, 0, 1), -0.5)))
    out = viewer.export_html(panda, short_path(panda), tmp_path / "c.html", clouds={"camera": pts}, scene=scene)
    page = out.read_text(encoding="utf-8")
    clouds = drawn_clouds(page)
    assert set(clouds) == {"/environment/seen", "/environment/camera"}
    cam, rgb, size = clouds["/environment/camera"]
    assert np.array_equal(cam, pts.astype(np.float32)) and size == viewer.CLOUD_POINT_SIZE
    low, high = int(np.argmin(pts[:, 2])), int(np.argmax(pts[:, 2]))
    assert tuple(rgb[low]) == viewer._CLOUD_LOW_COLOR and tuple(rgb[high]) == viewer._CLOUD_HIGH_COLOR
    seen, _, size = clouds["/environment/seen"]
    assert np.array_equal(seen, pts[:10].astype(np.float32)) and size == pytest.approx(0.04)
    assert "point clouds" in page

    monkeypatch.setattr(viewer, "MAX_CLOUD_POINTS", 300)
    out = viewer.export_html(panda, short_path(panda), tmp_path / "d.html", clouds={"camera": pts})
    cam, _, _ = drawn_clouds(out.read_text(encoding="utf-8"))["/environment/camera"]
    assert len(cam) == 250 and np.array_equal(cam, pts[::4].astype(np.float32))


def test_bad_clouds(panda, tmp_path):
    """A bad cloud is refused naming it, before anything is written."""
    path = short_path(panda)
    bad = np.zeros((4, 3))
    bad[2, 1] = np.nan
    with pytest.raises(NonFiniteError, match=r"clouds\['camera'\]: row 2"):
        viewer.export_html(panda, path, tmp_path / "a.html", clouds={"camera": bad})
    with pytest.raises(ShapeError, match=r"clouds\['camera'\].*shape \(4, 2\)"):
        viewer.export_html(panda, path, tmp_path / "a.html", clouds={"camera": np.zeros((4, 2))})
    with pytest.raises(ShapeError, match=r"clouds\['camera'\].*empty"):
        viewer.export_html(panda, path, tmp_path / "a.html", clouds={"camera": np.zeros((0, 3))})
    with pytest.raises(ShapeError, match="clouds: expected a mapping"):
        viewer.export_html(panda, path, tmp_path / "a.html", clouds=np.zeros((4, 3)))  # type: ignore[arg-type]
    assert not (tmp_path / "a.html").exists()


@pytest.mark.parametrize("shape", ["hull", "mesh", "decomposed"])
def test_mesh_obstacles_are_drawn_as_collision_keeps_them(tmp_path, shape):
    """A non-convex mesh (an L of two cubes) is drawn as its convex hull when the scene keeps it
    as one, and as its own triangles when it is kept as a mesh or decomposed: the drawing never
    shows a filled corner the planner treats as free."""
    import trimesh

    from genplan.scene import Mesh, Pose, Scene

    ell = trimesh.util.concatenate([trimesh.creation.box(extents=(1, 1, 1)),
                                    trimesh.creation.box(extents=(1, 1, 1), transform=trimesh.transformations.translation_matrix((1, 0, 0))),
                                    trimesh.creation.box(extents=(1, 1, 1), transform=trimesh.transformations.translation_matrix((0, 1, 0)))])
    path = tmp_path / "ell.obj"
    ell.export(path)
    scene = Scene(name="ell", obstacles=(Mesh("ell", path, scale=(0.1, 0.1, 0.1), pose=Pose(position=(0.5, 0, 0.2)), shape=shape),))
    _, ((name, v, f),) = viewer._scene_shapes(scene)
    drawn = trimesh.Trimesh(v, f)
    expected = (ell.convex_hull if shape == "hull" else ell).volume * 1e-3
    assert name == "ell"
    assert drawn.volume == pytest.approx(expected, rel=1e-6)
    assert np.allclose(drawn.bounds, [[0.45, -0.05, 0.15], [0.65, 0.15, 0.25]], atol=1e-6)
