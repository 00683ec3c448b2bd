"""Execute spatula trajectories with the 1 kHz task-space P-D + disturbance-observer controller on
the simulated UR5 (friction, an unknown 0.3 kg payload and a torque offset in the plant), and see
whether the pancake stays on the spatula.

    python examples/04_execute_with_the_controller.py
"""

from __future__ import annotations

import numpy as np

from genplan import control
from genplan.pancake import s_curve


def main() -> None:
    disturbances = control.Disturbances.reference()
    gentle = s_curve([0.0, 0.0, 0.0], [0.08, 0.05, -0.6], K=800)   # 0.8 s, a mild tilt
    hasty = s_curve([0.0, 0.0, 0.0], [0.08, 0.05, -0.6], K=150)    # the same move in 0.15 s
    for name, traj in (("gentle", gentle), ("hasty", hasty)):
        for dob in (True, False):
            log = control.execute(traj, dob=dob, disturbances=disturbances, settle=0.5, tail=0.1)
            print(f"{name:6s} DOB {'on ' if dob else 'off'}: tracking error {log.max_tracking_error_mm:6.2f} mm / "
                  f"{log.max_tracking_error_deg:5.2f} deg, max |phi| {np.degrees(np.abs(log.phi).max()):5.1f} deg, "
                  f"pancake {'slipped' if log.slipped else 'stayed'}")


if __name__ == "__main__":
    main()
