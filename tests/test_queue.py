"""EventQueue: pending events taken in (microphone, sample) order, placed in the banks."""

import numpy as np

from mjsound.synth.queue import NONE, EventQueue


def _amp(k, w, base):
    return (base + np.arange(k * w).reshape(k, w)) + 1j * (-base - np.arange(k * w).reshape(k, w))


def _layout():
    # two objects (indices 0 and 2; index 1 was removed), 2 microphones; object 0 has 3 modes,
    # object 2 has 2: bank of a microphone = [obj0 modes | obj2 modes]
    vbase = np.array([0, -1, 2])  # voice = vbase[obj] + mic
    v_rel = np.array([0, 0, 3, 3])  # voice -> column offset in its microphone's bank
    v_len = np.array([3, 3, 2, 2])
    return vbase, v_rel, v_len


def test_take_orders_places_and_keeps_the_rest():
    q = EventQueue(capacity=2)  # small: forces growth
    a0 = _amp(3, 3, 10.0)
    q.push(0, np.array([1, 0, 0]), np.array([7, 9, 7]), np.zeros(3, np.int8), a0)
    a2 = _amp(2, 2, 100.0)
    q.push(2, np.array([0, 0]), np.array([7, 30]), np.array([0, 1], np.int8), a2)
    q.push(1, np.array([0]), np.array([3]), np.zeros(1, np.int8), _amp(1, 4, 500.0))  # removed object
    assert q.count == 6 and q.next_sample == 3
    vbase, v_rel, v_len = _layout()
    ptr, na, kd, re, im = q.take(10, vbase, v_rel, v_len, 2, 5)
    # mic 0: (obj0 n7), (obj2 n7) [queue order], (obj0 n9); mic 1: (obj0 n7)
    np.testing.assert_array_equal(ptr, [0, 3, 4])
    np.testing.assert_array_equal(na, [7, 7, 9, 7])
    np.testing.assert_array_equal(kd, [0, 0, 0, 0])
    np.testing.assert_array_equal(re[0], [a0[2, 0].real, a0[2, 1].real, a0[2, 2].real, 0, 0])
    np.testing.assert_array_equal(re[1], [0, 0, 0, a2[0, 0].real, a2[0, 1].real])
    np.testing.assert_array_equal(im[2, :3], a0[1].imag)
    np.testing.assert_array_equal(re[3, :3], a0[0].real)
    # the event at 30 stays, with its amplitudes, and is taken by a later block
    assert q.count == 1 and q.next_sample == 30
    ptr, na, kd, re, im = q.take(31, vbase, v_rel, v_len, 2, 5)
    np.testing.assert_array_equal(ptr, [0, 1, 1])
    assert na.tolist() == [30] and kd.tolist() == [1]
    np.testing.assert_array_equal(re[0, 3:], a2[1].real)
    assert q.count == 0 and q.next_sample == NONE


def test_drop_object_and_microphones():
    q = EventQueue()
    q.push(0, np.array([0, 1]), np.array([5, 6]), np.zeros(2, np.int8), _amp(2, 3, 1.0))
    q.push(2, np.array([1]), np.array([4]), np.zeros(1, np.int8), _amp(1, 2, 50.0))
    q.drop_object(2)
    assert q.count == 2 and q.next_sample == 5
    q.drop_mics(1)
    assert q.count == 1
    vbase, v_rel, v_len = _layout()
    ptr, na, kd, re, im = q.take(100, vbase, v_rel, v_len, 2, 5)
    np.testing.assert_array_equal(ptr, [0, 1, 1])
    np.testing.assert_array_equal(re[0, :3], [1.0, 2.0, 3.0])
