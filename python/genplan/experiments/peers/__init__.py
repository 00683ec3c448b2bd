"""Peers measured beside genplan on the same problems: :mod:`~genplan.experiments.peers.ompl`
(ProjectedStateSpace + RRTConnect), :mod:`~genplan.experiments.peers.casadi` (CasADi + IPOPT),
:mod:`~genplan.experiments.peers.scipy` (``scipy.optimize.least_squares``)."""
