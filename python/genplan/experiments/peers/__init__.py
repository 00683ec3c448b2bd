"""Peers measured beside genplan on the same problems: :mod:`~genplan.experiments.peers.ompl`
(ProjectedStateSpace + RRTConnect), :mod:`~genplan.experiments.peers.casadi` (CasADi + IPOPT),
:mod:`~genplan.experiments.peers.scipy` (``scipy.optimize.least_squares``); the IK peers of
``genplan bench peers`` (the ``genplan[peers]`` extra, one problem set and success test:
:mod:`~genplan.experiments.peers.ik`): :mod:`~genplan.experiments.peers.pink` (pin-pink + daqp),
:mod:`~genplan.experiments.peers.placo` (in its own interpreter), :mod:`~genplan.experiments.peers.ikpy`,
:mod:`~genplan.experiments.peers.pytorch_kinematics`."""
