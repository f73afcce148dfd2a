#!/usr/bin/env python3
"""Reruns the benchmarks and rewrites docs/performance.md with their output:
the machine, the date, the commit, and each table beside the command that
printed it, so the figures in the docs are always today's; and
docs/workprecision.png and .csv (docs/accuracy.md's figure) with those of
bench/workprecision.py's run.

    .venv/bin/python bench/report.py [--build build] [--quick]

--quick runs each bench on a smaller scale (a smoke test; its figures are
not for the docs, and it writes to stdout only).
"""
import argparse
import datetime
import os
import pathlib
import platform
import shutil
import subprocess
import sys
import tempfile

ROOT = pathlib.Path(__file__).resolve().parents[1]
INTRO = """# Performance

Every table below is the output of the command above it, on the machine
named here; `.venv/bin/python bench/report.py` reruns them all and rewrites this file.
Ratios are measured side by side in one run; absolute times depend on the
machine and on its other load (the machines are shared), so compare ratios.
What each bench measures is in the docstring at the top of its source file.
The tests (tests/python/test_docs.py) run each command at a tiny size
(ELLROLL_BENCH_QUICK=1) and check that it prints the tables shown.
"""
# above each command: how tests/python/test_docs.py runs it (docs_blocks.py)
QUICK_MARKER = "<!-- docs-test: env ELLROLL_BENCH_QUICK=1 (a tiny size; ELLROLL_TEST_FULL=1 runs it as written) -->\n"
SHAPE_MARKER = "<!-- docs-test: output shape -->\n"
WORKPRECISION = "bench/workprecision.py"



def benches(build, quick):
    python = sys.executable
    exe = str(build / "ellroll")
    # the Fortran benches take a second or less as written; the Python ones run quick in the tests
    return [
        ("RK4 and DOP853 kernels: case-steps per second against a naive scalar RK4, one case and SIMD batches",
         [str(build / "bench_throughput"), "3" if quick else "7"]),
        ("What a scene costs: a record, a harmonic cup and rolling resistance against the fixed cup",
         [str(build / "bench_scene_cost"), "2" if quick else "5"]),
        ("Scenes and the summary against revision e61ab12: kernels, one case's scenes, harmonic and record "
         "campaigns against a fixed cup",
         [python, "bench/scene_campaigns.py", "--exe", exe, "--revision", "e61ab12", "--rounds", "7",
          *(["--quick"] if quick else [])]),
        ("slip = 'slide' on cases that never slide, against slip = 'end'",
         [python, "bench/slide_cost.py", "--exe", exe, "--rounds", "5", *(["--quick"] if quick else [])]),
        ("The journal's checksum per record",
         [str(build / "bench_journal_checksum")]),
        ("Campaign throughput on 1 and 2 threads, and peak memory against the number of cases",
         [python, "bench/campaign.py", "--exe", exe, "--cases", "1000" if quick else "10000",
          "--repeat", "1" if quick else "3", "--rss-cases", "1000", *([] if quick else ["10000", "100000"])]),
        ("Small campaigns on 1 and 2 threads: every thread gets work",
         [python, "bench/small_campaigns.py", "--exe", exe, "--repeat", "1" if quick else "5"]),
        ("Reading a file with h5py",
         [python, "bench/post.py", "--exe", exe, "--cases", "1000" if quick else "10000"]),
        ("ellroll-plot on a sampled campaign",
         [python, "bench/plots.py", "--exe", exe, "--cases", "2000" if quick else "100000"]),
        ("Work-precision of the paper's case (also in docs/accuracy.md)",
         [python, WORKPRECISION, "--exe", exe, *(["--quick"] if quick else [])]),
        ("vern9 against dop853 on 16 cases: one case and batches, rtol 1e-6 to 1e-13",
         [python, "bench/pairs.py", "--exe", exe, *(["--quick"] if quick else [])]),
    ]


def shown(command):
    """The command as docs/performance.md shows it: paths from the repository root."""
    words = []
    for word in command:
        if word == sys.executable:
            python = pathlib.Path(sys.executable)
            words.append(str(python.relative_to(ROOT)) if python.is_relative_to(ROOT) else "python")
        elif word.startswith(str(ROOT)):
            words.append(str(pathlib.Path(word).relative_to(ROOT)))
        else:
            words.append(word)
    return " ".join(words)


def machine():
    model = "unknown processor"
    try:
        for line in pathlib.Path("/proc/cpuinfo").read_text().splitlines():
            if line.startswith("model name"):
                model = line.split(":", 1)[1].strip()
                break
    except OSError:
        pass
    commit = subprocess.run(["git", "describe", "--always", "--dirty"], cwd=ROOT, capture_output=True,
                            text=True).stdout.strip()
    return (f"Machine: {model}, {os.cpu_count()} logical cores, {platform.system()} {platform.release()}; "
            f"commit {commit}; {datetime.date.today().isoformat()}.")


def main():
    parser = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    parser.add_argument("--build", default=str(ROOT / "build"))
    parser.add_argument("--quick", action="store_true")
    args = parser.parse_args()
    # bench/workprecision.py writes its figure and CSV in the current folder: it runs in a scratch
    # one, and docs/accuracy.md's figure and CSV are taken from there
    scratch = pathlib.Path(tempfile.mkdtemp(prefix="ellroll_bench_"))
    try:
        report(pathlib.Path(args.build).absolute(), args.quick, scratch)
    finally:
        shutil.rmtree(scratch, ignore_errors=True)


def report(build, quick, scratch):
    sections = [INTRO, machine() + "\n"]
    for title, command in benches(build, quick):
        text = shown(command)
        print(f"== {text}", file=sys.stderr, flush=True)
        result = subprocess.run([str(ROOT / w) if w == WORKPRECISION else w for w in command],
                                cwd=scratch if WORKPRECISION in command else ROOT, capture_output=True, text=True)
        if result.returncode != 0:
            sys.exit(f"bench failed: {text}\n{result.stderr}")
        markers = (QUICK_MARKER if command[0] == sys.executable else "") + SHAPE_MARKER
        sections.append(f"## {title}\n\n{markers}```sh\n{text}\n```\n\n"
                        f"```\n{result.stdout.rstrip()}\n```\n")
    text = "\n".join(sections)
    if quick:
        print(text)
    else:
        for name in ("workprecision.png", "workprecision.csv"):
            shutil.move(scratch / name, ROOT / "docs" / name)
        (ROOT / "docs" / "performance.md").write_text(text)
        print("wrote docs/performance.md, docs/workprecision.png and docs/workprecision.csv", file=sys.stderr)


if __name__ == "__main__":
    main()
