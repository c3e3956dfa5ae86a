"""Start-up: ``import handeye`` and ``handeye --help`` against importing what handeye cannot do
without (numpy, scipy.optimize, scipy.spatial), in fresh interpreters (goal: <= 1.3x).

    python benchmarks/bench_import.py [--repeat 15]

Each is run ``--repeat`` times, interleaved, in a new ``python`` process; the best time of each
is kept (the least disturbed by the machine). Byte-code caching is on for these runs (as in any
installed package); with ``PYTHONDONTWRITEBYTECODE`` set, every import compiles its sources again,
which costs handeye ~0.15 s more and says nothing about the package.
"""

from __future__ import annotations

import argparse
import os
import subprocess
import sys

GOAL = 1.3

SNIPPETS = {
    "numpy + scipy.optimize + scipy.spatial": "import numpy, scipy.optimize, scipy.spatial",
    "import handeye": "import handeye",
    "handeye --help (the CLI's modules)": "import handeye.cli",
}


def _time(code: str, env: dict[str, str]) -> float:
    probe = f"import time; t = time.perf_counter(); {code}; print(time.perf_counter() - t)"
    out = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, env=env, check=True)
    return float(out.stdout.strip())


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--repeat", type=int, default=15)
    args = parser.parse_args()
    env = {k: v for k, v in os.environ.items() if k != "PYTHONDONTWRITEBYTECODE"}
    for code in SNIPPETS.values():  # write the byte-code caches first
        _time(code, env)
    best = {name: float("inf") for name in SNIPPETS}
    for _ in range(args.repeat):
        for name, code in SNIPPETS.items():
            best[name] = min(best[name], _time(code, env))
    base = best["numpy + scipy.optimize + scipy.spatial"]
    print(f"best of {args.repeat} fresh interpreters each ({sys.executable})")
    for name, t in best.items():
        ratio = t / base
        verdict = "" if name.startswith("numpy") else f"   (goal <= {GOAL}x: {'met' if ratio <= GOAL else 'NOT met'})"
        print(f"  {name:<40} {1e3 * t:7.1f} ms   {ratio:5.2f}x{verdict}")


if __name__ == "__main__":
    main()
