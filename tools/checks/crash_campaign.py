"""Crash campaign: many seeded user workflows (tests/blender/workflows.py), each seed in
a process of its own, so that a crash of Blender ends one seed only and is counted as
a crash (issue 30).

    .venv/bin/python tools/checks/crash_campaign.py --seeds 1000:1100 [--steps 300] [--jobs 2]
        [--hide-in VIEW] [--minutes 40] [--plain-check] [--skip KIND,..] [--json OUT.json]
    .venv-bpy42/bin/python tools/checks/crash_campaign.py --seeds 1:20      (another bpy: its python)

Per seed: ``pass``, ``fail`` (an invariant broke: the step, its kind, the first
problem), ``crash`` (the process died of a signal, rc -11 / 139: the step it was in,
from the workflow's ``--progress`` file, and the Python stack faulthandler printed),
``timeout`` or ``error`` (no result and no signal).  ``--plain-check`` replays each
crash's seed with ``workflows.py --plain`` (the same step kinds, the add-on never
installed, its steps skipped, the harness's own truth still drawn where they ran) up
to the crashing step: whether plain Blender crashes on the same user steps.  The twin
is not the same run: where the add-on hid objects, the steps that prefer hidden objects
pick others.  ``--plain`` runs every seed so: the crash rate of plain Blender over the
same seeds, to compare with the add-on's.  ``--backtrace``: each crash leaves a core
file that gdb reads for Blender's innermost frames (the crash's signature), then
deletes.  Prints one line per seed that did not pass, with the command that replays
it, and the counts; ``--json`` writes every seed's outcome.
"""

import argparse
import json
import os
import re
import resource
import shutil
import signal
import subprocess
import sys
import tempfile
import time
from concurrent.futures import ThreadPoolExecutor, as_completed

ROOT = os.path.dirname(os.path.dirname(os.path.dirname(os.path.abspath(__file__))))
WORKFLOWS = os.path.join(ROOT, "tests", "blender", "workflows.py")
MARK = "OCC_WORKFLOWS "


def parse_seeds(text):
    """``"A:B"`` (half-open) or ``"1,5,9"`` -> a list of ints."""
    if ":" in text:
        a, b = text.split(":")
        return list(range(int(a), int(b)))
    return [int(s) for s in text.split(",") if s]


def build_zip(work):
    dist = os.path.join(work, "dist")
    subprocess.run([sys.executable, os.path.join(ROOT, "tools", "build_extension.py"), "--no-wheels",
                    "--out", dist], cwd=ROOT, check=True, capture_output=True)
    return next(os.path.join(dist, f) for f in sorted(os.listdir(dist)) if f.endswith(".zip"))


def signal_name(rc):
    """The signal of a return code (-11 from subprocess, 139 from a shell), or None."""
    num = -rc if rc < 0 else rc - 128 if rc > 128 else None
    if num is None:
        return None
    try:
        return signal.Signals(num).name
    except ValueError:
        return f"signal {num}"


def last_progress(path):
    """``(step, kind)`` of the last step the workflow started (``--progress`` lines
    ``SEED STEP KIND``), or ``(None, None)``."""
    try:
        with open(path, encoding="utf-8") as f:
            lines = [ln.split() for ln in f if ln.strip()]
    except OSError:
        return None, None
    lines = [ln for ln in lines if len(ln) == 3]
    return (int(lines[-1][1]), lines[-1][2]) if lines else (None, None)


def crash_stack(stderr):
    """The workflow's frames of the crashing thread, innermost first (faulthandler's dump)."""
    blocks = re.split(r"\n(?=(?:Current thread|Thread) 0x)", stderr)
    for b in blocks:
        if "workflows.py" in b and "run_seed" in b:
            return [f"{m.group(2)}:{m.group(1)}" for m in re.finditer(r'File "[^"]*?([^/"]+)", line \d+ in (\w+)', b)]
    return []


def native_frames(core, python):
    """Blender's innermost frames in a core file (gdb's backtrace below the signal handler)."""
    gdb = shutil.which("gdb")
    if gdb is None or not os.path.exists(core):
        return []
    try:
        bt = subprocess.run([gdb, "-batch", "-ex", "bt 16", python, core], capture_output=True, text=True,
                            timeout=300).stdout
    except subprocess.TimeoutExpired:
        return []
    frames = re.findall(r"^#\d+\s+(?:0x[0-9a-f]+ in )?([^\s(]+)", bt, flags=re.M)
    if "<signal" in frames:
        frames = frames[frames.index("<signal") + 1:]
    # the C library's own frames of an abort (a heap check that failed) say nothing of where
    frames = [f for f in frames if not re.match(r"(__|_int_|malloc|raise|abort|free|cfree|\?\?|<signal)", f)]
    return frames[:4]


