"""The cost of a change: bench_throughput of another git revision and of this
working tree, run in turns in one process so that both see the same machine.

Builds REVISION's Release bench_throughput in a temporary worktree, then runs
the two binaries alternately ROUNDS times and prints, per path, the best
ns/step of each and their ratio (this tree over REVISION).

Usage: python3 bench/compare_revisions.py REVISION [--rounds 3] [--repeats 7]
       [--build build]   (this tree's Release build folder, already built)
"""
import argparse
import pathlib
import re
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parent.parent
ROW = re.compile(r"^\s*(\S.*?)\s+([0-9.]+)\.\s+([0-9.]+)\s+([0-9.]+)x$")


def build_revision(revision, workdir):
    tree = workdir / "tree"
    subprocess.run(["git", "-C", str(ROOT), "worktree", "add", "--detach", str(tree), revision],
                   check=True, capture_output=True)
    subprocess.run(["cmake", "-S", str(tree), "-B", str(tree / "build"), "-DCMAKE_BUILD_TYPE=Release"],
                   check=True, capture_output=True)
    subprocess.run(["cmake", "--build", str(tree / "build"), "-j2", "--target", "bench_throughput"],
                   check=True, capture_output=True)
    return tree, tree / "build" / "bench_throughput"


def ns_per_step(binary, repeats):
    out = subprocess.run([str(binary), str(repeats)], check=True, capture_output=True, text=True).stdout
    return {m.group(1): float(m.group(3)) for m in map(ROW.match, out.splitlines()) if m}


def main():
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("revision")
    parser.add_argument("--rounds", type=int, default=3)
    parser.add_argument("--repeats", type=int, default=7)
    parser.add_argument("--build", default="build")
    args = parser.parse_args()
    here = ROOT / args.build / "bench_throughput"
    with tempfile.TemporaryDirectory() as tmp:
        tree, there = build_revision(args.revision, pathlib.Path(tmp))
        try:
            best = {"revision": {}, "tree": {}}
            for _ in range(args.rounds):
                for name, binary in (("revision", there), ("tree", here)):
                    for path, ns in ns_per_step(binary, args.repeats).items():
                        best[name][path] = min(ns, best[name].get(path, float("inf")))
        finally:
            subprocess.run(["git", "-C", str(ROOT), "worktree", "remove", "--force", str(tree)],
                           capture_output=True)
    print(f"best ns/step over {args.rounds} rounds of {args.repeats} repeats, one core")
    print(f"{'path':>30} {args.revision[:12]:>12} {'this tree':>12} {'ratio':>8}")
    for path, ns in best["tree"].items():
        old = best["revision"].get(path)
        if old is not None:
            print(f"{path:>30} {old:12.1f} {ns:12.1f} {ns / old:8.3f}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
