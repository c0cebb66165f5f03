#!/usr/bin/env bash
# The benchmark on a lent NVIDIA machine (the device tool), in one call:
#   carry: .gl (Debian's GL loader .debs), .whl (moderngl, glcontext, trimesh wheels for
#   the machine's Python), .baseline (an older checkout to compare with, optional).
# Every figure is a median over the sample path, baseline and current code on the same card
# in the same call.  Writes $OUT/gpu.md (tables) and $OUT/raw.tgz (every bench --json and log).
set -uo pipefail
source tools/bench/gpu_setup.sh
RAW=/tmp/gpu_raw; mkdir -p "$RAW"
SCENES=${SCENES:-city assembly vessels cathedral isosurface city-xl}
FRAMES=${FRAMES:-}
for s in $SCENES; do
    args=(); [ -n "$FRAMES" ] && args=(--frames "$FRAMES")
    echo "== $s (current)"
    strat=(); [ -n "${STRATEGIES:-}" ] && strat=(--strategies "$STRATEGIES")
    timeout "${SCENE_TIMEOUT:-240}" python3 -m core bench "$s" "${strat[@]}" "${args[@]}" --json > "$RAW/$s.json" 2> "$RAW/$s.log" || tail -5 "$RAW/$s.log"
    if [ -d .baseline ] && [ "$s" != city-xl ]; then
        echo "== $s (baseline)"
        (cd .baseline && OCC_CACHE_DIR=$OCC_CACHE_DIR timeout "${SCENE_TIMEOUT:-240}" python3 -m core bench "$s" --strategies vfc,om_coherent,oracle "${args[@]}" --json) \
            > "$RAW/base-$s.json" 2> "$RAW/base-$s.log" || tail -5 "$RAW/base-$s.log"
    fi
done
echo "== GL backend (python -m core.lab.gl_bench --scene city)"
[ -z "${SKIP_GLBENCH:-}" ] && { timeout 120 python3 -m core.lab.gl_bench --scene city > "$RAW/glbench.txt" 2>&1; tail -25 "$RAW/glbench.txt"; }
python3 tools/bench/gpu_table.py "$RAW" | tee "$OUT/gpu.md"
tar -czf "$OUT/raw.tgz" -C "$RAW" .
