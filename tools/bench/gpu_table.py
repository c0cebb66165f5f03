"""Markdown tables from the JSON files tools/bench/gpu_bench.sh writes (``bench --json`` per scene).

    python tools/bench/gpu_table.py OUT_DIR

One table of median frame milliseconds (strategies as columns, scenes as rows), one of
every strategy against vfc and the oracle, and the baseline's figures where present.
"""

import json
import sys
from pathlib import Path

OPTIONAL = (("cpu_ms_median", "CPU ms outside GL"), ("gl_calls", "GL calls/frame"),
            ("blocking_reads", "blocking reads/frame"))


def load(path):
    try:
        text = path.read_text()
        return json.loads(text[text.index("{"):])
    except (OSError, ValueError):
        return None


def main(out):
    out = Path(out)
    current = {p.stem: load(p) for p in sorted(out.glob("*.json")) if not p.stem.startswith("base-")}
    current = {k: v for k, v in current.items() if v}
    strategies = []
    for rep in current.values():
        for name in rep["strategies"]:
            if name not in strategies:
                strategies.append(name)
    print("| median ms | " + " | ".join(strategies) + " |")
    print("|---" * (len(strategies) + 1) + "|")
    for scene, rep in current.items():
        row = [f"{rep['strategies'][s]['frame_ms_median']:.2f}" if s in rep["strategies"] else "-"
               for s in strategies]
        print(f"| {scene} | " + " | ".join(row) + " |")
    print()
    print("| scene | strategy | median ms | / vfc | / oracle | FN | "
          + " | ".join(label for _, label in OPTIONAL) + " |")
    print("|---" * (6 + len(OPTIONAL)) + "|")
    for scene, rep in current.items():
        st = rep["strategies"]
        for name in [n for n in strategies if n in st]:
            s = st[name]
            vfc = st.get("vfc", {}).get("frame_ms_median")
            orc = st.get("oracle", {}).get("frame_ms_median")
            extra = [f"{s[k]:.2f}" if isinstance(s.get(k), float) else str(s.get(k, "-")) for k, _ in OPTIONAL]
            print(f"| {scene} | {name} | {s['frame_ms_median']:.2f} | "
                  f"{s['frame_ms_median'] / vfc:.2f} | {s['frame_ms_median'] / orc:.2f} | "
                  f"{s.get('false_negatives', '-')} | " + " | ".join(extra) + " |")
    base = {p.stem[5:]: load(p) for p in sorted(out.glob("base-*.json"))}
    base = {k: v for k, v in base.items() if v}
    if base:
        print()
        print("| baseline (before) median ms | vfc | om_coherent | oracle |")
        print("|---|---|---|---|")
        for scene, rep in base.items():
            st = rep["strategies"]
            print(f"| {scene} | " + " | ".join(f"{st[n]['frame_ms_median']:.2f}" if n in st else "-"
                                             for n in ("vfc", "om_coherent", "oracle")) + " |")


if __name__ == "__main__":
    main(sys.argv[1])
