"""The one root exception of rover_sim."""

from __future__ import annotations


class RoverSimError(ValueError):
    """Bad input to the rover world: a config value, a command, a fault or a task name.

    The message always names the offending value.
    """
