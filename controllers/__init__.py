"""Controllers: map an observation of the drilling cell to an action; SB3's ``predict`` protocol.

``make_controller("li2023:kp=1.0")`` builds one from a spec; ``CONTROLLERS`` lists the names.
"""

from drillgym.controllers.base import Controller
from drillgym.controllers.li2023 import Li2023Config, Li2023Controller
from drillgym.controllers.none import NoCompensation, NoCompensationConfig
from drillgym.controllers.registry import CONTROLLERS, make_controller, parse_spec
from drillgym.controllers.zhang2005 import Zhang2005Config, Zhang2005Controller

__all__ = [
    "CONTROLLERS",
    "Controller",
    "Li2023Config",
    "Li2023Controller",
    "NoCompensation",
    "NoCompensationConfig",
    "Zhang2005Config",
    "Zhang2005Controller",
    "make_controller",
    "parse_spec",
]
