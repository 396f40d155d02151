"""The named layout of the fused step's buffers: every entry has exactly one name."""

import numpy as np
import pytest

from pbvs_pin.control import layout

SIZE = layout.Sizes(n=5, r=3, nv=6, n_arm=3, n_support=4)


@pytest.fixture
def indices():
    return layout.pack_indices(SIZE, np.array([0, 1, 3]), np.array([3, 4, 6]), np.array([0, 1, 0]))


def _covered_once(buffer, views):
    """Each entry of ``buffer`` lies in exactly one of ``views`` (views of ``buffer``)."""
    buffer[:] = np.arange(buffer.size)
    counts = np.zeros(buffer.size, dtype=int)
    for view in views:
        assert np.shares_memory(view, buffer)
        counts[view.ravel().astype(int)] += 1
    np.testing.assert_array_equal(counts, np.ones(buffer.size, dtype=int))


def test_parameter_fields_tile_the_float_buffer(indices):
    params = np.zeros(layout.parameter_size(indices))
    views = layout.parameter_views(params, indices)
    _covered_once(params, views)
    assert views.weight_inverse.shape == (5, 5)
    assert views.selection.shape == (6, 5)
    assert views.posture_target.shape == (3,)
    assert views.support_normals.shape == (4, 2)
    assert views.support_offsets.shape == (4,)
    assert views.support_barrier_offsets.shape == (4,)


def test_state_fields_tile_the_state_buffer(indices):
    state = np.zeros(layout.state_size(indices))
    views = layout.state_views(state, indices)
    _covered_once(state, views)
    assert views.jacobian.shape == (3, 5)
    assert views.object_jacobian.shape == (3, 3)


def test_index_fields_follow_the_sizes(indices):
    assert tuple(layout.sizes(indices)) == (5, 3, 6, 3, 4)
    views = layout.index_views(indices)
    np.testing.assert_array_equal(views.rows, [0, 1, 3])
    np.testing.assert_array_equal(views.arm_q_indices, [3, 4, 6])
    np.testing.assert_array_equal(views.arm_continuous, [0, 1, 0])


def test_settings_written_by_name_are_read_by_name(indices):
    params = np.zeros(layout.parameter_size(indices))
    block = layout.parameter_views(params, indices).settings
    block[:] = layout.Settings(
        focal=600.0,
        feature_scale=150.0,
        feedback_law=1,
        derivative_time_constant=0.05,
        n_base=2,
        joint_limits=True,
        limit_margin=0.2,
        limit_gain=2.0,
        upright=True,
        upright_rate=0.2,
        camera_period=0.04,
        loop_gain_margin=1.5,
        support_gain=10.0,
        support_d0=0.8,
    )
    read = layout.settings(block)
    assert read.focal == 600.0
    assert read.feedback_law == 1
    assert read.n_base == 2
    assert read.posture is False
    assert read.posture_gain == 0.0
    assert (read.joint_limits, read.limit_margin, read.limit_gain) == (True, 0.2, 2.0)
    assert read.obstacle is False
    assert read.upright is True
    assert (read.upright_rate, read.camera_period, read.loop_gain_margin) == (0.2, 0.04, 1.5)
    assert (read.support_gain, read.support_turn_gain, read.support_d0) == (10.0, 0.0, 0.8)


def test_step_scalars_stored_by_name_are_read_by_name(indices):
    state = np.zeros(layout.state_size(indices))
    block = layout.state_views(state, indices).scalars
    values = layout.StepScalars(
        has_previous=1.0, valid=1.0, storage=0.3, sigma_min=0.02, damped=1.0, factor=0.5, v2=0.1,
        loop_gain=0.7, gain_factor=1.0, sigma_phi=0.3, upright_weight=1.0, upright_angle=-0.1, seen=1.0,
    )  # fmt: skip
    layout.store(block, values)
    assert layout.step_scalars(block) == values
    assert block[layout.slot(layout.StepScalars, "v2")] == 0.1
    assert block[layout.slot(layout.StepScalars, "seen")] == 1.0
