#!/usr/bin/env bash
# The envelope pass and live mode's motions on a lent NVIDIA machine (the device tool), in
# one call; carry .gl and .whl as for tools/bench/gpu_bench.sh.  Each step has its own time limit
# and appends to $OUT/raw.tar as soon as it ends, so a call cut short still returns what ran:
#   1. the engine's tests without Blender, on NVIDIA's GL (the GPU envelope's own tests too);
#   2. `bench SCENE --strategies gpu --envelope 2,10 --frames 12` per sample scene (the
#      envelope's image work as compute passes, OCC_ENVELOPE=auto), the city again with
#      OCC_ENVELOPE=numpy, and a profile of the city's envelope passes;
#   3. `python -m core motion SCENE --frames 24` (passes land after their measured time).
# Then `python3 tools/bench/gpu_table.py --envelope DIR` (DIR: raw.tar unpacked) writes the tables.
set -uo pipefail
source tools/bench/gpu_setup.sh
RAW=/tmp/env_raw; mkdir -p "$RAW"
keep() { tar -rf "$OUT/raw.tar" -C "$RAW" "$@" 2>/dev/null; }
step() {  # step NAME LIMIT_S COMMAND...: stdout to NAME.json (or .txt), stderr to NAME.log
    local name=$1 limit=$2; shift 2
    local t0=$SECONDS
    timeout "$limit" "$@" > "$RAW/$name.out" 2> "$RAW/$name.log"; local rc=$?
    echo "== $name rc=$rc $((SECONDS - t0)) s"; [ $rc -ne 0 ] && tail -4 "$RAW/$name.log"
    keep "$name.out" "$name.log"
}
# the whole engine suite takes over 150 s there (a context and its shaders per test): TESTS narrows it
[ -z "${SKIP_TESTS:-}" ] && step tests 150 python3 -m pytest -q -p no:cacheprovider --tb=short -rf \
    -m "not blender and not gui" --ignore=tests/blender --ignore=tests/gui -W ignore ${TESTS:-}
[ -f "$RAW/tests.out" ] && tail -3 "$RAW/tests.out"
for s in ${SCENES:-city assembly vessels cathedral isosurface}; do
    step "env-$s" 120 python3 -m core bench "$s" --strategies gpu --envelope 2,10 --frames 12 --json -q
done
OCC_ENVELOPE=numpy step env-city-numpy 120 python3 -m core bench city --strategies gpu --envelope 2,10 --frames 12 --json -q
for s in ${PROFILE_SCENES:-city}; do
    step "profile-$s" 120 python3 tools/bench/envelope_profile.py "$s" --frames 8
    cat "$RAW/profile-$s.out"
done
for s in ${MOTION_SCENES:-city assembly}; do
    step "motion-$s" 120 python3 -m core motion "$s" --frames 24 --json -q
done
[ -z "${SKIP_XL:-}" ] && step motion-city-xl 180 python3 -m core motion city-xl --frames 24 --motions walk --json -q
[ -n "${XL_BENCH:-}" ] && step env-city-xl 150 python3 -m core bench city-xl --strategies gpu --envelope 2,10 --frames 12 --json -q
echo done
