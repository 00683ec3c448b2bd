"""The papers' experiments, apart from the library: they import genplan, genplan never imports them.

* :mod:`genplan.experiments.benchmarks` -- what ``genplan bench ...`` runs: each prints its table
  and writes JSON (Table I, Table II, GAN coverage, latent adjustment, the controller).
* :mod:`genplan.experiments.peers` -- the peers measured beside genplan: OMPL, CasADi + IPOPT,
  scipy ``least_squares``.
* :mod:`genplan.experiments.report` (and ``report_seq2seq``) -- ``genplan report``: report.md from
  the benchmarks' JSON.
* :mod:`genplan.experiments.reproduce` -- ``genplan reproduce``: every benchmark, then the report.
* :mod:`genplan.experiments.figures_seq2seq` and :mod:`genplan.experiments.common` -- the seq2seq
  paper's figures; machine description, JSON output and tables shared by the above.
"""
