"""The emulator's RTDE output-rate divider against a table of requested frequencies.

Rule pinned (``envs/real/emulator/rtde_server.py`` and docs/deployment.md): the request is clipped to the CB3's
1-125 Hz and a data package goes out every ``round(125 / f)`` controller cycles (Python's round: halves to even).
UR's RTDE guide (docs.universal-robots.com, "Real-Time Data Exchange (RTDE) Guide") and the PolyScope RTDE
manual page state the controller rates (125 Hz on CB-Series, 500 Hz on e-Series) and that the client asks for
an output frequency, but, in the copies searched for this test, no rule for a frequency that 125 Hz does not
divide: so the table pins the emulator's documented choice, not UR's. The rows marked ``floor differs`` are
the ones a ``floor(125 / f)`` rule (issue 43's proposal) would change; the others hold under either rule.
"""

import pytest

from drillgym.envs.real.emulator.rtde_server import CB3_RATE_HZ, output_divider

TABLE = [
    # requested Hz, cycles between packages
    (125.0, 1),
    (500.0, 1),  # an e-Series rate on a CB3: clipped to 125 Hz
    (100.0, 1),  # 1.25
    (84.0, 1),  # 1.49
    (70.0, 2),  # 1.79: floor differs (1)
    (62.5, 2),
    (50.0, 2),  # 2.5: half to even
    (45.0, 3),  # 2.78: floor differs (2)
    (40.0, 3),  # 3.125
    (30.0, 4),  # 4.17
    (25.0, 5),
    (20.0, 6),  # 6.25
    (10.0, 12),  # 12.5: half to even
    (9.0, 14),  # 13.9: floor differs (13)
    (1.0, 125),
    (0.5, 125),  # clipped to 1 Hz
    (0.0, 125),
]


@pytest.mark.parametrize(("frequency_hz", "divider"), TABLE)
def test_requested_frequency_to_divider(frequency_hz, divider):
    assert CB3_RATE_HZ == 125.0
    assert output_divider(frequency_hz) == divider


def test_the_served_rate_is_the_nearest_125_hz_over_a_whole_number():
    """No whole divider serves a request in 1-125 Hz closer (in cycles) than the chosen one: |125/f − n| ≤ ½."""
    for f in [1.0 + 0.37 * k for k in range(335)]:
        n = output_divider(f)
        assert abs(CB3_RATE_HZ / f - n) <= 0.5 + 1e-12, (f, n)
