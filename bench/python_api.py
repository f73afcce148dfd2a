#!/usr/bin/env python3
"""The Python API's cost over the integration, beside the program's.

The paper's case (input/legeza1990.nml, t_end = 30 s) and a short variant
(t_end = 1 s), each run on one thread, in one table side by side:

  - the integration alone: the run's own figure, /summary/wall_time;
  - `ellroll.run_arrays(text)` (numpy arrays): its overhead (a call less
    its integration) against the aim of 50 us plus 0.1 times the
    integration (a call within 50 us + 1.1 x the integration), as a share
    of it and as the ratio of the call to the integration alone, and the
    overhead's parts: the library's run less its integration (reading the
    input, laying the results out) and the arrays made of its datasets;
  - `ellroll.run(text)` (an xarray.DataTree): its overhead, as a share of
    the same allowance, and the DataTree's making in it;
  - the program, `ellroll run` in a fresh process writing its HDF5 file,
    then the file read back with h5py (every dataset);
  - the paper case's DataTree made part by part as run() makes it, and a
    DataTree of the same nodes holding their scales alone.

Each figure is the best of --repeat calls in a row (as a loop makes them).

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


def arrays_figures(text):
    """run_arrays: the call less its integration, and the integration (seconds)."""
    start = time.perf_counter()
    arrays, _ = ellroll.run_arrays(text, threads=1)
    call = time.perf_counter() - start
    integration = float(arrays["summary"]["wall_time"][0])
    return {"integration": integration, "arrays_overhead": call - integration}


def run_figures(text):
    """run: the call less its integration (seconds)."""
    start = time.perf_counter()
    tree = ellroll.run(text, threads=1)
    return {"run_overhead": time.perf_counter() - start - float(tree["summary"]["wall_time"][0])}


def part_figures(text):
    """The parts of a call (seconds): the library's run less its integration,
    the arrays made of its datasets, the DataTree made of them."""
    lib, encoded = ellroll._lib(), text.encode()
    start = time.perf_counter()
    handle = lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1)
    library = time.perf_counter() - start
    try:
        start = time.perf_counter()
        groups, attrs = ellroll._datasets(lib, handle)
        copy_out = time.perf_counter() - start
    finally:
        lib.ellroll_free(handle)
    start = time.perf_counter()
    ellroll._tree(groups, attrs)
    datatree = time.perf_counter() - start
    library -= float(next(v for n, _, v, _ in groups["summary"] if n == "wall_time")[0])
    return {"library": library, "copy_out": copy_out, "datatree": datatree}


def datatree_parts(text, repeat):
    """The paper case's DataTree made part by part as run() makes it
    (ellroll._Template.tree, its Datasets made once), each part timed on its
    own (seconds, the best of `repeat`): the root's node, the groups' nodes,
    the variables' data set, the groups joining the root; and a DataTree of
    the same nodes holding their scales alone (xarray's least for this shape)."""
    import xarray as xr
    lib, encoded = ellroll._lib(), text.encode()
    handle = lib.ellroll_run(encoded, len(encoded), b"<input>", 7, 1)
    try:
        groups, root_attrs = ellroll._datasets(lib, handle)
    finally:
        lib.ellroll_free(handle)
    template = ellroll._Template(xr, groups)
    scales = {group: dataset.drop_vars([n for n in dataset.variables if n not in dataset.xindexes])
              for group, dataset, _, _ in template.nodes}
    figures = {"root": [], "groups": [], "values": [], "join": [], "all": [], "scales": []}
    clock = time.perf_counter
    for _ in range(repeat):
        nodes, made, filled = {}, {}, 0.0
        begin = clock()
        for group, dataset, fill, deep in template.nodes:
            start = clock()
            node = xr.DataTree(dataset)
            made[group] = clock() - start
            start = clock()
            own, variables = node.variables, groups.get(group, [])
            for position, name in fill:
                own[name].data = variables[position][2]
            for position, name in deep:
                own[name].attrs = {k: v for k, v in variables[position][3].items() if k != "coordinates"}
            nodes[group] = node
            filled += clock() - start
        tree = nodes.pop("")
        tree.attrs = dict(root_attrs)
        start = clock()
        tree.children = nodes
        figures["join"].append(clock() - start)
        figures["all"].append(clock() - begin)
        figures["root"].append(made.pop(""))
        figures["groups"].append(sum(made.values()))
        figures["values"].append(filled)
        start = clock()
        bare = {group: xr.DataTree(dataset) for group, dataset in scales.items()}
        bare.pop("").children = bare
        figures["scales"].append(clock() - start)
    count = sum(len(fill) for _, _, fill, _ in template.nodes)
    return {key: min(values) for key, values in figures.items()}, count


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
    print(f"{'':<38}|{'run_arrays':^34}|{'overhead parts':^17}|{'run()':^25}|{'CLI':^15}")
    print(f"{'case':<26}{'integration':>12}{'overhead':>9}{'allowed':>9}{'share':>7}{'ratio':>9}"
          f"{'library':>9}{'arrays':>8}{'overhead':>9}{'share':>7}{'DataTree':>9}{'process':>8}{'h5py':>7}")
    with tempfile.TemporaryDirectory() as tmp:
        folder = pathlib.Path(tmp)
        for name, text in CASES:
            ellroll.run(text, threads=1)                      # the library loaded, the caches warm
            # (each kind of call `repeat` times in a row, as a loop calls it)
            api = {**best(repeat, lambda: arrays_figures(text)), **best(repeat, lambda: run_figures(text)),
                   **best(repeat, lambda: part_figures(text))}
            cli = best(repeat, lambda: cli_figures(exe, folder, text))
            allowed = 50e-6 + 0.1 * api["integration"]
            ms = {key: value * 1e3 for key, value in {**api, **cli, "allowed": allowed}.items()}
            print(f"{name:<26}{ms['integration']:>12.3f}{ms['arrays_overhead']:>9.3f}{ms['allowed']:>9.3f}"
                  f"{100 * api['arrays_overhead'] / allowed:>6.0f}%"
                  f"{1 + api['arrays_overhead'] / api['integration']:>8.3f}x"
                  f"{ms['library']:>9.3f}{ms['copy_out']:>8.3f}{ms['run_overhead']:>9.3f}"
                  f"{100 * api['run_overhead'] / allowed:>6.0f}%{ms['datatree']:>9.3f}"
                  f"{ms['process']:>8.3f}{ms['read']:>7.3f}")
    print("integration: /summary/wall_time; run_arrays: its overhead (a call less its integration) against")
    print("the allowed 50 us + 0.1 x integration (share: of it used; ratio: the call / the integration alone);")
    print("library: the library's run less its integration (the input, the lay-out); arrays: the datasets into numpy;")
    print("run(): its overhead, its share of the same allowance, and the xarray.DataTree's making in it;")
    print("CLI: `ellroll run` (process and file), then h5py reading it all")
    parts, count = datatree_parts(PAPER, 25 * repeat)
    ms = {key: value * 1e3 for key, value in parts.items()}
    print(f"DataTree of the paper case, part by part (best of {25 * repeat}; ms): the root's node {ms['root']:.3f}, "
          f"the groups' nodes {ms['groups']:.3f},")
    print(f"the data of {count} variables set {ms['values']:.3f}, the 3 groups joining the root {ms['join']:.3f}; "
          f"in all {ms['all']:.3f}")
    print(f"a DataTree of the same nodes holding their scales alone (time, xyz, mode; case): {ms['scales']:.3f}")


if __name__ == "__main__":
    main()
