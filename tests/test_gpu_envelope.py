"""The envelope pass's image work on the GPU (core/gl/gpuenvelope.py) against its numpy
reference (core/envelope.py's extended_depth), and the occluders an envelope pass draws."""

import numpy as np
import pytest

from core import Culler, OccError
from core.envelope import (
    HALF_SIZES,
    NEAREST_GUARD,
    Envelope,
    _lens,
    envelope_camera,
    extended_depth,
    sample_views,
    slope_tolerance,
)
from core.gl import gpuenvelope
from tests import scenes

# the depth texture as the shaders see it (texelFetch; a read-back may round a 24-bit
# depth to the float next to it): the reference is fed exactly what the GPU reads
COPY = """#version 430 core
layout(local_size_x = 8, local_size_y = 8) in;
uniform sampler2D u_depth;
uniform ivec2 u_size;
layout(std430, binding = 8) writeonly buffer Out { float d[]; };
void main() {
    ivec2 p = ivec2(gl_GlobalInvocationID.xy);
    if (p.x >= u_size.x || p.y >= u_size.y) return;
    d[p.y * u_size.x + p.x] = texelFetch(u_depth, p, 0).r;
}"""


def _fetched(ctx, tex):
    w, h = tex.size
    cs = ctx.compute_shader(COPY)
    buf = ctx.buffer(reserve=4 * w * h)
    try:
        buf.bind_to_storage_buffer(8)
        tex.use(gpuenvelope.DEPTH_UNIT)
        cs["u_depth"].value = gpuenvelope.DEPTH_UNIT
        cs["u_size"].value = (w, h)
        cs.run(-(-w // 8), -(-h // 8))
        ctx.memory_barrier()
        return np.frombuffer(buf.read(), dtype=np.float32).reshape(h, w)
    finally:
        buf.release()
        cs.release()


def _gpu(c, monkeypatch):
    monkeypatch.setenv("OCC_ENVELOPE", "gpu")
    g = c.renderer.gpu_envelope()
    if g is None:
        pytest.skip("the 4.1 path (or a driver without doubles in compute shaders): numpy only")
    return g


@pytest.mark.parametrize("seed", [0, 1, 2])
def test_the_gpu_image_is_the_reference_bit_for_bit(ctx, monkeypatch, seed):
    scene, cams, _ = scenes.random_city(seed, 250)
    compared = finite = 0
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        g = _gpu(c, monkeypatch)
        for camera in cams[:3]:
            for env, near_eff in ((Envelope(0.0, 0.0), 0.0), (Envelope(0.5, 5.0), 0.6),
                                  (Envelope(2.0, 10.0), 2.2), (Envelope(0.3, 20.0, any_roll=False), 0.4)):
                view = envelope_camera(camera, env, 90)
                if view is None:                  # a turn wider than the square holds
                    continue
                tex = c.renderer.envelope_depth(view.render, view.size)
                want = extended_depth(_fetched(ctx, tex), view.render, env, near_eff)
                got = g.extended_depth(tex, _lens(view.render), env, near_eff, HALF_SIZES, slope_tolerance,
                                       NEAREST_GUARD)
                assert got.shape == want.shape
                same = (got == want) | (np.isinf(got) & np.isinf(want))
                assert same.all(), (seed, env, int((~same).sum()))
                compared += got.size
                finite += int(np.isfinite(want).sum())
    assert finite > 0.05 * compared           # covered pixels: the comparison can fail


@pytest.mark.parametrize("seed", [3, 4])
def test_gpu_envelope_passes_hide_nothing_any_view_of_the_envelope_sees(ctx, monkeypatch, seed):
    scene, cams, _ = scenes.random_city(seed, 300)
    rng = np.random.default_rng(seed)
    hidden = 0
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        _gpu(c, monkeypatch)
        for camera in cams:
            for env in (Envelope(0.5, 5.0), Envelope(2.0, 10.0)):
                result = c.cull(camera, envelope=env)
                seen = np.zeros(len(c), dtype=bool)
                for v in sample_views(camera, env, 12, rng):
                    seen |= c.truth(v)
                assert not (seen & ~result.visible).any(), (seed, env)
                hidden += int((~result.visible).sum())
    assert hidden > 0


def test_auto_leaves_a_software_rasteriser_to_numpy(ctx, monkeypatch):
    scene, _, _ = scenes.random_city(0, 20)
    with Culler(scene, resolution=(64, 36), ctx=ctx) as c:
        monkeypatch.delenv("OCC_ENVELOPE", raising=False)
        software = any(k in c.renderer.device.lower() for k in gpuenvelope.SOFTWARE)
        assert (c.renderer.gpu_envelope() is None) == (software or c.renderer.path != "4.3")
        monkeypatch.setenv("OCC_ENVELOPE", "numpy")
        assert c.renderer.gpu_envelope() is None
        monkeypatch.setenv("OCC_ENVELOPE", "fast")
        with pytest.raises(OccError, match="OCC_ENVELOPE must be one of auto, gpu, numpy"):
            c.renderer.gpu_envelope()


def test_an_envelope_pass_draws_only_what_the_last_did_not_prove_hidden(ctx):
    scene, cams, _ = scenes.random_city(6, 300)
    env = Envelope(0.5, 5.0)
    rng = np.random.default_rng(6)
    with Culler(scene, resolution=(160, 90), ctx=ctx) as c:
        first = c.cull(cams[0], envelope=env)
        assert c.envelope_occluders is not None
        assert (~first.visible).sum() > 0
        drawn = []
        for camera in cams:
            r = c.cull(camera, envelope=env)
            drawn.append(r.stats.envelope_occluders)
            seen = np.zeros(len(c), dtype=bool)
            for v in sample_views(camera, env, 8, rng):
                seen |= c.truth(v)
            assert not (seen & ~r.visible).any()
        c.envelope_image.reset()                                                 # this pass draws its image
        again = c.cull(cams[-1], envelope=env)
        assert again.stats.envelope_image_hidden is not None
        assert again.stats.envelope_occluders < first.stats.envelope_occluders   # fewer drawn
        hidden = np.flatnonzero(~again.visible)
        assert len(hidden)
        c.set_matrices(hidden[:1], scene.matrices[hidden[:1]])                    # moved: drawn again
        assert c.envelope_occluders[hidden[0]]
        fresh = c.cull(cams[-1], envelope=env, fresh=True)                        # a fresh pass draws all
        assert fresh.stats.envelope_occluders > again.stats.envelope_occluders
