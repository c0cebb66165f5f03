"""tools/checks/fuzz_truth.py, the seeded search for false negatives, on a few seeds: every
strategy keeps every truly visible object (query and display resolution), and the
scenes it draws do hide things (a search that culls nothing proves nothing)."""

import os
import sys

import numpy as np

from tests.cli_helpers import ROOT

sys.path.insert(0, os.path.join(ROOT, "tools", "checks"))
import fuzz_truth  # noqa: E402


def test_seeded_scenes_and_walks_have_no_false_negatives(ctx):
    passes, seen, occluded, failures = fuzz_truth.search(
        range(6), ["gpu", "auto", "om_coherent", "two_pass"], 8, ctx, report=lambda line: None)
    assert failures == []
    assert passes == 6 * 4 * 8
    assert occluded > seen > 0


def test_seeded_envelope_passes_hide_nothing_a_view_of_the_envelope_sees(ctx):
    """Envelope passes over seeded walks whose far planes may cut the scene, against seeded
    views of each envelope.  Seeds 4 and 19 hid objects a turned view draws before its far
    plane (before the far-plane rule); 88 and 122 objects seen through a gap narrower than
    a pixel between two surfaces (before every step between two surfaces broke the image);
    174 an object 0.1 behind a wall where the depth buffer rounds by 0.7 (before the polygon
    proof's depth guard)."""
    seeds = [0, 1, 2, 3, 4, 19, 88, 122, 174]
    passes, hidden, failures = fuzz_truth.envelope_search(seeds, 8, ctx, report=lambda line: None)
    assert failures == []
    assert passes == len(seeds) * 8 and hidden > 0


def test_orthographic_envelope_passes_hide_nothing_their_views_see(ctx):
    """Every view of the walks parallel (half of them clipped as Blender clips its own, by a
    slab around the eye), each envelope pass against seeded views of its envelope."""
    seeds = [0, 1, 2, 3, 5, 8]
    passes, hidden, failures = fuzz_truth.envelope_search(seeds, 8, ctx, report=lambda line: None, ortho_share=1.0)
    assert failures == []
    assert passes == len(seeds) * 8 and hidden > 0


def test_the_scenes_reach_the_extremes():
    """Far offsets, very thin slabs, tiny objects, one-sided triangles, rotations."""
    offsets, thin, tiny, rotated, tris = [], 0, 0, 0, 0
    for seed in range(40):
        scene, offset, size = fuzz_truth.scene_for(seed)
        offsets.append(np.abs(offset).max())
        axes = np.linalg.norm(scene.matrices[1:, :3, :3], axis=1)         # each axis's scale
        thin += int((axes.min(axis=1) < 1e-4 * size).sum())
        tiny += int((axes.max(axis=1) < 5e-3 * size).sum())
        m = scene.matrices[1:, :3, :3]
        rotated += int((np.abs(m - m * np.eye(3)).max(axis=(1, 2)) > 0).sum())     # off the diagonal
        tris += int((scene.mesh_of == 1).sum())
    assert max(offsets) > 1e5 and min(offsets) < 10
    assert thin and tiny and rotated and tris
