"""Measure the GL backend on a sample scene: the cost of one query batch on each path,
sample counters against flags, and the display -> query depth reduction.

    OCC_CACHE_DIR=... python -m core.lab.gl_bench [--scene city] [--boxes 500 5000] [--repeat 7]

Numbers are medians of ``--repeat`` runs in one process, on whatever context
:func:`core.gl.create_context` gives (llvmpipe here): compare the ratios.
"""

import argparse
import time

import numpy as np

from ..gl import GLRenderer


def _median_ms(fns, repeat):
    """Median ms of each callable, run interleaved (round robin) so that load changes
    on a shared machine hit them alike."""
    for fn in fns.values():
        fn()                               # warm (programs, buffers, driver caches)
    times = {name: [] for name in fns}
    for _ in range(repeat):
        for name, fn in fns.items():
            t = time.perf_counter()
            fn()
            times[name].append(time.perf_counter() - t)
    return {name: 1e3 * float(np.median(t)) for name, t in times.items()}


def _frame_setup(r, cam, units):
    r.begin_frame(cam)
    r.draw(units)
    r.finish()


def query_costs(scene, culler, cam, counts, repeat, log=print):
    """One batch of k boxes (unit boxes in the frustum, drawn behind the scene's own
    depth) on the 4.1 path (= the old renderer's query: one query object, one draw and
    one blocking read per box), on 4.3 with sample counters and with flags."""
    state = culler.cull(cam).state
    drawn = np.flatnonzero(state[culler.units.object] == 0)
    boxes_all = culler.unit_bounds()[drawn] - cam.eye
    rng = np.random.default_rng(0)
    rows = []
    ctx = culler.renderer.ctx
    r41 = GLRenderer(scene, *culler.resolution, ctx=ctx, units=culler.units, path="4.1")
    r43 = GLRenderer(scene, *culler.resolution, ctx=ctx, units=culler.units, path="4.3")
    rs = {"4.1 (old: query objects)": (r41, True), "4.3 counters": (r43, True), "4.3 flags": (r43, False)}
    for k in counts:
        boxes = boxes_all[rng.choice(len(boxes_all), k, replace=k > len(boxes_all))]
        row = {"boxes": k}
        answers = {}
        for r in (r41, r43):
            _frame_setup(r, cam, drawn)
        for name, (r, counts) in rs.items():
            answers[name] = r.query(boxes, counts)
        row.update(_median_ms({name: (lambda r=r, b=boxes, c=counts: r.query(b, c))
                               for name, (r, counts) in rs.items()}, repeat))
        assert np.array_equal(answers["4.1 (old: query objects)"], answers["4.3 counters"])
        assert np.array_equal(np.minimum(answers["4.3 counters"], 1), answers["4.3 flags"])
        row["visible"] = int((answers["4.3 counters"] > 0).sum())
        rows.append(row)
        log(f"  {k} boxes ({row['visible']} visible): " +
            ", ".join(f"{n} {row[n]:.2f} ms" for n in rs) +
            f"; old / 4.3 counters = {row['4.1 (old: query objects)'] / row['4.3 counters']:.1f}x")
    r41.release()
    r43.release()
    return rows


def reduction_costs(scene, culler, cameras, query_res, display, strategy, log=print):
    """A culling pass over ``cameras`` with queries at ``query_res``: plain, with the
    reduction from ``display``, and plain at ``display``; the three run frame by frame
    in turn (load changes hit them alike).  Medians per frame."""
    from ..engine import Culler
    setups = {f"query {query_res[0]}x{query_res[1]}": (query_res, None),
              f"query {query_res[0]}x{query_res[1]}, display {display[0]}x{display[1]}": (query_res, display),
              f"query {display[0]}x{display[1]}": (display, None)}
    cullers = {}
    for name, (res, disp) in setups.items():
        c = Culler(scene, res, strategy=strategy, ctx=culler.renderer.ctx)
        if disp is not None:
            old = c.renderer
            c.renderer = GLRenderer(scene, *res, ctx=old.ctx, units=c.units, display=disp)
            old.release()
        cullers[name] = c
    stats = {name: [] for name in setups}
    for i, cam in enumerate(cameras[:1] + cameras):
        for name, c in cullers.items():
            s = c.cull(cam).stats
            if i:                                              # the first frame is a warm-up
                stats[name].append({**s.as_dict(), **c.renderer.counters})
    out = {}
    for name, c in cullers.items():
        c.close()
        med = {k: float(np.median([s[k] for s in stats[name]]))
               for k in ("total_ms", "query_ms", "draw_ms", "visible", "occluded", "gl_calls")}
        out[name] = med
        log(f"  {name:<40} total {med['total_ms']:7.1f}  query {med['query_ms']:7.1f}  "
            f"draw {med['draw_ms']:7.1f} ms  GL calls {med['gl_calls']:5.1f}  visible {med['visible']:.0f}  "
            f"occluded {med['occluded']:.0f}")
    return out


def main(argv=None):
    import sample_scenes

    from ..camera import cameras_from_json
    from ..engine import Culler
    from ..loading import load_scene

    ap = argparse.ArgumentParser(prog="python -m core.lab.gl_bench", description=__doc__.split("\n\n")[0])
    ap.add_argument("--scene", default="city")
    ap.add_argument("--boxes", type=int, nargs="+", default=[500, 5000])
    ap.add_argument("--repeat", type=int, default=7)
    ap.add_argument("--frames", type=int, default=12, help="frames of the path for the reduction pass")
    ap.add_argument("--strategy", default="om_multi")
    ap.add_argument("--skip-reduction", action="store_true")
    a = ap.parse_args(argv)
    scene = load_scene(str(sample_scenes.scene_path(a.scene)))
    cams = cameras_from_json(sample_scenes.default_camera_path(a.scene))
    cams = [cams[i] for i in np.linspace(0, len(cams) - 1, min(a.frames, len(cams))).astype(int)]
    with Culler(scene, (640, 360), strategy="vfc") as c:
        print(f"{a.scene}: {len(scene)} objects, {len(c.units)} units; {c.renderer.device}")
        print(f"query batch cost (median of {a.repeat}, 640x360):")
        query_costs(scene, c, cams[len(cams) // 2], a.boxes, a.repeat)
        if not a.skip_reduction:
            print(f"{a.strategy} over {len(cams)} frames of the path (median per frame):")
            reduction_costs(scene, c, cams, (640, 360), (1280, 720), a.strategy)


if __name__ == "__main__":
    main()
