"""``genplan view``: plan one query of a paper environment with the constrained RRT and write its
3D view, one self-contained HTML file that works offline (:func:`genplan.viewer.export_plan_html`).

    genplan view panda_shelf --out panda_shelf.html --sampler hybrid --seed 0

Needs the viewer extra (``pip install 'genplan[viewer]'``). ``genplan plan --html`` draws a plan
of any robot, task and scene the same way.
"""

from __future__ import annotations

import argparse

from genplan.cli import args as A


def add_arguments(p: argparse.ArgumentParser) -> None:
    from genplan.planning import ENVIRONMENT_NAMES, SAMPLERS
    from genplan.viewer import DEFAULT_FPS, DEFAULT_MAX_FRAMES

    p.add_argument("env", choices=ENVIRONMENT_NAMES, help="the paper's environment")
    p.add_argument("--out", type=A.output_file, required=True, help="the HTML file")
    p.add_argument("--sampler", choices=SAMPLERS, default="hybrid")
    p.add_argument("--seed", type=A.seed, default=0, help="the query's and the planner's seed")
    p.add_argument("--fps", type=A.positive_float, default=DEFAULT_FPS, help=f"frames per second (default {DEFAULT_FPS})")
    p.add_argument("--max-frames", type=A.positive_int, default=DEFAULT_MAX_FRAMES,
                   help=f"most states animated (default {DEFAULT_MAX_FRAMES})")


def main(args: argparse.Namespace) -> int:
    from genplan.viewer import export_plan_html

    out = export_plan_html(args.env, args.out, sampler=args.sampler, seed=args.seed, fps=args.fps,
                           max_frames=args.max_frames)
    print(f"{out} ({out.stat().st_size / 1e6:.1f} MB): open it in a browser (works offline)")
    return 0
