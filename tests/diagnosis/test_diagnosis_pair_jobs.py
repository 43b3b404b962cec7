"""Forward selection's pair jobs (eval/diagnosis/diagnose.py): every other candidate on top of each seed single, but
never a second form of the seed's own physics."""

from diagnosis_stubs import stub_score

from drillgym.eval.diagnosis.diagnose import pair_jobs


def test_a_seed_is_paired_with_every_other_physics_but_not_with_another_form_of_its_own():
    import numpy as np

    seed = stub_score(("kinematic_offset",), 5.0, 1.0, 0.5, np.ones(4))
    shared = ["kinematic_offset", "kinematic_offset_trend", "latency", "tool_length"]
    assert [names for names, _ in pair_jobs([seed], shared)] == [
        ("kinematic_offset", "latency"),
        ("kinematic_offset", "tool_length"),
    ]
    trend = stub_score(("kinematic_offset_trend",), 5.0, 1.0, 0.5, np.ones(4))
    assert [names for names, _ in pair_jobs([trend], shared)] == [
        ("kinematic_offset_trend", "latency"),
        ("kinematic_offset_trend", "tool_length"),
    ]
