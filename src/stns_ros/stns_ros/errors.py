"""The one root exception of stns_ros."""


class StnsRosError(Exception):
    """A bad config, scenario, parameter or bag; the message names the offending value."""
