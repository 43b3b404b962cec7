"""Contract with ur_rtde: fails loudly if a new release changes what the emulator relies on.

The pinned release, the recipes its interfaces set up, the control program's markers and the program parts the
emulator mirrors (by digest). If this fails after a ur_rtde upgrade, re-read the new ``rtde_control.script`` and
``rtde_control_interface.cpp``, adapt ``envs/real/emulator`` and only then update ``envs/real/emulator/contract.py``.
"""

from importlib import metadata

import rtde_control
import rtde_receive

from drillgym.envs.real.emulator import contract


def test_the_pinned_ur_rtde_is_installed():
    assert metadata.version("ur_rtde") == contract.UR_RTDE_VERSION, "ur_rtde changed: re-check the emulator contract"


def test_recipes_and_uploaded_program_match_what_the_emulator_assumes(start_emulator):
    emu = start_emulator()
    r = rtde_receive.RTDEReceiveInterface(emu.host)
    c = rtde_control.RTDEControlInterface(emu.host)
    try:
        seen = emu.control({"cmd": "contract"})
    finally:
        del c, r
    problems = contract.check_contract(seen)
    assert not problems, "ur_rtde no longer matches the emulator:\n" + "\n".join(problems)


def test_the_check_notices_a_changed_program():
    script = "def rtde_control():\n    def signal_ready():\n        write_output_integer_reg(0, 7)\n    end\nend\n"
    problems = contract.check_contract({"output_recipes": [], "input_recipes": [], "script": script})
    assert any("signal_ready changed" in p for p in problems)
    assert any("input recipe 2" in p for p in problems) and any("Script Loaded" in p for p in problems)
