"""The exceptions of stns_core: one root, one subclass per kind of problem."""

from __future__ import annotations


class StnsError(Exception):
    """Root of every error raised by stns_core."""


class StnsConfigError(StnsError, ValueError):
    """An invalid configuration value, type or key."""


class StnsInputError(StnsError, ValueError):
    """An invalid observation, reward or argument given to the agent."""


class StnsDimensionError(StnsInputError):
    """An observation whose shape does not match the agent's ``obs_dim``."""


class StnsStateError(StnsError):
    """A saved learner file that cannot be read: corrupt, incompatible or missing."""
