"""Reduce a seeded workflow's crash to the few steps it needs, and ask plain Blender.

    .venv/bin/python tools/checks/reduce_crash.py --seed 8 --step 164 [--match switch_view_layer] [--hide-in VIEW]

A crash of ``tests/blender/workflows.py`` at step ``--step`` of a seed is replayed with
steps left out (``workflows.py --drop``: a dropped step does nothing, the steps after it
keep their kinds), by delta debugging (Zeller's ddmin) over the steps before it, until no
single step can go.  A run counts as the same crash when Blender dies of a signal and the
Python stack of the crashing thread (faulthandler's, on stderr) names ``--match`` (default:
the crash step's own function, read from the first run).  Then the kept steps are replayed
once more with the add-on and once without it (``--plain``): a crash without the add-on
is Blender's own.  Prints the kept steps (with their history lines) and one JSON line.
Each run is a new Blender process (5-10 s on the workflow scene; seed 8 took 223 runs, 21 min).
"""

import argparse
import json
import os
import re
import subprocess
import sys
import tempfile

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORKFLOWS = os.path.join(ROOT, "tests", "blender", "workflows.py")


def main(argv=None):
    ap = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    ap.add_argument("--seed", type=int, required=True)
    ap.add_argument("--step", type=int, required=True, help="the step the crash happens at (0-based, as --verbose)")
    ap.add_argument("--match", default="", help="a name in the crashing thread's Python stack")
    ap.add_argument("--hide-in", default="AUTO", choices=("AUTO", "VIEW", "EVERYWHERE"))
    args = ap.parse_args(argv)
    work = tempfile.mkdtemp(prefix="occ_reduce_")
    dist = os.path.join(work, "dist")
    subprocess.run([sys.executable, os.path.join(ROOT, "tools", "build_extension.py"), "--no-wheels", "--out", dist],
                   cwd=ROOT, check=True, capture_output=True)
    zip_path = next(os.path.join(dist, f) for f in os.listdir(dist) if f.endswith(".zip"))
    env = {**os.environ, "BLENDER_USER_RESOURCES": os.path.join(work, "user"), "PYTHONHASHSEED": "0"}
    runs = [0]

    def run(kept, plain=False, verbose=False):
        drop = ",".join(str(s) for s in range(args.step) if s not in kept)
        cmd = [sys.executable, WORKFLOWS, "--work", work, "--seeds", str(args.seed), "--steps", str(args.step + 1),
               "--hide-in", args.hide_in] + (["--drop", drop] if drop else []) + (["--verbose"] if verbose else [])
        cmd += ["--plain"] if plain else ["--zip", zip_path]
        runs[0] += 1
        p = subprocess.run(cmd, env=env, capture_output=True, text=True, timeout=1800)
        crashed = p.returncode in (-11, 139, -6, 134)
        # faulthandler prints the crashing thread's stack last
        stack = p.stderr.split("(most recent call first):")[-1] if crashed else ""
        return crashed, stack, p.stdout + p.stderr

    every = list(range(args.step))
    crashed, stack, _ = run(every)
    if not crashed:
        print(f"seed {args.seed} does not crash by step {args.step}", file=sys.stderr)
        return 1
    match = args.match or (re.findall(r'line \d+ in (\w+)', stack) or [""])[0]

    def same(kept):
        c, s, _ = run(kept)
        return c and match in s

    kept, n = every, 2
    while len(kept) >= 2:
        size = max(1, len(kept) // n)
        for part in (kept[i:i + size] for i in range(0, len(kept), size)):
            rest = [s for s in kept if s not in part]
            if same(rest):
                kept, n = rest, max(n - 1, 2)
                print(f"{len(kept)} steps kept: {kept}", file=sys.stderr, flush=True)
                break
        else:
            if n >= len(kept):
                break
            n = min(len(kept), n * 2)
    with_addon, _, out = run(kept, verbose=True)
    plain, plain_stack, _ = run(kept, plain=True)
    for line in out.splitlines():
        if line.startswith(f"[seed {args.seed}]") and "(dropped)" not in line:
            print(line)
    print(json.dumps({"seed": args.seed, "step": args.step, "match": match, "kept": kept, "runs": runs[0],
                      "crashes_with_addon": with_addon, "crashes_plain": plain,
                      "plain_stack": [ln.strip() for ln in plain_stack.strip().splitlines()[:3]]}))
    return 0


if __name__ == "__main__":
    sys.exit(main())
