"""ellroll from Python: run an input in memory and get the results as the
output file lays them out.

    import ellroll
    tree = ellroll.run(open("input/legeza1990.nml").read())
    tree["summary"]["theta_max"]            # the file's /summary/theta_max
    tree["trajectory"]["nutation"].sel(time=5.0)

`run` takes the namelist text of an input, or a dict of its groups
({'geometry': {'a': 1.0, ...}, ...}; a group given more than once, as
&sweep or &record, as a list of dicts), runs every case in the Fortran
core (libellroll, through ctypes; the GIL is released while it runs) and
returns an xarray.DataTree with the groups case, summary and trajectory:
the same datasets, values (bit for bit), units, long names and statuses as
the file `ellroll run` writes (docs/python.md). Bad input raises
InputError with the message `ellroll run` prints.

The library is looked for in $ELLROLL_LIB (the file), beside this package,
in the build/ folder of the checkout the package comes from (pip install -e
post/, as .ci/setup installs it), then in the lib/ folder beside the bin/
of the `ellroll` on PATH (cmake --install's layout).
"""
import ctypes
import os
import pathlib
import shutil
import threading

import numpy as np

__all__ = ["run", "run_arrays", "namelist", "Error", "InputError", "library_path"]

# the error classes of `ellroll run`'s exit codes
_INTERNAL, _INPUT = 1, 2
_REAL, _INT, _TEXT = 1, 2, 3


class Error(Exception):
    """A run that failed; `code` is the exit code `ellroll run` gives it, `message` its message."""

    def __init__(self, message, code=_INTERNAL):
        super().__init__(message)
        self.message = message
        self.code = code


class InputError(Error, ValueError):
    """A bad input (`ellroll run` exits 2): the message names the group, variable and value."""


_lock = threading.Lock()
_library = None


def library_path():
    """The libellroll the package loads: $ELLROLL_LIB, beside the package, the checkout's build/,
    or the lib/ of the installed `ellroll` on PATH."""
    if os.environ.get("ELLROLL_LIB"):
        return pathlib.Path(os.environ["ELLROLL_LIB"])
    here = pathlib.Path(__file__).resolve().parent
    candidates = [here / "libellroll.so", here.parents[1] / "build" / "libellroll.so"]
    program = shutil.which("ellroll")
    if program:
        prefix = pathlib.Path(program).resolve().parents[1]
        candidates += [prefix / "lib" / "libellroll.so", *prefix.glob("lib/*/libellroll.so")]
    for candidate in candidates:
        if candidate.exists():
            return candidate
    raise Error("libellroll.so not found (looked in: " + ", ".join(map(str, candidates)) + "); build ellroll "
                "(bash .ci/setup) or set ELLROLL_LIB to the library's path")


def _lib():
    global _library
    with _lock:
        if _library is None:
            lib = ctypes.CDLL(str(library_path()))
            handle, i64, c_int, buf = ctypes.c_void_p, ctypes.c_int64, ctypes.c_int, ctypes.c_char_p
            signatures = {
                "ellroll_init": (None, []),
                "ellroll_run": (handle, [buf, i64, buf, i64, c_int]),
                "ellroll_free": (None, [handle]),
                "ellroll_error_code": (c_int, [handle]),
                "ellroll_error_message": (i64, [handle, ctypes.c_void_p, i64]),
                "ellroll_dataset_count": (c_int, [handle]),
                "ellroll_dataset_text": (i64, [handle, c_int, c_int, ctypes.c_void_p, i64]),
                "ellroll_dataset_info": (c_int, [handle, c_int, ctypes.POINTER(c_int), ctypes.POINTER(c_int),
                                                 ctypes.POINTER(c_int), ctypes.POINTER(i64)]),
                "ellroll_dataset_read": (c_int, [handle, c_int, ctypes.c_void_p, i64]),
                "ellroll_catalog": (i64, [handle, ctypes.c_void_p, i64]),
            }
            for name, (restype, argtypes) in signatures.items():
                function = getattr(lib, name)
                function.restype, function.argtypes = restype, argtypes
            lib.ellroll_init()
            _library = lib
    return _library


