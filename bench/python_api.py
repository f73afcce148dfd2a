#!/usr/bin/env python3
"""The Python API's cost over the integration, beside the program's.

The paper's case (input/legeza1990.nml, t_end = 30 s) and a short variant
(t_end = 1 s), each run on one thread:

  - through the API, `ellroll.run(text)`: the whole call (namelist text in,
    xarray.DataTree out), and its parts: the library's run (reading the
    input, integrating, laying the results out), the copy of every dataset
    into numpy arrays, and the DataTree made of them;
  - through the program, `ellroll run` in a fresh process writing its HDF5
    file, then the file read back with h5py (every dataset).

The integration time is the run's own figure, /summary/wall_time. The
overhead is the call's time less it; the target is a call within 50 us plus
1.1 times the integration. Each figure is the best of --repeat runs.

    .venv/bin/python bench/python_api.py [--exe build/ellroll] [--repeat 20] [--quick]

--quick (or ELLROLL_BENCH_QUICK=1): three runs of each (a smoke test).
"""
import argparse
import pathlib
import subprocess
import sys
import tempfile
import time

import h5py

from common import executable, quick

ROOT = pathlib.Path(__file__).resolve().parents[1]
sys.path.insert(0, str(ROOT / "post"))
import ellroll  # noqa: E402  (the checkout's package)

PAPER = (ROOT / "input" / "legeza1990.nml").read_text()
CASES = [("paper case, t_end = 30 s", PAPER), ("t_end = 1 s", PAPER.replace("t_end = 30.0", "t_end = 1.0"))]


def best(repeat, measure):
    """The smallest of each figure measure() returns, over `repeat` calls."""
    figures = [measure() for _ in range(repeat)]
    return {key: min(f[key] for f in figures) for key in figures[0]}


def api_figures(text):
    """One call and its parts (seconds), and its integration time."""
    start = time.perf_counter()
    tree = ellroll.run(text, threads=1)
    call = time.perf_counter() - start
    lib, encoded = ellroll._lib(), text.encode()
    start = time.perf_counter()
    handle = lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1)
    core = time.perf_counter() - start
    try:
        start = time.perf_counter()
        groups, attrs = ellroll._datasets(lib, handle)
        arrays = time.perf_counter() - start
    finally:
        lib.ellroll_free(handle)
    start = time.perf_counter()
    ellroll._tree(groups, attrs)
    datatree = time.perf_counter() - start
    start = time.perf_counter()
    plain, _ = ellroll.run_arrays(text, threads=1)
    arrays_call = time.perf_counter() - start - float(plain["summary"]["wall_time"][0])
    integration = float(tree["summary"]["wall_time"][0])
    core_integration = float(next(v for n, _, v, _ in groups["summary"] if n == "wall_time")[0])
    return {"call": call, "integration": integration, "core": core - core_integration, "arrays": arrays,
            "datatree": datatree, "call_overhead": call - integration, "arrays_overhead": arrays_call}


def cli_figures(exe, folder, text):
    (folder / "in.nml").write_text(text)
    (folder / "out.h5").unlink(missing_ok=True)
    start = time.perf_counter()
    subprocess.run([exe, "run", "in.nml", "-o", "out.h5", "-q", "--threads", "1"], cwd=folder, check=True,
                   stdout=subprocess.DEVNULL)
    process = time.perf_counter() - start
    start = time.perf_counter()
    with h5py.File(folder / "out.h5", "r") as f:
        f.visititems(lambda name, item: item[()] if isinstance(item, h5py.Dataset) else None)
    return {"process": process, "read": time.perf_counter() - start}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--exe", default="build/ellroll", help="the ellroll program (default build/ellroll)")
    parser.add_argument("--repeat", type=int, default=20, help="runs of each; the best counts (default 20)")
    parser.add_argument("--quick", action="store_true", help="three runs of each (a smoke test)")
    args = parser.parse_args()
    exe = executable(args.exe)
    repeat = 3 if quick(args.quick) else args.repeat
    print(f"libellroll: {ellroll.library_path()}; one thread; best of {repeat}; ms")
    print(f"{'case':<26}{'integration':>12}{'API call':>10}{'overhead':>10}{'target':>9}"
          f"{'arrays ovh':>11}{'core':>7}{'arrays':>8}{'DataTree':>10}{'CLI':>8}{'h5py':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        for name, text in CASES:
            ellroll.run(text, threads=1)                      # the library loaded, the caches warm
            api = best(repeat, lambda: api_figures(text))
            cli = best(repeat, lambda: cli_figures(exe, folder, text))
            target = 50e-6 + 1.1 * api["integration"]
            ms = {key: value * 1e3 for key, value in {**api, **cli, "target": target}.items()}
            print(f"{name:<26}{ms['integration']:>12.3f}{ms['call']:>10.3f}{ms['call_overhead']:>10.3f}"
                  f"{ms['target']:>9.3f}{ms['arrays_overhead']:>11.3f}{ms['core']:>7.3f}{ms['arrays']:>8.3f}{ms['datatree']:>10.3f}"
                  f"{ms['process']:>8.3f}{ms['read']:>7.3f}")
    print("integration: /summary/wall_time; overhead: ellroll.run's call less it; target: 50 us + 1.1 x integration;")
    print("arrays ovh: ellroll.run_arrays's call less its integration (numpy arrays, no xarray);")
    print("core: the library's run less its integration (input, lay-out); arrays: every dataset into numpy;")
    print("DataTree: the xarray.DataTree made of them; CLI: `ellroll run` (process and file); h5py: reading it all")


if __name__ == "__main__":
    main()