def core_unlimited():
    resource.setrlimit(resource.RLIMIT_CORE, (resource.RLIM_INFINITY, resource.RLIM_INFINITY))


def run_one(seed, args, zip_path, work, plain=False, steps=None):
    """One seed in its own process: its outcome as a dict."""
    tag = f"{seed}{'_plain' if plain else ''}"
    home = tempfile.mkdtemp(prefix=f"seed{tag}_", dir=work)
    progress = os.path.join(home, "progress.txt")
    steps = steps or args.steps
    cmd = [args.python, WORKFLOWS, "--work", home, "--seed", str(seed), "--steps", str(steps),
           "--hide-in", args.hide_in, "--progress", progress, "--tail", "12"]
    cmd += ["--plain"] if plain else ["--zip", zip_path]
    cmd += ["--skip", args.skip] if args.skip else []
    cmd += ["--ground", str(args.ground)] if args.ground else []
    env = {**os.environ, "BLENDER_USER_RESOURCES": os.path.join(home, "user"), "PYTHONHASHSEED": "0"}
    t = time.perf_counter()
    try:
        p = subprocess.run(cmd, cwd=home, env=env, capture_output=True, text=True, timeout=args.timeout,
                           preexec_fn=core_unlimited if args.backtrace else None)
        rc, out, err = p.returncode, p.stdout, p.stderr
    except subprocess.TimeoutExpired as e:
        rc, out, err = None, e.stdout or "", e.stderr or ""
        out, err = (x.decode(errors="replace") if isinstance(x, bytes) else x for x in (out, err))
    seconds = round(time.perf_counter() - t, 1)
    step, kind = last_progress(progress)
    replay = (f"{os.path.relpath(args.python, ROOT)} tests/blender/workflows.py --seed {seed} "
              f"--steps {step or steps} --hide-in {args.hide_in}{' --plain' if plain else ''}"
              f"{' --skip ' + args.skip if args.skip else ''}{f' --ground {args.ground}' if args.ground else ''}"
              " --verbose")
    res = {"seed": seed, "rc": rc, "seconds": seconds, "step": step, "kind": kind, "replay": replay}
    line = next((ln for ln in out.splitlines() if ln.startswith(MARK)), None)
    if line is not None:
        got = json.loads(line[len(MARK):])["seeds"][str(seed)]
        fail = got["failure"]
        res["counts"], res["stats"] = got["counts"], got["stats"]
        if fail is None:
            res["outcome"] = "pass"
        else:
            res.update(outcome="fail", step=fail["step"], kind=fail["kind"], problem=fail["problems"][0][:600],
                       history=fail["history"])
            res["replay"] = res["replay"].replace(f"--steps {step or steps}", f"--steps {fail['step']}")
    elif rc is None:
        res["outcome"] = "timeout"
    elif signal_name(rc) is not None:
        res.update(outcome="crash", signal=signal_name(rc), stack=crash_stack(err)[:8])
        if args.backtrace:
            cores = [os.path.join(home, f) for f in os.listdir(home) if f.startswith("core")]
            res["native"] = native_frames(cores[0], args.python) if cores else []
            for c in cores:
                os.remove(c)
    else:
        res.update(outcome="error", tail=err[-1500:])
    if res["outcome"] in ("pass", "fail"):
        shutil.rmtree(home, ignore_errors=True)
    else:
        res["stderr_file"] = os.path.join(home, "stderr.txt")
        with open(res["stderr_file"], "w", encoding="utf-8") as f:
            f.write(err)
        shutil.rmtree(os.path.join(home, "user"), ignore_errors=True)
    return res


def describe(r):
    head = f"seed {r['seed']}: {r['outcome'].upper()}"
    if r["outcome"] == "crash":
        head += f" ({r['signal']}, rc {r['rc']}) in step {r['step']} ({r['kind']})"
        if r.get("stack"):
            head += " at " + " <- ".join(r["stack"][:4])
        if r.get("native"):
            head += " [" + " <- ".join(r["native"]) + "]"
        if "plain" in r:
            head += f"; plain Blender, same steps: {r['plain']}"
    elif r["outcome"] == "fail":
        head += f" at step {r['step']} ({r['kind']}): {r['problem'][:300]}"
    elif r["outcome"] == "error":
        head += f" (rc {r['rc']}): {r['tail'][-300:]}"
    return head + f"\n    replay: {r['replay']}"


