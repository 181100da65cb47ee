"""A task's tool names its working point in the run's words (hubo_cli.tasks.tool): the drill's
keys and lines as they were, the hand's say hand (review 21: a hand task's stop spoke of the
bit)."""

from types import SimpleNamespace

import numpy as np

from hubo_cli.cli.task import _stop_words
from hubo_cli.tasks.runner import _travel_after
from hubo_cli.tasks.tool import tool_point, travel_keys

DRILL_KEYS = ("bit_along_wall_mm", "bit_into_wall_mm", "bit_out_of_wall_mm")


def _stop(keys, travel=(3.03, 0.0, 12.95)) -> dict:
    """A wrist-torque stop's summary entry (review 21's hand plunge) with travel ``keys``."""
    return {"t_s": 5.24, "sources": ["wrist-torque"], "step": "drill in",
            "finished_step": False, "reverted_to_t_s": None, "retreat_mm": 5.0, "held": True,
            "held_after_s": 0.295, "wrist_torque_nm": 1.224, "wrist_torque_after_nm": 4.496,
            **dict(zip(keys, travel, strict=True))}


def test_the_drills_keys_stay_and_the_hands_say_hand():
    assert travel_keys("drill") == DRILL_KEYS  # read by tests, docs/tasks.md and exports
    assert travel_keys("hand") == ("hand_along_wall_mm", "hand_into_wall_mm",
                                   "hand_out_of_wall_mm")
    assert (tool_point("drill"), tool_point("hand")) == ("bit", "hand")
    for tool in ("drill", "hand"):
        plan = SimpleNamespace(spec=SimpleNamespace(stance=SimpleNamespace(tool=tool)))
        assert _travel_after(None, plan, np.ones(3, dtype=bool)) == dict.fromkeys(
            travel_keys(tool))


def test_the_stop_line_names_the_tool_used():
    drill = _stop_words(_stop(DRILL_KEYS), "drill")
    assert ("braked and backed the bit 5 mm out of the wall and held 0.29 s after the latch; "
            "after the latch: wrist 4.50 N m max, bit 3.0 mm along the wall, 0.0 mm into it"
            ) in drill
    hand = _stop_words(_stop(travel_keys("hand")), "hand")
    assert hand == drill.replace("bit", "hand")
    assert "bit" not in hand
