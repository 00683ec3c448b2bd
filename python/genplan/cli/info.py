"""``genplan info``: the versions of genplan, its Rust core and its dependencies, and every preset
robot loaded (degrees of freedom, collision geometries, self pairs, frames, load time).
"""

from __future__ import annotations

import argparse
import importlib.metadata
import platform
import time

from genplan.cli.args import FAILED


def add_arguments(p: argparse.ArgumentParser) -> None:
    """``genplan info`` takes no arguments."""


def _version(dist: str) -> str:
    try:
        return importlib.metadata.version(dist)
    except importlib.metadata.PackageNotFoundError:
        return "not installed"


def main(args: argparse.Namespace) -> int:
    """Print versions and the robots genplan can load."""
    import genplan
    from genplan import robots

    print(f"genplan {genplan.__version__}  (python {platform.python_version()}, {platform.machine()})")
    crates = ", ".join(f"{k} {v}" for k, v in sorted(genplan.CRATE_VERSIONS.items()))
    print(f"  rust core: {crates}")
    for dist in ("numpy", "pin", "coal", "example-robot-data", "torch", "safetensors", "ompl", "casadi", "viser"):
        print(f"  {dist:<19}{_version(dist)}")
    try:
        root = robots.robots_dir()
    except FileNotFoundError as exc:
        print(f"robots: {exc}")
        return FAILED
    print(f"robots ({root}):")
    status = 0
    for name in robots.ROBOT_NAMES:
        t0 = time.perf_counter()
        try:
            robot = robots.load(name)
            world = robot.collision_world()
        except Exception as exc:  # report every robot, then fail
            print(f"  {name:<6} FAILED: {exc}")
            status = FAILED
            continue
        ms = (time.perf_counter() - t0) * 1e3
        frames = ", ".join(f"{k}={v}" for k, v in robot.frames.items())
        print(
            f"  {name:<6} nq={robot.nq:<3} nv={robot.nv:<3} joints={len(robot.joint_names):<3}"
            f" collision geometries={len(world.geometry_names):<3} self pairs={len(world.self_pairs):<4}"
            f" loaded in {ms:.0f} ms  frames: {frames}"
        )
    return status