def main(argv=None):
    p = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    p.add_argument("--seeds", required=True, help="A:B (half-open range) or a comma-separated list")
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--jobs", type=int, default=1, help="seeds run at once")
    p.add_argument("--hide-in", default="AUTO", choices=("AUTO", "VIEW", "EVERYWHERE"))
    p.add_argument("--skip", default="", help="step kinds left out (workflows.py --skip): e.g. the kinds of "
                   "Blender's own crashes, to hunt the add-on's failures further into each seed")
    p.add_argument("--ground", type=float, default=0.0,
                   help="a ground slab this wide each way under every seed's scene (workflows.py --ground)")
    p.add_argument("--python", default=sys.executable, help="the interpreter with bpy (default: this one)")
    p.add_argument("--timeout", type=int, default=900, help="seconds per seed")
    p.add_argument("--minutes", type=float, default=None, help="start no seed after this many minutes")
    p.add_argument("--plain-check", action="store_true",
                   help="replay each crash's seed without the add-on (workflows.py --plain)")
    p.add_argument("--backtrace", action="store_true", help="Blender's frames of each crash (core file, gdb)")
    p.add_argument("--plain", action="store_true", help="every seed without the add-on (workflows.py --plain)")
    p.add_argument("--json", help="write every seed's outcome here")
    args = p.parse_args(argv)
    seeds = parse_seeds(args.seeds)
    work = tempfile.mkdtemp(prefix="occ_campaign_")
    zip_path = build_zip(work)
    version = subprocess.run([args.python, "-c", "import bpy; print(bpy.app.version_string)"],
                             capture_output=True, text=True).stdout.strip().splitlines()[-1:]
    commit = subprocess.run(["git", "log", "-1", "--format=%h"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    print(f"campaign: {len(seeds)} seeds x {args.steps} steps, bpy {version}, commit {commit}, "
          f"hide in {args.hide_in}{', plain Blender (no add-on)' if args.plain else ''}, work {work}", flush=True)
    start = time.monotonic()
    results = []
    with ThreadPoolExecutor(max_workers=args.jobs) as pool:
        pending = {}
        it = iter(seeds)

        def submit():
            if args.minutes is not None and time.monotonic() - start > args.minutes * 60:
                return False
            seed = next(it, None)
            if seed is None:
                return False
            pending[pool.submit(run_one, seed, args, zip_path, work, args.plain)] = seed
            return True

        for _ in range(args.jobs):
            submit()
        while pending:
            fut = next(as_completed(pending))
            del pending[fut]
            r = fut.result()
            if r["outcome"] == "crash" and args.plain_check and not args.plain:
                q = run_one(r["seed"], args, zip_path, work, plain=True, steps=r["step"])
                r["plain"] = (f"crashes too ({q.get('signal')}, step {q['step']} {q['kind']})"
                              if q["outcome"] == "crash" else f"no crash ({q['outcome']})")
            results.append(r)
            print(("." if r["outcome"] == "pass" else "\n" + describe(r)), end="", flush=True)
            submit()
    print()
    counts = {}
    for r in results:
        counts[r["outcome"]] = counts.get(r["outcome"], 0) + 1
    elapsed = round(time.monotonic() - start)
    print(f"\n{len(results)} seeds in {elapsed} s: " + ", ".join(f"{k} {v}" for k, v in sorted(counts.items())))
    totals = {}
    for r in results:
        for k, v in r.get("stats", {}).items():
            totals[k] = totals.get(k, 0) + v
    if totals:
        print("checks: " + ", ".join(f"{k} {v}" for k, v in totals.items()))
    for r in sorted(results, key=lambda r: r["seed"]):
        if r["outcome"] != "pass":
            print(describe(r))
    if args.json:
        with open(args.json, "w", encoding="utf-8") as f:
            json.dump({"commit": commit, "bpy": version, "steps": args.steps, "hide_in": args.hide_in,
                       "plain": args.plain, "counts": counts, "seconds": elapsed, "seeds": results}, f, indent=1)
    return 0 if set(counts) <= {"pass"} else 1


if __name__ == "__main__":
    sys.exit(main())
