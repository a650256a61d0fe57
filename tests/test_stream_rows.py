"""A block's rows of the persistent streams (``streams.streams_bank_rows``) against a plain
Python reading of the rings: which streams have rows at which microphone, their gains placed
in the banks, their ranges, and the force samples read through each stream's delay (zero
where the ring no longer holds the source sample, or not yet)."""

from __future__ import annotations

import numpy as np

from mjsound.synth.records import STREAM, STREAMS, BankLayout, StreamState
from mjsound.synth.streams import streams_bank_rows


def plain_rows(st, layout, start, end):
    """The rows as the loops over every sample would make them (numpy, no ring arithmetic)."""
    n_mics, cap = st.D.shape[1], st.ring.shape[1]
    rows = []
    for m in range(n_mics):
        for s in range(int(st.counts[0]["n"])):
            t = st.table[s]
            hi = int(t["last"]) + int(st.D[s, m])
            if not t["live"] or hi <= start:
                continue
            v = layout.vbase[t["obj"]] + m
            gr = np.zeros(layout.width, np.float32)
            gi = np.zeros(layout.width, np.float32)
            w = min(layout.v_len[v], st.gr.shape[2])
            gr[layout.v_rel[v]: layout.v_rel[v] + w] = st.gr[s, m, :w]
            gi[layout.v_rel[v]: layout.v_rel[v] + w] = st.gi[s, m, :w]
            F = np.zeros(end - start, np.float32)
            b = min(hi, end)
            for u in range(start, b):
                ks = u - int(st.D[s, m])
                if int(t["gen"]) - cap <= ks < int(t["gen"]):
                    F[u - start] = st.ring[s, ks % cap]
            rows.append((m, start, b, gr, gi, F))
    return rows


def test_stream_rows_read_the_rings_through_the_delays():
    rng = np.random.default_rng(5)
    cap, n_mics, nmax = 64, 2, 3
    S = 5
    table = np.zeros(8, STREAM)
    # (live, object, samples generated up to gen, last driven sample): a stream that stops
    # inside the block, one whose ring wraps inside it (and whose far microphone hears samples
    # older than the ring holds), one that stopped before it, one heard only at its far
    # microphone, one retired (no rows)
    for s, (live, obj, gen, last) in enumerate([(1, 0, 230, 230), (1, 1, 300, 290), (1, 0, 205, 205),
                                                (1, 1, 150, 150), (0, 0, 260, 260)]):
        table[s]["live"], table[s]["obj"], table[s]["gen"], table[s]["last"] = live, obj, gen, last
    D = np.array([[3, 9], [0, 40], [7, 2], [1, 60], [0, 0]] + [[0, 0]] * 3, np.int64)
    gr = rng.standard_normal((8, n_mics, nmax)).astype(np.float32)
    gi = rng.standard_normal((8, n_mics, nmax)).astype(np.float32)
    ring = rng.standard_normal((8, cap))
    counts = np.zeros(1, STREAMS)
    counts[0]["n"] = S
    st = StreamState(table, D, gr, gi, ring, counts, np.full((8, n_mics), np.nan), np.zeros((8, n_mics, 3, nmax)))
    # two objects (3 and 2 modes) at two microphones: voices object-major, banks microphone-major
    layout = BankLayout(np.array([0, 2], np.int64), np.array([0, 0, 3, 3], np.int64), np.array([3, 3, 2, 2], np.int64),
                        np.array([0, 1, 0, 1], np.int64), 5)
    start, end = 200, 260
    ptr, sa, sb, rgr, rgi, F = streams_bank_rows(st, layout, start, end, np.float32(0))
    ref = plain_rows(st, layout, start, end)
    assert len(sa) == len(ref) == 7  # streams 0-2 at both microphones, stream 3 only where it is still heard
    assert ptr.tolist() == [0, 3, 7]
    for j, (m, a, b, g_r, g_i, f) in enumerate(ref):
        assert ptr[m] <= j < ptr[m + 1]
        assert (sa[j], sb[j]) == (a, b)
        np.testing.assert_array_equal(rgr[j], g_r)
        np.testing.assert_array_equal(rgi[j], g_i)
        np.testing.assert_array_equal(F[j], f)
    assert F[0].any() and not F[0][-20:].any()  # (stream 0: its last samples come after gen)


