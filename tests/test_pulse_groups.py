"""A click and its images in the floor rendered in one window (one inverse FFT,
:func:`mjsound.synth.bandlimited.pulse_group`) against the same pulses rendered one by one."""

import numpy as np
import pytest

from mjsound.jit import call_inner
from mjsound.sim.clicks import click_rows
from mjsound.sim.images import ImageSet, mirror_affine
from mjsound.synth import accel_noise as an
from mjsound.synth import bandlimited as bl

FS = 48000


def _click_and_image(height_m, gain=0.7, tau=3e-5, t=0.0101):
    """The click of a 4 cm ball ``height_m`` above the floor z = 0 at a microphone 1 m up and
    at its mirror image, the image's row scaled by ``gain`` into the microphone's channel."""
    mic = np.array([0.3, -0.2, 1.0])
    image = mirror_affine([0, 0, 1], [0, 0, 0])[:, :3] @ mic
    rows = an.click_pulses(np.array([0.0, 0.0, height_m]), np.eye(3), np.full(3, 0.02), np.array([0.0, 0.0, 1.0]),
                           np.stack([mic, image]), t, tau)
    rows[1]["b0"] *= gain
    rows[1]["b1"] *= gain
    rows[1]["channel"] = 0
    rows[1]["joins"] = 1
    return rows


def _rendered(rows, dv=2.0, n=4096):
    track = bl.PulseTrack(int(rows["channel"].max()) + 1, FS)
    track.add(rows, np.full(len(rows), dv))
    return track.take(n)


@pytest.mark.parametrize("height_m", [0.01, 0.05, 0.12])
def test_a_click_and_its_image_in_one_window_match_the_band_limited_closed_form(height_m):
    """One window for both is as exact as a window each: both within 1e-4 of the peak of the
    band-limited integral of the two pulses' spectrum (the renderer's own accuracy: the
    low-pass's tails beyond ``LEAD`` / ``TAIL`` samples are dropped, -70 dB; where each pulse
    sits in its window decides how they alias, so the two renders differ at that level)."""
    from tests.test_accel_noise import _half_sine_accel, _reference_samples

    rows = _click_and_image(height_m)
    end, first, window = call_inner(bl.pulse_group, rows, np.full(2, 2.0), 0, 2, float(FS))
    assert end == 2 and window > 0  # (one window for both)
    assert first == int(np.floor(rows[0]["time_s"] * FS)) - bl.LEAD
    together = _rendered(rows)[0]
    apart = rows.copy()
    apart["joins"] = 0
    separately = _rendered(apart[:1])[0] + _rendered(apart[1:])[0]

    def spectrum(w):
        s = 1j * w
        return sum(_half_sine_accel(w, r["tau_s"], 2.0) * (r["b0"] + r["b1"] * s)
                   / (1 + r["d1"] * s + r["d2"] * s * s) * np.exp(-s * r["time_s"]) for r in rows)

    heard = np.flatnonzero(separately + together)  # (the two windows)
    k = np.arange(heard[0] - 10, heard[-1] + 10)
    ref = _reference_samples(spectrum, k / FS, FS, n_w=200000)
    peak = np.abs(ref).max()
    err_together = np.abs(together[k] - ref).max()
    err_apart = np.abs(separately[k] - ref).max()
    assert err_together < 1e-4 * peak and err_apart < 1e-4 * peak
    assert err_together < 1.05 * err_apart + 1e-6 * peak
    # the image is heard: the sum differs from the direct click by far more than that
    assert np.abs(together - _rendered(apart[:1])[0]).max() > 0.1 * peak


def test_an_image_too_late_for_the_window_is_rendered_alone():
    """Beyond :data:`~mjsound.synth.bandlimited.GROUP_GROWTH` times the direct pulse's window
    the image gets its own (the same samples as without ``joins``)."""
    rows = _click_and_image(0.05)
    rows[1]["time_s"] += 0.05  # 2400 samples later
    end, _, window = call_inner(bl.pulse_group, rows, np.full(2, 2.0), 0, 2, float(FS))
    assert (end, window) == (1, 0)
    apart = rows.copy()
    apart["joins"] = 0
    assert np.array_equal(_rendered(rows), _rendered(apart))


@pytest.mark.parametrize("field, value", [("channel", 1), ("tau_s", 4e-5), ("d1", 1e-5), ("d2", 1e-9)])
def test_joins_only_the_same_pulse_at_the_same_channel(field, value):
    rows = _click_and_image(0.05)
    rows[1][field] = value
    apart = rows.copy()
    apart["joins"] = 0
    assert call_inner(bl.pulse_group, rows, np.full(2, 2.0), 0, 2, float(FS))[0] == 1
    assert np.array_equal(_rendered(rows), _rendered(apart))
    # nor a pulse with another velocity change
    rows = _click_and_image(0.05)
    track = bl.PulseTrack(1, FS)
    track.add(rows, np.array([2.0, 2.5]))
    ref = bl.PulseTrack(1, FS)
    rows["joins"] = 0
    ref.add(rows, np.array([2.0, 2.5]))
    assert np.array_equal(track.take(4096), ref.take(4096))


def test_click_rows_put_each_microphone_before_its_images():
    im = ImageSet(np.array([1, 0, 1]), np.zeros((3, 3, 4)), np.ones((3, 6)), np.array([0.5, 0.25, 0.9]),
                  ["a", "b", "c"])
    rows = click_rows(5, im)
    assert rows["mic"].tolist() == [0, 3, 1, 2, 4]
    assert rows["channel"].tolist() == [0, 0, 1, 1, 1]
    assert rows["gain"].tolist() == [1.0, 0.25, 1.0, 0.5, 0.9]
    assert rows["joins"].tolist() == [0, 1, 0, 1, 1]
    free = click_rows(2)
    assert free["mic"].tolist() == free["channel"].tolist() == [0, 1] and not free["joins"].any()
    with pytest.raises(ValueError, match="image microphones"):
        click_rows(2, im)


def test_taking_a_block_across_the_ring_wrap_matches_the_sample_loop():
    """``take_into_block`` (contiguous runs of the ring) against the plain per-sample loop:
    every pending sample added as float32, a non-finite one adds nothing, taken samples
    zeroed, across the ring's wrap and at any pending span."""
    rng = np.random.default_rng(1)
    for trial in range(60):
        track = bl.PulseTrack(int(rng.integers(1, 4)), FS)
        st = track.state
        cap = st.acc.shape[1]
        st.acc[:] = rng.standard_normal(st.acc.shape)
        st.acc[rng.random(st.acc.shape) < 0.02] = np.nan
        start = int(rng.integers(0, 5000))
        lo_p = start + int(rng.integers(0, 300))
        rec = st.rec[0]
        rec["start"], rec["pending_from"], rec["pending_until"] = start, lo_p, lo_p + int(rng.integers(0, cap))
        n = int(rng.integers(1, cap))
        block = rng.standard_normal((st.acc.shape[0], n)).astype(np.float32)
        ref, acc = block.copy(), st.acc.copy()
        for c in range(acc.shape[0]):
            for u in range(max(start, lo_p), min(start + n, int(rec["pending_until"]))):
                x, acc[c, u % cap] = acc[c, u % cap], 0.0
                if np.isfinite(x):
                    ref[c, u - start] += np.float32(x)
        bl.take_into_block(st, block)
        np.testing.assert_array_equal(block, ref, err_msg=f"trial {trial}")
        np.testing.assert_array_equal(st.acc, acc, err_msg=f"trial {trial}")
        assert st.rec[0]["start"] == start + n
