"""tools/causal_pair_floor.py: the causal pair floor on goals whose answer is known in closed
form, and the twins it builds from the generator (no simulation; under a second of CPU)."""

from __future__ import annotations

import numpy as np
from tool_support import load_tool

from hubo_cli.input.operator_stream import StreamSettings, hand_stream

H = 0.025   # the tool's node spacing (s)
A = 0.8     # rad/s^2


def _step_pair(c_a: float, c_b: float, post_nodes: int = 12):
    """A point hand moved by six independent joints (the Jacobian the identity): the goal at 0
    for 0.3 s, then joint 0's goal steps to ``c_a`` on A and to ``c_b`` on B; errors sampled
    on the nodes."""
    t_part = 1.0
    t_pre = t_part - H * np.arange(12, -1, -1)
    t_post = t_part + H * np.arange(1, post_nodes + 1)
    J = np.broadcast_to(np.eye(6), (len(t_post), 6, 6))
    q_a, q_b = np.zeros((len(t_post), 6)), np.zeros((len(t_post), 6))
    q_a[:, 0], q_b[:, 0] = c_a, c_b
    return ((t_pre, t_post, t_post), t_part, np.broadcast_to(np.eye(6), (len(t_pre), 6, 6)),
            np.zeros((len(t_pre), 6)), J, q_a, J, q_b, A)


def test_opposite_steps_cost_what_full_acceleration_from_rest_leaves():
    """Joint 0's goal steps by +0.2 rad on A and -0.2 rad on B. A controller that cannot tell
    them apart until the parting holds the joint at rest on the shared goal (any other shared
    state helps one branch as much as it hurts the other) and then accelerates at the limit:
    on the nodes the relaxation lets the joint reach a H^2 m (m + 1) / 2 after m nodes, so the
    floor is sum over m of (0.2 - a H^2 m (m + 1) / 2)^2 on each branch, the min-max the same
    (never above it: a bound)."""
    tool = load_tool("causal_pair_floor")
    m = np.arange(1, 13)
    closed_form = float(np.sum((0.2 - A * H**2 * m * (m + 1) / 2) ** 2))
    floor = tool.minmax_floor(*_step_pair(0.2, -0.2))
    assert closed_form * (1 - 1e-3) <= floor <= closed_form * (1 + 1e-9), (floor, closed_form)


def test_a_rest_on_both_has_no_floor_and_a_step_against_a_rest_less_than_opposite_steps():
    """A rest on both branches: 0. A step against a rest lies strictly between 0 and the
    opposite steps' floor (the controller may start part of the way before it can tell)."""
    tool = load_tool("causal_pair_floor")
    rest = tool.minmax_floor(*_step_pair(0.0, 0.0))
    one_way = tool.minmax_floor(*_step_pair(0.2, 0.0))
    both_ways = tool.minmax_floor(*_step_pair(0.2, -0.2))
    assert rest <= 1e-12
    assert 0.0 < one_way < both_ways


def test_twins_share_the_streams_past_and_part_where_a_move_starts():
    """The tool's twins of a generated stream: the stream rebuilt from its logged gestures is
    the generator's to the bit, and each twin is the same sample for sample before its parting
    and differs there (the same noise, another gesture)."""
    tool = load_tool("causal_pair_floor")
    settings = StreamSettings(duration_s=1.5, max_speed_m_s=0.25)
    labels = set()
    for seed in (135177642, 8650587, 1398143491):
        for hand in ("right", "left"):
            stream, pairs = tool.twins(hand, seed, settings)
            assert np.array_equal(stream.T_operator_hand,
                                  hand_stream(hand, seed, settings).T_operator_hand)
            for label, t_part, twin in pairs:
                labels.add(label)
                before = stream.t_s < t_part - 1e-9
                assert np.array_equal(twin.T_operator_hand[before],
                                      stream.T_operator_hand[before])
                k = int(np.argmin(np.abs(stream.t_s - t_part)))
                assert not np.array_equal(twin.T_operator_hand[k], stream.T_operator_hand[k])
    assert labels == {"pause", "no-turn", "no-move"}
