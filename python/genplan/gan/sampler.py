"""Deprecated alias of :mod:`genplan.samplers.sampler` (one release)."""

from genplan.gan import alias_module

alias_module(__name__, "genplan.samplers.sampler")
