"""core.encoder_modes: one decoder per input mode, the same for the nodes and the bag reader."""

import math

import numpy as np
from tracked_kinematics.core.encoder_modes import (
    encoder_decoder, ENCODER_DECODERS, JointStatesDecoder, TICK_BITS)
from tracked_kinematics.offline.bags import EncoderSource
from tracked_kinematics.params import (ENCODER_INPUT_DEFAULTS, INPUT_MODES, JOINT_STATES_TOPIC,
                                       SIDE_TOPICS)


def test_the_parameter_table_lists_the_decoders():
    assert INPUT_MODES == tuple(ENCODER_DECODERS)
    assert SIDE_TOPICS == {m: d.topics for m, d in ENCODER_DECODERS.items() if d.per_side}
    assert JOINT_STATES_TOPIC == JointStatesDecoder.topics[0]


def test_node_and_bag_build_the_same_decoder():
    for mode in INPUT_MODES:
        node = encoder_decoder({**ENCODER_INPUT_DEFAULTS, 'input_mode': mode,
                                'sprocket_radius': 0.1})
        bag = EncoderSource(mode=mode, sprocket_radius=0.1).decoder()
        assert type(node) is type(bag)
        assert node.factor == bag.factor and node.per_side == bag.per_side


def test_joint_states_reading_positions_else_velocities():
    decoder = JointStatesDecoder(['a', 'b'], ['c'], 0.1)
    index = decoder.index(['c', 'a', 'x', 'b'])
    assert index == ([1, 3], [0])
    assert decoder.index(['a', 'b']) is None and decoder.missing(['a', 'b']) == ['c']
    assert decoder.reading(index, 4, [3.0, 1.0, 0.0, 2.0], []) == ('position', 1.5, 3.0)
    nan = math.nan
    assert decoder.reading(index, 4, [3.0, nan, 0.0, 2.0], [5.0, 1.0, 0.0, 1.0]) == (
        'velocity', 1.0, 5.0)
    kind, left, _ = decoder.reading(index, 4, [3.0, nan, 0.0, 2.0], [])
    assert kind == 'position' and math.isnan(left)   # the tracker skips it as non-finite
    assert decoder.reading(index, 4, [1.0], [2.0]) is None


def test_ticks_travel_wraps_at_the_message_width():
    decoder = encoder_decoder({'input_mode': 'encoder_ticks', 'sprocket_radius': 0.5,
                               'ticks_per_revolution': 2 * math.pi})
    assert decoder.message_types == tuple(TICK_BITS) and decoder.factor == 0.5
    counts = np.array([2**31 - 2, -2**31 + 1], dtype=float)
    np.testing.assert_allclose(decoder.travel(None, counts, 'std_msgs/msg/Int32'), [0.0, 1.5])
