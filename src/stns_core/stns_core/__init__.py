"""The STNS learner: situations, classifier, categorical learning, STN, IPRL/PIA planners, agent, save/load.

Public API (docs/INTERFACES.md): ``StnsAgent``, ``StnsConfig``, ``StepRecord`` and the
``StnsError`` family.
"""

from .agent import StnsAgent
from .config import StnsConfig
from .errors import (
    StnsConfigError,
    StnsDimensionError,
    StnsError,
    StnsInputError,
    StnsStateError,
)
from .records import StepRecord

__all__ = [
    "StnsAgent",
    "StnsConfig",
    "StepRecord",
    "StnsError",
    "StnsConfigError",
    "StnsDimensionError",
    "StnsInputError",
    "StnsStateError",
]