def _text(function, *args, size=256):
    """A text the library copies out: asked once with a buffer, again if it was short."""
    while True:
        buffer = ctypes.create_string_buffer(size)
        length = function(*args, buffer, size)
        if length < 0:
            raise Error(f"libellroll: {function.__name__}{args[1:]} failed")
        if length <= size:
            return buffer.raw[:length].decode()
        size = length


# ------------------------------------------------------------- the input


def _literal(value, where):
    """A Python value as a Fortran namelist literal."""
    if isinstance(value, (bool, np.bool_)):
        return ".true." if value else ".false."
    if isinstance(value, (int, np.integer)):
        return str(int(value))
    if isinstance(value, (float, np.floating)):
        # repr: the shortest text that reads back as the same double
        return repr(float(value))
    if isinstance(value, str):
        return "'" + value.replace("'", "''") + "'"
    if isinstance(value, (list, tuple, np.ndarray)):
        items = np.asarray(value, dtype=object).ravel() if isinstance(value, np.ndarray) else value
        if len(items) == 0:
            raise InputError(f"{where}: an empty list has no namelist value", _INPUT)
        return ", ".join(_literal(item, where) for item in items)
    raise InputError(f"{where}: {value!r} ({type(value).__name__}) has no namelist value "
                     "(numbers, logicals, texts or lists of them)", _INPUT)


def namelist(groups):
    """The namelist text of a dict of groups: {'geometry': {'a': 1.0}, 'sweep': [{...}, {...}]}.

    Numbers are written so that they read back as the same doubles, texts
    quoted, logicals .true./.false., lists comma-separated; a group given as
    a list of dicts is written once per dict (&sweep, &record).
    """
    lines = []
    for group, contents in groups.items():
        for members in contents if isinstance(contents, (list, tuple)) else [contents]:
            if not isinstance(members, dict):
                raise InputError(f"&{group}: give its variables as a dict (or a list of dicts), "
                                 f"not {type(members).__name__}", _INPUT)
            lines.append(f"&{group}")
            lines += [f"  {name} = {_literal(value, f'&{group}: {name}')}" for name, value in members.items()]
            lines.append("/")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------- the results


def _datasets(lib, handle):
    """Every dataset of a finished run: {group: [(name, dims, values, attrs), ...]}, and the root's attributes."""
    groups = {}
    # one text describes them all (ellroll_catalog): a record per dataset,
    # fields ended by ASCII's unit separator
    for i, record in enumerate(_text(lib.ellroll_catalog, handle, size=65536).split("\x1e")[:-1]):
        group, name, units, long_name, dims, kind, itemsize, shape, other, _ = record.split("\x1f")
        kind = int(kind)
        values = np.empty(tuple(int(n) for n in shape.split()),
                          dtype={_REAL: np.float64, _INT: np.int64, _TEXT: f"S{itemsize}"}[kind])
        if lib.ellroll_dataset_read(handle, i, values.ctypes.data, values.nbytes) != 0:
            raise Error(f"libellroll: cannot read dataset {group}/{name}")
        if kind == _TEXT:
            values = np.char.rstrip(values).astype(str)
        attrs = {"units": units, "long_name": long_name}
        attrs.update(_attributes(other))
        groups.setdefault(group, []).append((name, tuple(dims.split()), values, attrs))
    return groups, _attributes(_text(lib.ellroll_dataset_text, handle, -1, 5))


def _attributes(lines):
    attrs = {}
    for line in lines.splitlines():
        name, kind, value = line.split("\t", 2)
        if kind in ("i4", "i8"):
            attrs[name] = np.array(value.split(), dtype=np.int32 if kind == "i4" else np.int64)
        elif name == "input_namelist":
            attrs[name] = value.replace("\\n", "\n").replace("\\\\", "\\")
        else:
            attrs[name] = value
    return attrs


