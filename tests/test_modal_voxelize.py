"""Voxel occupancy (mjsound.modal.voxelize): the fused count equals fill + block mean."""

import numpy as np
import pytest
import trimesh

from mjsound.modal import analyze as A
from mjsound.modal.hex import grid_for
from mjsound.modal.voxelize import block_mean, winding_fill, winding_occupancy


@pytest.mark.parametrize("spec", ["bowl:0.1,0.004", "sphere:0.05", "box:0.1,0.04,0.02"])
@pytest.mark.parametrize("r,s", [(4, 2), (3, 3), (2, 1)])
def test_winding_occupancy_equals_block_mean_of_the_fill(spec, r, s):
    tm = A.load_mesh(spec)
    lo, n, hc = grid_for(tm.bounds, 0.02, 1)
    nf, hf = n * r, hc / r
    ref = block_mean(winding_fill(tm.triangles, lo, hf / s, nf * s), s)
    occ = winding_occupancy(tm.triangles, lo, hf, nf, s)
    assert occ.dtype == np.float32 and np.array_equal(occ, ref)
    assert 0 < occ.sum() <= occ.size


def test_runs_meeting_on_a_sample_count_it_once():
    # two boxes stacked in z whose shared face passes exactly through a sample centre:
    # the two inside runs of each column meet on that sample
    a = trimesh.creation.box(extents=(1.0, 1.0, 1.0))
    a.apply_translation((0.5, 0.5, 0.5))  # z in [0, 1]
    b = a.copy()
    b.apply_translation((0.0, 0.0, 1.0))  # z in [1, 2]
    tris = np.concatenate([a.triangles, b.triangles])
    # samples at z = 0.125 + 0.25 k: k = 3.5 would be the face; shift the grid so that
    # z = 1 is the centre of sample 4: origin -0.125
    lo = np.array([0.0, 0.0, -0.125])
    occ = winding_occupancy(tris, lo, np.array([0.5, 0.5, 0.5]), np.array([2, 2, 5]), 2)
    ref = block_mean(winding_fill(tris, lo, np.array([0.25, 0.25, 0.25]), np.array([4, 4, 10])), 2)
    assert np.array_equal(occ, ref)
    assert occ.max() <= 1.0


def test_winding_moments_are_exact_along_z_and_give_the_centroid():
    """A box from z = 0.13 to 0.87 on voxels of 0.25: each voxel's filled length and the
    filled part's centroid along z are exact (not counted in samples); over a sphere the
    occupancy and moments give its volume and centre to the sampling's accuracy."""
    from mjsound.modal.voxelize import winding_moments

    box = trimesh.creation.box(extents=(1.0, 1.0, 0.74))
    box.apply_translation((0.5, 0.5, 0.5))  # z in [0.13, 0.87]
    occ, mom = winding_moments(box.triangles, np.zeros(3), np.full(3, 0.25), np.array([4, 4, 4]), 2)
    lengths = np.array([0.12, 0.25, 0.25, 0.12]) / 0.25  # filled fraction of each z layer
    centre = np.array([0.25 - 0.06, 0.375, 0.625, 0.75 + 0.06])  # filled part's centre [m]
    want_mz = lengths * (centre - (np.arange(4) + 0.5) * 0.25) / 0.25
    np.testing.assert_allclose(occ, np.broadcast_to(lengths, (4, 4, 4)), atol=1e-6)
    np.testing.assert_allclose(mom[..., 2], np.broadcast_to(want_mz, (4, 4, 4)), atol=1e-6)
    np.testing.assert_allclose(mom[..., :2], 0.0, atol=1e-6)  # full across x and y: centred
    tm = A.load_mesh("sphere:0.05")
    lo, n, hc = grid_for(tm.bounds, 0.02, 1)
    hf = hc / 4
    occ, mom = winding_moments(tm.triangles, lo, hf, n * 4, 8)
    vox = np.prod(hf)
    centres = lo + (np.indices(n * 4).reshape(3, -1).T + 0.5) * hf
    volume = occ.sum() * vox
    centroid = (occ.reshape(-1, 1) * centres + mom.reshape(-1, 3) * hf).sum(axis=0) * vox / volume
    assert volume == pytest.approx(tm.volume, rel=1e-3)
    assert np.abs(centroid - tm.center_mass).max() < 1e-6 * 0.1
    # the sample columns (x, y) agree with winding_occupancy's counts summed over z samples
    ref = winding_occupancy(tm.triangles, lo, hf, n * 4, 8)
    assert np.abs(occ - ref).max() < 0.02 and abs(occ.sum() - ref.sum()) < 1e-3 * ref.sum()
