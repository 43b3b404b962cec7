"""Helpers of the controller tests: a drill plan at the cell's entry point and the arm's joints there."""

from __future__ import annotations

from typing import Any

import numpy as np

from drillgym.controllers.models import RobotComplianceModel
from drillgym.envs.cell_params import R_BASE_TASK, CellParams
from drillgym.envs.plan import DrillPlan
from drillgym.envs.robot.ur5 import Q_HOME_RAD, TCP_FRAME
from drillgym.envs.scenario import Scenario

TCP_OFFSET_M = 0.11 + 0.036
"""Sensor-to-chuck plus the default stick-out (m): the drill tip's offset from the flange."""


def _t_base_entry() -> np.ndarray:
    t = np.eye(4)
    t[:3, :3] = R_BASE_TASK
    t[:3, 3] = CellParams().entry_point
    return t


def plan_at_entry(**scenario: Any) -> DrillPlan:
    """The plan of ``Scenario(**scenario)`` with the task frame at the cell's entry point (base frame)."""
    return DrillPlan.from_scenario(Scenario(**scenario), _t_base_entry(), TCP_OFFSET_M)


def q_at_entry() -> np.ndarray:
    """Joint angles (rad) that put the drill tip at the entry point, from the home pose."""
    return RobotComplianceModel(TCP_OFFSET_M).kin.ik(_t_base_entry(), Q_HOME_RAD, TCP_FRAME)
