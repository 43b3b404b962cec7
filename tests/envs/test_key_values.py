"""The one key=value grammar that controller, effect and scenario specs share."""

import pytest

from drillgym.controllers import make_controller
from drillgym.envs.effects.registry import parse_effect_spec
from drillgym.envs.key_values import convert, split_items, split_named
from drillgym.envs.real.emulator.cli import parse_scenario


def test_items_are_split_and_stripped_and_an_empty_text_is_no_items():
    assert split_items(" kp = 3, y_gain=1.3 ", "spec") == {"kp": "3", "y_gain": "1.3"}
    assert split_items("  ", "spec") == {}
    assert split_named(" li2023 : kp=3 ") == ("li2023", "kp=3")
    assert split_named("none") == ("none", "")


@pytest.mark.parametrize("text", ["kp", "=3", "kp=3,,"])
def test_an_item_without_a_key_and_a_value_is_an_error_naming_it(text):
    with pytest.raises(ValueError, match=r"my spec: expected key=value, got"):
        split_items(text, "my spec")


def test_values_take_their_fields_types_and_bad_ones_name_the_field():
    assert convert("online", "off", bool) is False and convert("online", "Yes", "bool") is True
    assert convert("n", "7", int) == 7 and convert("kp", "2.5", "float") == 2.5 and convert("bone", "x", str) == "x"
    for raw, kind, noun in (("maybe", bool, "a boolean"), ("7.5", int, "an integer"), ("half", float, "a number")):
        with pytest.raises(ValueError, match=f"f={raw!r} is not {noun}"):
            convert("f", raw, kind)


def test_controller_effect_and_scenario_specs_report_the_same_grammar_error():
    for parse, bad in (
        (make_controller, "li2023:kp"),
        (parse_effect_spec, "latency:0.1"),
        (parse_scenario, "beta_deg"),
    ):
        with pytest.raises(ValueError, match="expected key=value"):
            parse(bad)


def test_a_spec_list_splits_on_commas_and_key_values_continue_the_spec_before_them():
    from drillgym.envs.key_values import split_spec_list

    assert split_spec_list("none, li2023:kp=1,ki=0.5 ,li2023", "--x") == ["none", "li2023:kp=1,ki=0.5", "li2023"]
    with pytest.raises(ValueError, match="--x 'kp=1': 'kp=1' has no name before it"):
        split_spec_list("kp=1", "--x")
    with pytest.raises(ValueError, match="--x is empty"):
        split_spec_list(" , ", "--x")