def test_stream_seed_is_splitmix_of_seed_object_and_key():
    """A new stream's generator state is splitmix64 twice (numpy's wrapping uint64 arithmetic
    as the reference), its bits as the int64 the STREAM record holds: the same state the
    stream generator's own splitmix (numba) would make, for seeds and keys of any size."""
    from mjsound.synth.streams import stream_seed

    def splitmix(x):
        with np.errstate(over="ignore"):
            x = x + np.uint64(0x9E3779B97F4A7C15)
            z = (x ^ (x >> np.uint64(30))) * np.uint64(0xBF58476D1CE4E5B9)
            z = (z ^ (z >> np.uint64(27))) * np.uint64(0x94D049BB133111EB)
        return z ^ (z >> np.uint64(31))

    low63 = 0x7FFFFFFFFFFFFFFF
    rng = np.random.default_rng(3)
    cases = [(0, 0, 0), (2**64 - 1, 5, 2**32 - 1), (-1, 0, 7)] + [tuple(int(v) for v in rng.integers(0, 2**63, 3))
                                                                  for _ in range(50)]
    for seed, obj, key in cases:
        a = splitmix(np.uint64(seed & low63) ^ np.uint64(obj & low63))
        want = splitmix(a ^ np.uint64(key & low63))
        got = stream_seed(seed, obj, key)
        assert -(2**63) <= got < 2**63
        assert np.array([got], np.int64).view(np.uint64)[0] == want


def test_stream_gains_keep_their_delay_factors_only_while_the_delay_stays():
    """``stream_gains`` keeps each microphone's factors ``e^{lam dts}`` of a stream and reuses
    them while the sub-sample delay ``dts`` is the same: the gains equal, bit for bit, those
    made with every factor computed again, before and after the object moves (a move makes
    them again: the gains at the new pose are not the old ones)."""
    from mjsound import ModalModel, get_material
    from mjsound.synth.streams import streams_gains
    from mjsound.synth.synthesizer import Synthesizer

    rng = np.random.default_rng(2)
    n, n_points = 12, 15
    f = np.geomspace(300.0, 6000.0, n)
    pts = rng.normal(size=(n_points, 3)) * 0.05
    model = ModalModel(f, np.full(n, 5.0), pts, pts / np.linalg.norm(pts, axis=1, keepdims=True),
                       rng.normal(size=(n_points, 3, n)), np.full(n, 0.01), get_material("steel"), mass_kg=0.3)
    syn = Synthesizer(sample_rate=16000, microphones=[[1.0, 0.2, 0.0], [-0.3, 2.0, 0.5]])
    syn.add_object("o", model, position=(0.0, 0.0, 0.1))
    j = syn.stream(("side", 0), "o")

    def gains(scratch):
        ks = syn.kernel_state()
        st = ks.streams
        st.table[j]["p"] = (0.01, -0.02, 0.12)
        st.table[j]["n"] = (0.0, 0.6, 0.8)
        st.table[j]["live"] = 1
        st.table[j]["due"] = 1
        if scratch:
            st.dts[j] = np.nan
        streams_gains(ks)
        assert np.isfinite(st.dts[j]).all()
        return st.gr[j].copy(), st.gi[j].copy(), st.D[j].copy()

    first = gains(True)
    assert np.abs(first[0]).max() > 0
    for a, b in zip(gains(False), first):  # the kept factors
        np.testing.assert_array_equal(a, b)
    syn.set_pose("o", (0.3, -0.1, 0.2), np.eye(3))
    moved = gains(False)
    assert not np.array_equal(moved[0], first[0])
    for a, b in zip(moved, gains(True)):
        np.testing.assert_array_equal(a, b)
