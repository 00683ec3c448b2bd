"""Execute spatula trajectories with the 1 kHz task-space P-D + disturbance-observer controller on
the simulated UR5 (friction, an unknown 0.3 kg payload and a torque offset in the plant), and see
whether the pancake stays on the spatula.

First a mild tilt, gentle and hasty. Then the seq2seq paper's turn-over (Section 5): the move to
[0, 0, -3 pi / 4] adjusted on the shipped model's latent vector for the paper's J2, and for J2
with execution margins (genplan.pancake.J2Executable), whose plan keeps the pancake until the
flip at the end of the motion.

    python examples/04_execute_with_the_controller.py
"""

from __future__ import annotations

import math

import numpy as np

from genplan.pancake import J2, J2Executable, adjust, control, linear, s_curve


def report(name: str, log: control.SpatulaLog) -> None:
    print(f"{name:28s} tracking error {log.max_tracking_error_mm:6.2f} mm / {log.max_tracking_error_deg:5.2f} deg, "
          f"max |phi| {log.max_abs_phi_deg:5.1f} deg, pancake {'slipped' if log.slipped else 'stayed'}")


def main() -> None:
    disturbances = control.reference_disturbances()
    gentle = s_curve([0.0, 0.0, 0.0], [0.08, 0.05, -0.6], K=800)   # 0.8 s, a mild tilt
    hasty = s_curve([0.0, 0.0, 0.0], [0.08, 0.05, -0.6], K=150)    # the same move in 0.15 s
    for name, traj in (("gentle", gentle), ("hasty", hasty)):
        for dob in (True, False):
            log = control.execute(traj, dob=dob, disturbances=disturbances, settle=0.5, tail=0.1)
            report(f"{name}, DOB {'on' if dob else 'off'}", log)

    # the turn-over: 0.5 s at constant velocity is far too fast; adjust it (shipped seq2seq model)
    x_in = linear([0.0, 0.0, 0.0], [0.0, 0.0, -0.75 * math.pi])
    paper = adjust(x_in, J2(), method="latent", updates=20)                          # the paper's 20 updates
    margins = adjust(x_in, J2Executable(), method="latent", updates=500, step="adam")
    for name, traj in (("turn-over, unadjusted", x_in), ("turn-over, J2", paper.p[0]),
                       ("turn-over, J2Executable", margins.p[0])):
        report(name, control.execute(traj, disturbances=disturbances, settle=0.5, tail=0.1))
    end = margins.p[0, -1]
    print(f"J2Executable plan: ends {1e3 * math.hypot(end[0], end[1]):.0f} mm from the start at "
          f"{math.degrees(end[2]):.0f} deg, planned max |phi| {math.degrees(float(np.abs(margins.phi[0]).max())):.1f} deg")


if __name__ == "__main__":
    main()
