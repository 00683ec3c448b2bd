"""The ``genplan`` command line."""

from __future__ import annotations

import argparse
import importlib
import importlib.metadata
import platform
import sys
import time
from collections.abc import Sequence
from pathlib import Path


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def cmd_info(args: argparse.Namespace) -> int:
    """Print versions and the robots genplan can load."""
    from genplan import _core, robots

    print(f"genplan {_core.__version__}  (python {platform.python_version()}, {platform.machine()})")
    crates = ", ".join(f"{k} {v}" for k, v in sorted(_core.CRATE_VERSIONS.items()))
    print(f"  rust core: {crates}")
    for dist in ("numpy", "pin", "coal", "example-robot-data", "torch", "safetensors"):
        print(f"  {dist:<19}{_version(dist)}")
    try:
        root = robots.robots_dir()
    except FileNotFoundError as exc:
        print(f"robots: {exc}")
        return 1
    print(f"robots ({root}):")
    status = 0
    for name in robots.ROBOT_NAMES:
        t0 = time.perf_counter()
        try:
            robot = robots.load(name)
            world = robot.collision_world()
        except Exception as exc:  # report every robot, then fail
            print(f"  {name:<6} FAILED: {exc}")
            status = 1
            continue
        ms = (time.perf_counter() - t0) * 1e3
        frames = ", ".join(f"{k}={v}" for k, v in robot.frames.items())
        print(
            f"  {name:<6} nq={robot.nq:<3} nv={robot.nv:<3} joints={len(robot.joint_names):<3}"
            f" collision geometries={len(world.geometry_names):<3} self pairs={len(world.self_pairs):<4}"
            f" loaded in {ms:.0f} ms  frames: {frames}"
        )
    return status


def _lazy(module: str, attr: str):  # type: ignore[no-untyped-def]
    """A command that imports its (torch-heavy) module only when it runs."""

    def run(args: argparse.Namespace) -> int:
        return int(getattr(importlib.import_module(module), attr)(args))

    return run


def _doc(module: str) -> str:
    """A module's docstring without importing it (keeps `genplan --help` fast)."""
    import ast
    import importlib.util

    spec = importlib.util.find_spec(module)
    if spec is None or spec.origin is None:
        return ""
    return ast.get_docstring(ast.parse(Path(spec.origin).read_text())) or ""


def build_parser() -> argparse.ArgumentParser:
    parser = argparse.ArgumentParser(
        prog="genplan",
        description="Learned, constraint-aware robot motion generation (GAN samplers, constrained "
        "IK and planning, latent trajectory adjustment) with a Rust core.",
    )
    sub = parser.add_subparsers(dest="command", metavar="COMMAND")
    p = sub.add_parser("info", help="print versions and the robots found")
    p.set_defaults(func=cmd_info)

    bench = sub.add_parser("bench", help="run a benchmark: print its table, write JSON")
    bench_sub = bench.add_subparsers(dest="benchmark", metavar="BENCHMARK", required=True)
    from genplan.benchmarks import projection as bench_projection

    p = bench_sub.add_parser("projection", help="Table I: projection and IK (Gauss-Newton or scipy)",
                             description=bench_projection.__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    bench_projection.add_arguments(p)
    p.set_defaults(func=bench_projection.main)

    p = bench_sub.add_parser("coverage", help="GAN coverage: planar arm (N_net 1 vs 5), Panda/Talos ablations",
                             description=_doc("genplan.benchmarks.coverage"),
                             formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--quick", action="store_true", help="fewer iterations (planar 1,500, robots 1,500)")
    p.add_argument("--robots", nargs="*", default=["panda", "talos"], choices=["panda", "talos"])
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--figures", type=Path, default=Path("benches/results"), help="folder for the PNG figures")
    p.add_argument("--out", type=Path, default=None, help="write the results as JSON")
    p.set_defaults(func=_lazy("genplan.benchmarks.coverage", "main"))

    train = sub.add_parser("train", help="train a model (written to models/ with a JSON card)")
    train_sub = train.add_subparsers(dest="model", metavar="MODEL", required=True)
    from genplan.gan import train_cli as gan_train

    p = train_sub.add_parser("gan", help="the conditional ensemble GAN of valid configurations")
    gan_train.add_arguments(p)
    p.set_defaults(func=gan_train.main)
    return parser


def main(argv: Sequence[str] | None = None) -> int:
    parser = build_parser()
    args = parser.parse_args(argv)
    if not hasattr(args, "func"):
        parser.print_help()
        return 2
    return int(args.func(args))


if __name__ == "__main__":
    sys.exit(main())
