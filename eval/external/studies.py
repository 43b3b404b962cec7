"""Published bone-drilling thrust forces and torques: the measurements, their conditions and their sources.

Entered as the sources state them (mean ± SD where given); what a source does not state is None, never guessed.
Each :class:`Series` is one study's one material over a sweep: the validation calibrates on its first condition
and predicts the others. A :class:`FeedRatio` is a relative number a source gives without absolute forces.
"""

from __future__ import annotations

from dataclasses import dataclass


@dataclass(frozen=True)
class Condition:
    """One drilling condition and what was measured there.

    Attributes:
        spindle_rpm: spindle speed (rev/min).
        thrust_n, thrust_sd_n: mean thrust force and its SD across specimens (N); SD None where not given.
        torque_nm, torque_sd_nm: mean drilling torque and its SD (N·m); None where not measured.
    """

    spindle_rpm: float
    thrust_n: float
    thrust_sd_n: float | None
    torque_nm: float | None
    torque_sd_nm: float | None


@dataclass(frozen=True)
class Series:
    """One study's one material: a sweep of conditions at fixed drill and feed.

    Attributes:
        study: short key of the study (``macavelia2012``).
        material: the specimen as the source names it.
        bone_preset: the simulator's closest specimen (:data:`drillgym.envs.drilling.bone.BONE_PRESETS`).
        drill_diameter_m: drill diameter (m).
        point_angle_deg: full point angle (deg); None where the source does not give it (118° is then used).
        feed_m_s: feed rate (m/s); None where the source does not give it (the validation then sweeps
            :data:`~drillgym.eval.external.validate.FEED_RANGE_M_S` and counts the worst prediction).
        conditions: the sweep, the calibration condition first.
    """

    study: str
    material: str
    bone_preset: str
    drill_diameter_m: float
    point_angle_deg: float | None
    feed_m_s: float | None
    conditions: tuple[Condition, ...]


@dataclass(frozen=True)
class FeedRatio:
    """A relative feed-rate effect a source states without absolute forces.

    Attributes:
        study, material: as in :class:`Series`.
        drill_diameter_m: the smaller of the study's drills (m), the one its number is quoted for.
        feed_low_m_s, feed_high_m_s: the feed range (m/s).
        thrust_ratio: maximum thrust at the high feed over that at the low one (-).
        spindle_rpm: the spindle speed; None where not confirmed from the source.
    """

    study: str
    material: str
    drill_diameter_m: float
    feed_low_m_s: float
    feed_high_m_s: float
    thrust_ratio: float
    spindle_rpm: float | None


SOURCES = {
    "macavelia2012": (
        "MacAvelia T, Salahi M, Olsen M, Crookshank M, Schemitsch EH, Ghasempoor A, Janabi-Sharifi F, Zdero R. "
        "Biomechanical measurements of surgical drilling force and torque in human versus artificial femurs. "
        "J Biomech Eng 134(12), 2012. Numbers from the abstract: unicortical holes with a 3.2 mm surgical drill "
        "bit on a CNC machine at 120 mm/min, 1000, 1250 and 1500 rpm; 16 human femurs, 5 artificial femurs."
    ),
    "orelaja2020": (
        "Orelaja et al., Journal of Healthcare Engineering 2020, article 8817422 (hindawi.com/journals/jhe/2020/"
        "8817422). Numbers from the abstract: bovine, porcine and artificial femur, 2.5 mm drill bit, 6 mm depth of "
        "cut, 1000 and 1500 rpm; the feed rate is not stated there."
    ),
    "abjs_feed": (
        "Archives of Bone and Joint Surgery, article 16047 (abjs.mums.ac.ir): 10 mm cortical bovine samples, "
        "2.5 and 3.2 mm drills, six feed rates from 0.5 to 3 mm/s. From the abstract: 'MTF increased by 335% ... "
        "by increasing feed rates from 0.5 to 3 mm/sec', read as a ratio of 4.35 (the same abstract's 'decreased by "
        "almost 230%' shows its percentages are loose: read as 3.35, the ratio is further from the model's); the "
        "spindle speed is not in the abstract."
    ),
}
"""Each study's citation and what was read of it."""

SERIES: tuple[Series, ...] = (
    Series(
        "macavelia2012",
        "human femur, cortical",
        "human_femur",
        3.2e-3,
        None,
        2.0e-3,
        (
            Condition(1000, 198.4, 14.2, 0.1863, 0.0169),
            Condition(1250, 180.6, 14.0, 0.1578, 0.0161),
            Condition(1500, 176.3, 11.2, 0.1402, 0.0164),
        ),
    ),
    Series(
        "macavelia2012",
        "artificial femur",
        "sawbones_20pcf",
        3.2e-3,
        None,
        2.0e-3,
        (
            Condition(1000, 87.2, 19.3, 0.0672, 0.0084),
            Condition(1250, 82.2, 11.2, 0.0610, 0.0029),
            Condition(1500, 75.7, 8.8, 0.0533, 0.0029),
        ),
    ),
    Series(
        "orelaja2020",
        "bovine femur",
        "bovine_tibia",
        2.5e-3,
        None,
        None,
        (Condition(1000, 20.07, None, 0.0412, None), Condition(1500, 12.34, None, 0.0242, None)),
    ),
    Series(
        "orelaja2020",
        "porcine femur",
        "porcine_femur",
        2.5e-3,
        None,
        None,
        (Condition(1000, 11.25, None, 0.0370, None), Condition(1500, 8.14, None, 0.0216, None)),
    ),
    Series(
        "orelaja2020",
        "artificial femur",
        "sawbones_20pcf",
        2.5e-3,
        None,
        None,
        (Condition(1000, 5.62, None, 0.0136, None), Condition(1500, 3.86, None, 0.0067, None)),
    ),
)
"""The published sweeps (two independent studies, five materials)."""

FEED_RATIOS: tuple[FeedRatio, ...] = (FeedRatio("abjs_feed", "bovine cortical", 2.5e-3, 0.5e-3, 3.0e-3, 4.35, None),)
"""Relative feed-rate effects."""
