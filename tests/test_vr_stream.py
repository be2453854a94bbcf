"""The camera stream's frame schedule (a frame right after each control step) and its depth colour map, without a
simulator; the stream in robosuite's loop is tested in test_vr_device.py."""

from types import SimpleNamespace

import numpy as np
import pytest

from veragmil_suite.devices.vr.render import depth_colormap
from veragmil_suite.devices.vr.stream import POLL_S, frame_decision, step_progress

INTERVAL = 1 / 30  # 30 fps at most
IDLE = 1 / 30


def decide(scene, complete=True, shown=("m", 0.05, 1), now=10.0, last_capture=9.9, expecting=False):
    return frame_decision(now, scene, complete, shown, last_capture, INTERVAL, expecting, IDLE)


def test_a_finished_step_is_rendered_at_once():
    assert decide(("m", 0.10, 2)) == (True, 0.0)
    assert decide(("m2", 0.0, 0)) == (True, 0.0)  # a new model (robosuite's hard reset)
    assert decide(("m", 0.0, 0), shown=None) == (True, 0.0)  # a page connected: a fresh frame


def test_a_step_half_done_is_polled_until_it_finishes():
    assert decide(("m", 0.07, 2), complete=False) == (False, POLL_S)


def test_frames_come_at_most_fps_a_second():
    render, wait = decide(("m", 0.10, 2), now=10.0, last_capture=10.0 - INTERVAL / 4)
    assert not render and wait == pytest.approx(0.75 * INTERVAL)


def test_an_unchanged_scene_waits_idle_unless_a_step_is_expected():
    assert decide(("m", 0.05, 1)) == (False, IDLE)
    assert decide(("m", 0.05, 1), expecting=True) == (False, POLL_S)  # an action was just computed


def test_step_progress_reads_robosuites_step_clock():
    env = SimpleNamespace(timestep=3, cur_time=0.15000000000000002, control_timestep=0.05)
    assert step_progress(env) == (3, True)
    env.cur_time = 0.1  # step() counted timestep up and is in its physics
    assert step_progress(env) == (3, False)
    assert step_progress(SimpleNamespace()) is None  # no step clock: the stream samples on its fps clock


def test_depth_colormap_near_red_far_blue_beyond_black_in_place():
    depth = np.array([[0.1, 0.2, 1.35, 2.49, 2.5, 40.0]])
    colours = depth_colormap(depth, 0.2, 2.5)
    assert colours.shape == (1, 6, 3) and colours.dtype == np.uint8
    near, mid, far = colours[0, 1], colours[0, 2], colours[0, 3]
    assert near[0] > 100 and near[2] < 10  # red
    assert far[2] > 40 and far[0] < 80  # blue
    assert mid[1] > 150  # turbo's middle is green-yellow
    assert (colours[0, 0] == near).all()  # nearer than near: clipped to near
    assert (colours[0, 4:] == 0).all()  # from far on: black
    out = np.zeros((1, 12, 3), np.uint8)
    depth_colormap(depth, 0.2, 2.5, out=out[:, 6:])  # straight into the depth half of the streamed image
    assert (out[:, 6:] == colours).all() and (out[:, :6] == 0).all()
