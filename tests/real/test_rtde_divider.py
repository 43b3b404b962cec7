"""The emulator's RTDE output-rate divider against a table of requested frequencies.

Rule pinned (``envs/real/emulator/rtde_server.py`` and docs/deployment.md §6): the request is clipped to the CB3's
1-125 Hz and a data package goes out every ``floor(125 / f)`` controller cycles, so the served rate is never below
the request. Source: UR's RTDE guide ("Real-Time Data Exchange (RTDE) Guide", RTDE_CONTROL_PACKAGE_SETUP_OUTPUTS,
output frequency), which issue 43 reports documents ``floor(125 / f)`` for CB-Series controllers (500 Hz and
``floor(500 / f)`` on e-Series, which the emulator does not emulate: an e-Series rate on a CB3 is clipped to
125 Hz). The copies of the guide this project could read did not show that passage, and no controller checked it.
The rows marked ``round differs`` are those the emulator's earlier ``round(125 / f)`` served differently.
"""

import math

import pytest

from drillgym.envs.real.emulator.rtde_server import CB3_RATE_HZ, output_divider

TABLE = [
    # requested Hz, cycles between packages
    (125.0, 1),
    (500.0, 1),  # an e-Series rate on a CB3: clipped to 125 Hz
    (math.inf, 1),
    (100.0, 1),  # 1.25
    (84.0, 1),  # 1.49
    (70.0, 1),  # 1.79: round differs (2)
    (62.5, 2),
    (50.0, 2),  # 2.5
    (45.0, 2),  # 2.78: round differs (3)
    (125.0 / 3.0, 3),  # 3 in floating point arithmetic is 2.9999...: the rule must not fall to 2
    (40.0, 3),  # 3.125
    (30.0, 4),  # 4.17
    (25.0, 5),
    (20.0, 6),  # 6.25
    (125.0 / 7.0, 7),  # 6.999... in floating point
    (10.0, 12),  # 12.5
    (9.0, 13),  # 13.9: round differs (14)
    (1.0, 125),
    (0.5, 125),  # clipped to 1 Hz
    (0.0, 125),
    (-5.0, 125),
]


@pytest.mark.parametrize(("frequency_hz", "divider"), TABLE)
def test_requested_frequency_to_divider(frequency_hz, divider):
    assert CB3_RATE_HZ == 125.0
    assert output_divider(frequency_hz) == divider


def test_the_served_rate_is_the_slowest_125_hz_over_a_whole_number_not_below_the_request():
    """125 / n >= f > 125 / (n + 1) for every f in 1-125 Hz: floor's divider, checked on a grid of requests.

    The 1e-9 slack is floating point's: 125 / (125 / n) is n only to within a few ulps.
    """
    for f in [1.0 + 0.37 * k for k in range(335)]:
        n = output_divider(f)
        assert CB3_RATE_HZ / n >= f - 1e-9, (f, n)
        assert CB3_RATE_HZ / (n + 1) < f, (f, n)


def test_a_frequency_that_is_not_a_number_is_refused():
    with pytest.raises(ValueError, match="not a number"):
        output_divider(math.nan)