def _dataset(xr, variables, extra_coords=()):
    """An xarray.Dataset of a group: its scales and its `coordinates` as coordinates."""
    coordinate_names = set(extra_coords)
    for name, dims, values, attrs in variables:
        coordinate_names.update(attrs.pop("coordinates", "").split())
        if dims == (name,):                  # a dimension scale: case, time, xyz, mode
            coordinate_names.add(name)
    data_vars, coords = {}, {}
    for name, dims, values, attrs in variables:
        (coords if name in coordinate_names else data_vars)[name] = xr.Variable(dims, values, attrs)
    return xr.Dataset(data_vars, coords)


def _tree(groups, root_attrs):
    import xarray as xr
    root = _dataset(xr, groups.get("", []))
    root.attrs.update(root_attrs)
    datasets = {name: _dataset(xr, groups.get(name, [])) for name in ("case", "summary", "trajectory")}
    if hasattr(xr, "DataTree"):
        # the root's scales (time, xyz, mode) are inherited by the groups
        return xr.DataTree.from_dict({"/": root, **{f"/{name}": ds for name, ds in datasets.items()}})
    datasets["trajectory"] = datasets["trajectory"].assign_coords(
        {name: root[name] for name in ("time", "xyz") if name in root.coords})
    return {"/": root, **datasets}


def run_arrays(inputs, threads=None, *, path=None):
    """Run an input in memory; its results as plain numpy arrays.

    The same run as run() without xarray: {group: {name: array}} for the
    groups '' (the root's scales), 'case', 'summary' and 'trajectory', and
    the arrays' dimension names, units and long names in
    `attributes[group][name]` ({'dims': (...), 'units': ..., 'long_name': ...,
    and flag_values / flag_meanings where the file has them}), returned as
    (arrays, attributes). For calls in a loop (an optimisation), where
    building an xarray.DataTree (milliseconds) would cost more than the
    integration.
    """
    groups, _ = _run_groups(inputs, threads, path)
    arrays = {group: {name: values for name, _, values, _ in items} for group, items in groups.items()}
    attributes = {group: {name: {"dims": dims, **attrs} for name, dims, _, attrs in items}
                  for group, items in groups.items()}
    return arrays, attributes


def run(inputs, threads=None, *, path=None):
    """Run an input in memory; its results as the output file lays them out.

    inputs: the namelist text of an input, or a dict of its groups (namelist()).
    threads: threads to run the cases on (None: OMP_NUM_THREADS or all cores),
        as `ellroll run --threads`; the results are the same for any count.
    path: the input's name in messages, and the folder its record files are
        relative to (default '<input>', in the current folder).
    The &output group needs no file here (one given is not written).

    Returns an xarray.DataTree with the groups case, summary and trajectory
    (time, xyz and mode at its root, inherited by the groups), or a dict of
    xarray.Datasets where xarray has no DataTree. Raises InputError for a bad
    input, Error for any other failure, each with the message `ellroll run`
    prints. The GIL is released while the cases run (ctypes releases it for
    every call into the library), so other Python threads go on, and several
    runs may go at the same time. run_arrays() gives the same results as
    numpy arrays, without xarray's cost.
    """
    return _tree(*_run_groups(inputs, threads, path))


def _run_groups(inputs, threads, path):
    """The library's run of an input: its datasets by group, and the root's attributes."""
    text = inputs if isinstance(inputs, str) else namelist(inputs)
    if threads is not None and (not isinstance(threads, (int, np.integer)) or threads < 1):
        raise ValueError(f"threads = {threads!r}: give a count of at least 1, or None")
    lib = _lib()
    label = (path if path is not None else "<input>").encode()
    encoded = text.encode()
    handle = lib.ellroll_run(encoded, len(encoded), label, len(label), int(threads or 0))
    if not handle:
        raise Error("libellroll: out of memory")
    try:
        code = lib.ellroll_error_code(handle)
        if code != 0:
            message = _text(lib.ellroll_error_message, handle)
            raise (InputError if code == _INPUT else Error)(message, code)
        groups, root_attrs = _datasets(lib, handle)
    finally:
        lib.ellroll_free(handle)
    return groups, root_attrs
