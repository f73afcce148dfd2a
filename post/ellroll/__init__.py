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
import builtins
import ctypes
import numbers
import os
import pathlib
import queue
import shutil
import re
import signal
import tempfile
import threading

import numpy as np

__all__ = ["run", "run_arrays", "namelist", "Record", "Error", "InputError", "library_path"]

# the error classes of `ellroll run`'s exit codes
_INTERNAL, _INPUT = 1, 2
_REAL, _INT, _TEXT = 1, 2, 3
# the most bytes a record file may hold (docs/inputs.md), as the run reads it
RECORD_FILE_LIMIT = 2**30


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


class Record:
    """A ground-acceleration record given as arrays, for `record_file` in a dict input.

    time: increasing sample times (s), the first at 0 or before;
    acceleration: one row per time, a column per axis (x, y[, z]), m/s^2.
    run() writes it as a CSV file in a private folder for the run (each
    number as the shortest text that reads back as the same double, so the
    run equals one of the same CSV given by name) and removes it after.
    """

    def __init__(self, time, acceleration, name="record"):
        if not isinstance(name, str):
            raise InputError(f"Record name {name!r}: give a text (letters, digits, '_', '.', '-'; 1 to 32), "
                             f"not {type(name).__name__}", _INPUT)
        self.time = _real_array(time, "time", name)
        self.acceleration = _real_array(acceleration, "acceleration", name)
        if self.time.ndim != 1 or self.acceleration.ndim != 2 or \
                self.acceleration.shape[0] != self.time.shape[0] or self.acceleration.shape[1] not in (2, 3):
            raise InputError(f"Record {name!r}: give time as n values and acceleration as n rows of 2 or 3 "
                             f"(x, y[, z]), not shapes {self.time.shape} and {self.acceleration.shape}", _INPUT)
        # (as &record name: at most 32 characters)
        if not re.fullmatch(r"[A-Za-z0-9_.-]{1,32}", name):
            raise InputError(f"Record name {name!r}: letters, digits, '_', '.', '-' (1 to 32)", _INPUT)
        self.name = name

    def csv_text(self):
        """The record as a CSV file's text: `time, ax, ay[, az]`, m/s^2."""
        return "".join(self._csv_chunks())

    def _csv_chunks(self, rows=65536):
        """csv_text in pieces of `rows` rows."""
        columns = np.column_stack([self.time, self.acceleration])
        for start in range(0, len(columns), rows):
            yield "".join(", ".join(repr(float(v)) for v in row) + "\n" for row in columns[start:start + rows])

    def write_csv(self, path):
        """Write csv_text to a new file at path, piece by piece; InputError
        as soon as it passes what a record file may hold (1 GiB), or where
        its rows could not fit there even at their shortest."""
        rows, width = len(self.time), 1 + self.acceleration.shape[1]
        shortest_row = 3 * width + 2 * (width - 1) + 1          # "0.0, 0.0, 0.0\n"
        if rows * shortest_row > RECORD_FILE_LIMIT:
            raise InputError(f"Record {self.name!r}: {rows} rows of {width} numbers take at least "
                             f"{rows * shortest_row} bytes as CSV, more than a record file may hold (1 GiB)", _INPUT)
        written = 0
        with builtins.open(path, "x", encoding="ascii") as handle:
            for chunk in self._csv_chunks():
                written += len(chunk)
                if written > RECORD_FILE_LIMIT:
                    raise InputError(f"Record {self.name!r}: its CSV text passes {RECORD_FILE_LIMIT} bytes, more "
                                     f"than a record file may hold (1 GiB)", _INPUT)
                handle.write(chunk)


def _real_array(values, argument, name):
    """values as float64; InputError unless each is a real number (numpy
    would drop a complex part with only a warning, and read True as 1)."""
    try:
        array = np.asarray(values)
    except (ValueError, TypeError) as error:          # ragged rows
        raise InputError(f"Record {name!r}: {argument}: {error}", _INPUT) from None
    if not isinstance(values, np.ndarray) and array.dtype.kind in "iuf":
        # a list mixing logicals with numbers becomes numbers: look at its items
        for value in np.asarray(values, dtype=object).ravel().tolist():
            if isinstance(value, (bool, np.bool_)):
                raise InputError(f"Record {name!r}: {argument} must be real numbers, not bool ({value!r})", _INPUT)
    if array.dtype.kind == "O":                       # Python objects: each a real number
        for value in array.ravel().tolist():
            if not _is_real_number(value):
                raise InputError(f"Record {name!r}: {argument} must be real numbers, not "
                                 f"{type(value).__name__} ({value!r})", _INPUT)
    elif array.dtype.kind not in "iuf":
        words = {"c": "complex", "b": "logicals", "U": "text", "S": "bytes"}.get(array.dtype.kind, str(array.dtype))
        raise InputError(f"Record {name!r}: {argument} must be real numbers, not {words} "
                         f"(dtype {array.dtype})", _INPUT)
    return array.astype(np.float64)


def _is_real_number(value):
    """Whether value is a real number (not a logical, a text or a complex number) float() reads."""
    if isinstance(value, (bool, np.bool_, str, bytes)) or \
            (isinstance(value, numbers.Complex) and not isinstance(value, numbers.Real)):
        return False
    try:
        float(value)
    except (TypeError, ValueError):
        return False
    return True


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
                "ellroll_read_all": (c_int, [handle, c_int, ctypes.c_void_p]),
                "ellroll_take": (c_int, [handle, c_int, ctypes.c_void_p, ctypes.c_void_p, ctypes.c_void_p]),
                "ellroll_free_values": (None, [handle]),
                "ellroll_stop": (None, [c_int]),
            }
            for name, (restype, argtypes) in signatures.items():
                function = getattr(lib, name)
                function.restype, function.argtypes = restype, argtypes
            lib.ellroll_init()
            _library = lib
    return _library


def _text(function, *args, size=256, decode=True):
    """A text the library copies out: asked once with a buffer, again if it was short."""
    while True:
        buffer = ctypes.create_string_buffer(size)
        length = function(*args, buffer, size)
        if length < 0:
            raise Error(f"libellroll: {function.__name__}{args[1:]} failed")
        if length <= size:
            text = ctypes.string_at(buffer, length)
            return text.decode() if decode else text
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
        # a namelist text ends on its line: a line break would end the group's
        # text there, and the error would name a line of text nobody wrote
        if any(mark in value for mark in "\n\r"):
            shown = repr(value) if len(value) <= 60 else repr(value[:50]) + "..."
            raise InputError(f"{where}: a text value cannot hold a line break ({shown})", _INPUT)
        return "'" + value.replace("'", "''") + "'"
    if isinstance(value, Record):
        raise InputError(f"{where}: a Record is written for run() and run_arrays(); give namelist() a file name",
                         _INPUT)
    if isinstance(value, (list, tuple, np.ndarray)):
        items = np.asarray(value, dtype=object).ravel() if isinstance(value, np.ndarray) else value
        if (isinstance(value, np.ndarray) and value.ndim > 1) or \
                any(isinstance(item, (list, tuple, np.ndarray)) for item in items):
            items = _rows(value, where)
        if len(items) == 0:
            raise InputError(f"{where}: an empty list has no namelist value", _INPUT)
        return ", ".join(_literal(item, where) for item in items)
    raise InputError(f"{where}: {value!r} ({type(value).__name__}) has no namelist value "
                     "(numbers, logicals, texts or lists of them)", _INPUT)


def _rows(value, where):
    """A nested list's items row by row, as numpy would lay out its array;
    InputError for a ragged one (rows of different lengths), whose values
    would otherwise run as one flat list that nobody wrote."""
    try:
        array = np.array(value, dtype=object)
    except ValueError:
        array = None
    if array is None or any(isinstance(item, (list, tuple, np.ndarray)) for item in array.ravel()):
        raise InputError(f"{where}: {value!r} is a ragged nested list (rows of different lengths): give one "
                         "list of values, or rows of one length", _INPUT)
    if 1 in array.shape:
        # a vector kept in a table of one row or column (numpy's keepdims, a
        # slice [i:i+1]): which values were meant is a guess
        raise InputError(f"{where}: a nested list or array of shape {array.shape} is a table with a row or "
                         "column of one: give one flat list of values (numpy: .ravel()), or rows of one length",
                         _INPUT)
    return array.ravel()


_GROUP_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*", re.ASCII)
_VARIABLE_NAME = re.compile(r"[A-Za-z][A-Za-z0-9_]*(\([1-9][0-9]*\))?", re.ASCII)


def _require_groups(value):
    """InputError unless value is a dict of groups (what namelist() writes)."""
    if not isinstance(value, dict):
        raise InputError(f"the input must be a namelist text (str) or a dict of groups, not "
                         f"{type(value).__name__}", _INPUT)


def namelist(groups):
    """The namelist text of a dict of groups: {'geometry': {'a': 1.0}, 'sweep': [{...}, {...}]}.

    Numbers are written so that they read back as the same doubles, texts
    quoted, logicals .true./.false., lists comma-separated; a group given as
    a list of dicts is written once per dict (&sweep, &record).
    """
    _require_groups(groups)
    lines = []
    for group, contents in groups.items():
        if not isinstance(group, str) or not _GROUP_NAME.fullmatch(group):
            raise InputError(f"group name {group!r}: a namelist group is a name (a letter, then letters, digits "
                             "or '_'), e.g. 'geometry'", _INPUT)
        for members in contents if isinstance(contents, (list, tuple)) else [contents]:
            if not isinstance(members, dict):
                raise InputError(f"&{group}: give its variables as a dict (or a list of dicts), "
                                 f"not {type(members).__name__}", _INPUT)
            for name in members:
                if not isinstance(name, str) or not _VARIABLE_NAME.fullmatch(name):
                    raise InputError(f"&{group}: variable name {name!r}: a name (a letter, then letters, digits "
                                     "or '_'), or one element of it such as 'omega(3)'", _INPUT)
            lines.append(f"&{group}")
            lines += [f"  {name} = {_literal(value, f'&{group}: {name}')}" for name, value in members.items()]
            lines.append("/")
    return "\n".join(lines) + "\n"


# ------------------------------------------------------------- the results


class _Entry:
    """A dataset as the catalog describes it: where it goes, its type and shape, its attributes."""
    __slots__ = ("group", "name", "dims", "shape", "dtype", "text_dtype", "nbytes", "attrs", "deep", "offset")

    def __init__(self, group, name, units, long_name, dims, kind, itemsize, shape, other):
        self.group, self.name, self.dims = group, name, tuple(dims.split())
        self.shape = tuple(int(n) for n in shape.split())
        kind, itemsize = int(kind), int(itemsize)
        self.dtype = np.dtype({_REAL: np.float64, _INT: np.int64, _TEXT: f"S{itemsize}"}[kind])
        # texts: the C strings the library writes, as Python strings of as many characters
        self.text_dtype = np.dtype(f"U{itemsize}") if kind == _TEXT else None
        self.nbytes = int(np.prod(self.shape, dtype=np.int64)) * self.dtype.itemsize
        self.attrs = {"units": units, "long_name": long_name, **_attributes(other)}
        # (an attribute that is an array is copied for each run, as a dict is)
        self.deep = any(isinstance(v, np.ndarray) for v in self.attrs.values())
        self.offset = None                  # in the block of small datasets, or None: an array of its own

    def fresh_attrs(self):
        if self.deep:
            return {k: (v.copy() if isinstance(v, np.ndarray) else v) for k, v in self.attrs.items()}
        return dict(self.attrs)


# A dataset of this many bytes or more gets an array of its own; the smaller
# ones are views of one block (an array each would cost more than their
# values), which a view kept alive keeps whole: at most some 60 times this
# (texts go through the block, and become strings of their own).
_OWN_ARRAY_BYTES = 16384


class _Layout:
    """The datasets of a catalog, parsed once: the calls of a loop give the same catalog each time."""

    def __init__(self, catalog):
        self.entries = [_Entry(*record.split("\x1f")[:9]) for record in catalog.split("\x1e")[:-1]]
        own, kinds = [], {}
        for i, entry in enumerate(self.entries):
            if entry.nbytes >= _OWN_ARRAY_BYTES and entry.text_dtype is None:      # (texts: copied as strings)
                own.append(i)
            elif entry.nbytes > 0:
                kinds.setdefault((entry.dtype, entry.shape), []).append(i)
        # the block: the datasets of a type and shape one after another (8
        # bytes a value: each stays aligned), made into arrays together
        self.block_bytes = 0
        self.stacks = []                      # (indices, dtype, shape of the stack, offset, text dtype)
        for (dtype, shape), indices in kinds.items():
            for i in indices:
                self.entries[i].offset = self.block_bytes
                self.block_bytes += self.entries[i].nbytes
            self.stacks.append((indices, dtype, (len(indices), *shape), self.entries[indices[0]].offset,
                                self.entries[indices[0]].text_dtype))
        # the addresses of the block's datasets, less the block's; 0: none, or an array of its own
        self.offsets = np.array([e.offset if e.offset is not None else 0 for e in self.entries], dtype=np.uint64)
        self.in_block = np.array([e.offset is not None for e in self.entries])
        self.own = [i for i in own if self.entries[i].nbytes > 0]
        # (ellroll_take's: the datasets worth taking out rather than copying)
        self.want = np.zeros(len(self.entries), dtype=np.intc)
        self.want[self.own] = 1
        self.empty = [i for i, e in enumerate(self.entries) if e.nbytes == 0]
        self.template = None                  # run()'s _Template, made by its first call


_layouts = {}
_LAYOUTS_KEPT = 64


def _layout(catalog):
    layout = _layouts.get(catalog)
    if layout is None:
        layout = _Layout(catalog.decode())
        if len(_layouts) >= _LAYOUTS_KEPT:
            _layouts.clear()
        _layouts[catalog] = layout
    return layout


def _address(array):
    return array.__array_interface__["data"][0]


class _Values:
    """A dataset's values taken out of their run (ellroll_take), as numpy's
    base of the array over them: freed when the array, and every view of
    it, goes."""
    __slots__ = ("lib", "owner", "__array_interface__")

    def __init__(self, lib, owner, address, entry):
        self.lib, self.owner = lib, owner
        self.__array_interface__ = {"data": (address, False), "shape": entry.shape, "typestr": entry.dtype.str,
                                    "version": 3}

    def __del__(self):
        self.lib.ellroll_free_values(self.owner)


def _values(lib, handle):
    """Every dataset of a finished run: their _Layout and values (numpy
    arrays, in the catalog's order). A large dataset the library holds as
    the array lays it out (one case's trajectories, long columns) is taken
    from it as it is, without a copy; the others are copied out in one
    call."""
    layout = _layout(_text(lib.ellroll_catalog, handle, size=16384, decode=False))
    n = len(layout.entries)
    block = np.empty(layout.block_bytes, dtype=np.uint8)
    addresses = np.where(layout.in_block, layout.offsets + np.uint64(_address(block)), np.uint64(0))
    values = [None] * n
    if layout.own:
        owners, taken = np.empty(n, dtype=np.uint64), np.empty(n, dtype=np.uint64)
        if lib.ellroll_take(handle, n, _address(layout.want), _address(owners), _address(taken)) != 0:
            raise Error("libellroll: cannot read the datasets")
        for i in layout.own:
            entry = layout.entries[i]
            if owners[i]:
                values[i] = np.asarray(_Values(lib, int(owners[i]), int(taken[i]), entry))
            else:
                values[i] = np.empty(entry.shape, dtype=entry.dtype)
                addresses[i] = _address(values[i])
    if lib.ellroll_read_all(handle, n, _address(addresses)) != 0:
        raise Error("libellroll: cannot read the datasets")
    for indices, dtype, shape, offset, text_dtype in layout.stacks:
        stack = np.ndarray(shape, dtype=dtype, buffer=block, offset=offset)
        if text_dtype is not None:
            stack = stack.astype(text_dtype)
        for i, array in zip(indices, stack):              # (each a view of its row)
            values[i] = array
    for i in layout.empty:
        values[i] = np.empty(layout.entries[i].shape, dtype=layout.entries[i].dtype)
    return layout, values


# the library's escapes in the input's text: \\n a line feed, \\\\ a backslash
_UNESCAPE = re.compile(r"\\(.)", re.DOTALL)


class _Groups(dict):
    """_datasets' {group: [(name, dims, values, attrs), ...]}, with the _Layout they were read by."""
    __slots__ = ("layout",)


def _datasets(lib, handle):
    """Every dataset of a finished run: {group: [(name, dims, values, attrs), ...]}, and the root's attributes."""
    layout, values = _values(lib, handle)
    groups = _Groups()
    groups.layout = layout
    for entry, array in zip(layout.entries, values):
        groups.setdefault(entry.group, []).append((entry.name, entry.dims, array, entry.fresh_attrs()))
    return groups, _attributes(_text(lib.ellroll_dataset_text, handle, -1, 5))


def _attributes(lines):
    """The library's attributes: a line each (name, kind, value, by tabs); the
    input's text with its line feeds and backslashes escaped (\\n, \\\\), any
    other character (a CR of a Windows file, a form feed) as it stands."""
    attrs = {}
    for line in lines.split("\n"):
        if not line:
            continue
        name, kind, value = line.split("\t", 2)
        if kind in ("i1", "i4", "i8"):
            attrs[name] = np.array(value.split(), dtype={"i1": np.int8, "i4": np.int32, "i8": np.int64}[kind])
        elif kind == "f8":
            attrs[name] = np.array(value.split(), dtype=np.float64)
        elif name == "input_namelist":
            attrs[name] = _UNESCAPE.sub(lambda m: "\n" if m.group(1) == "n" else m.group(1), value)
        else:
            attrs[name] = value
    return attrs


def _dataset(xr, variables, attrs=None):
    """An xarray.Dataset of a group: its scales and its `coordinates` as coordinates.

    Made as xr.Coordinates of every variable (an index for each scale),
    turned into a Dataset whose data variables reset_coords sets apart:
    xarray checks the dimensions' sizes but merges and aligns nothing, which
    xr.Dataset(data_vars, coords) does, at twice the cost, for variables that
    the library lays out consistent already.
    """
    coordinate_names = set()
    for name, dims, values, var_attrs in variables:
        coordinate_names.update(var_attrs.pop("coordinates", "").split())
        if dims == (name,):                  # a dimension scale: case, time, xyz, mode
            coordinate_names.add(name)
    # the data variables first, then the coordinates: the order of xr.Dataset(data_vars, coords)
    data_names = [name for name, _, _, _ in variables if name not in coordinate_names]
    ordered = sorted(variables, key=lambda variable: variable[0] in coordinate_names)
    # (fastpath: the values are numpy arrays already, which xarray need not check)
    dataset = xr.Coordinates({name: xr.Variable(dims, values, var_attrs, fastpath=True)
                              for name, dims, values, var_attrs in ordered}).to_dataset().reset_coords(data_names)
    if attrs:
        dataset.attrs = attrs
    return dataset


_GROUPS = ("", "case", "summary", "trajectory")
# groups of some runs only: /limit_state where the input gives limit states,
# /switches where a case may slide
_OPTIONAL_GROUPS = ("limit_state", "switches")


def _groups_of(groups):
    """The groups of a run, in the file's order."""
    return _GROUPS + tuple(group for group in _OPTIONAL_GROUPS if group in groups)


class _Template:
    """The Datasets of a tree's nodes for one layout of the results (made
    once, by _dataset), which each call copies and puts its values in.

    Made from its arrays, a node costs some 15-20 us a variable through
    xarray's public constructors (xr.Coordinates copies each variable
    twice, reset_coords and DataTree(dataset) once more each, and each
    scale gets a pandas index). A call here makes each node of its
    template Dataset (DataTree copies each variable and index: the node's
    own Variables and attribute dicts) and sets each variable's data to
    its run's values, some 5 us a variable. The scales (the indexed
    coordinates: time, xyz, mode, case) keep the values they were made
    with: a call whose scales differ (fits) makes its own _Template.
    """

    def __init__(self, xr, groups):
        # (group, Dataset, [(position, name)] to fill, [(position, name)] with array attributes)
        self.nodes = []
        self.scales = []         # (group, position, the scale's bytes)
        for group in _groups_of(groups):
            variables = groups.get(group, [])
            made, fill, deep = [], [], []
            for position, (name, dims, values, attrs) in enumerate(variables):
                if dims == (name,):
                    self.scales.append((group, position, values.tobytes()))
                    made.append((name, dims, values.copy(), dict(attrs)))
                else:
                    # (a stand-in of the shape and type, no memory: every call sets its own values)
                    fill.append((position, name))
                    made.append((name, dims, np.broadcast_to(np.zeros((), values.dtype), values.shape), dict(attrs)))
                if any(isinstance(value, np.ndarray) for value in attrs.values()):
                    deep.append((position, name))
            dataset = _dataset(xr, made)
            if set(dataset.xindexes) != {name for name, dims, _, _ in variables if dims == (name,)}:
                raise Error(f"libellroll: the scales of group {group!r} are not its indexes")
            self.nodes.append((group, dataset, fill, deep))

    def fits(self, groups):
        """Whether the scales of groups are, bit for bit, those the template's indexes hold."""
        return all(groups[group][position][2].tobytes() == values for group, position, values in self.scales)

    def tree(self, xr, groups, root_attrs):
        """The DataTree of groups (a run of this layout) and root_attrs."""
        nodes = {}
        for group, dataset, fill, deep in self.nodes:
            node = xr.DataTree(dataset)            # (a copy: the node's own Variables and attribute dicts)
            own = node.variables
            variables = groups.get(group, [])
            for position, name in fill:
                own[name].data = variables[position][2]
            for position, name in deep:            # (the run's own arrays, not the template's)
                own[name].attrs = {k: v for k, v in variables[position][3].items() if k != "coordinates"}
            nodes[group] = node
        tree = nodes.pop("")
        tree.attrs = root_attrs
        # the root's scales (time, xyz, mode) are inherited by the groups; each
        # group joins the tree once (xarray checks its alignment with the root)
        tree.children = nodes
        return tree


def _tree(groups, root_attrs):
    import xarray as xr
    if not hasattr(xr, "DataTree"):
        root = _dataset(xr, groups.get("", []), root_attrs)
        datasets = {name: _dataset(xr, groups.get(name, [])) for name in _groups_of(groups)[1:]}
        datasets["trajectory"] = datasets["trajectory"].assign_coords(
            {name: root[name] for name in ("time", "xyz") if name in root.coords})
        return {"/": root, **datasets}
    layout = getattr(groups, "layout", None)
    template = layout.template if layout is not None else None
    if template is None or not template.fits(groups):
        template = _Template(xr, groups)
        if layout is not None:
            layout.template = template
    return template.tree(xr, groups, root_attrs)


def run_arrays(inputs, threads=None, *, path=None):
    """Run an input in memory; its results as plain numpy arrays.

    The same run as run() without xarray: {group: {name: array}} for the
    groups '' (the root's scales), 'case', 'summary' and 'trajectory' (and
    'limit_state', 'switches' where the run has them), and
    the arrays' dimension names, units and long names in
    `attributes[group][name]` ({'dims': (...), 'units': ..., 'long_name': ...,
    and flag_values / flag_meanings where the file has them}), returned as
    (arrays, attributes). For calls in a loop (an optimisation), where
    building an xarray.DataTree (milliseconds) would cost more than the
    integration. The arrays are the caller's: a large one (one case's
    trajectories) is the library's memory handed over without a copy and
    freed when the array goes; keeping one keeps nothing else of the run.
    """
    layout, values = _run_inputs(inputs, threads, path, _values)
    arrays, attributes = {}, {}
    for entry, array in zip(layout.entries, values):
        if entry.group not in arrays:
            arrays[entry.group], attributes[entry.group] = {}, {}
        arrays[entry.group][entry.name] = array
        attributes[entry.group][entry.name] = {"dims": entry.dims, **entry.fresh_attrs()}
    return arrays, attributes


def run(inputs, threads=None, *, path=None):
    """Run an input in memory; its results as the output file lays them out.

    inputs: the namelist text of an input, or a dict of its groups (namelist());
        in a dict, a record_file may be a Record (arrays).
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
    return _tree(*_run_inputs(inputs, threads, path, _datasets))


def _run_inputs(inputs, threads, path, results):
    """The library's run of an input, its results as results(lib, handle) reads them."""
    if isinstance(inputs, str):
        # (a file's last line must end with a line break; a string built in code often has none)
        return _run_text(inputs if inputs.endswith("\n") or not inputs else inputs + "\n", threads, path, results)
    _require_groups(inputs)
    try:
        private = tempfile.TemporaryDirectory(prefix="ellroll-records-")
    except OSError as exc:
        raise Error(f"cannot make a private folder for the Records' files in {tempfile.gettempdir()}: "
                    f"{exc.strerror or exc} (TMPDIR names another)", 3) from None
    with private as folder:
        records = {}
        try:
            text = namelist(_with_record_files(inputs, pathlib.Path(folder), records))
        except OSError as exc:
            # (a failed write names no file: the folder it was written in)
            raise Error(f"{exc.filename or folder}: cannot write a Record's file: {exc.strerror or exc}", 3) from None
        try:
            return _run_text(text, threads, path, results)
        except Error as error:
            message = _name_records(error.message, records)
            if message == error.message:
                raise
            raise type(error)(message, error.code) from None


def _name_records(message, records):
    """message with each Record's CSV file (a temporary file) and line named
    as the Record and its row (the file has a row a line, from row 0)."""
    for path, record in records.items():
        message = re.sub(re.escape(path) + r":(\d+)",
                         lambda m: f"Record {record.name!r} row {int(m.group(1)) - 1}", message)
        message = message.replace(f"'{path}'", f"Record {record.name!r}").replace(path, f"Record {record.name!r}")
        # (a variable's value, then the file's row: the Record named once)
        message = message.replace(f"Record {record.name!r}: Record {record.name!r} row", f"Record {record.name!r} row")
        message = message.replace(f"Record {record.name!r}: Record {record.name!r}: ", f"Record {record.name!r}: ")
    return message


def _with_record_files(groups, folder, records):
    """groups with each Record value replaced by the path of its CSV file,
    written into folder; records gets {path: Record}."""
    written = {}

    def file_of(value):
        if not isinstance(value, Record):
            return value
        if id(value) not in written:
            target = folder / f"{len(written) + 1}_{value.name}.csv"
            value.write_csv(target)
            written[id(value)] = str(target)
            records[str(target)] = value
        return written[id(value)]

    def members(group):
        return {name: ([file_of(v) for v in value] if isinstance(value, (list, tuple)) else file_of(value))
                for name, value in group.items()} if isinstance(group, dict) else group

    return {name: ([members(g) for g in contents] if isinstance(contents, (list, tuple)) else members(contents))
            for name, contents in groups.items()}


_flight_lock = threading.Lock()
_in_flight = 0              # ellroll_run calls under way, in any thread
_WAIT = 0.05                # s: how often the main thread looks up from a run
_worker = None              # the main thread's runs: (thread, its queue of jobs)


def _forget_the_worker():
    """A forked child has only the thread that forked: the parent's worker
    and the locks held in its other threads are not there."""
    global _lock, _flight_lock, _in_flight, _worker
    _lock = threading.Lock()
    _flight_lock = threading.Lock()
    _in_flight = 0
    _worker = None


os.register_at_fork(after_in_child=_forget_the_worker)


def _work(jobs):
    while True:
        function, args, box, done = jobs.get()
        try:
            box.append(function(*args))
        finally:
            done.set()


def _interruptible_run(lib, *args):
    """lib.ellroll_run(*args), stopped by Ctrl-C. From the main thread (where
    Python takes SIGINT) the call runs in a worker thread while this one
    waits in short steps: Ctrl-C asks the library to stop every run under
    way (ellroll_stop, as `ellroll run` does on SIGINT), waits for the call
    to return, frees its results and raises KeyboardInterrupt. The stop is
    lifted when no call is under way. The worker is one thread for the
    process's life: OpenMP keeps a team of threads for each thread that
    starts parallel work, which a new thread per call would make anew
    (some 0.6 ms a call measured)."""
    global _in_flight, _worker
    with _flight_lock:
        _in_flight += 1
    try:
        if threading.current_thread() is not threading.main_thread():
            return lib.ellroll_run(*args)
        if _worker is None:
            jobs = queue.SimpleQueue()
            thread = threading.Thread(target=_work, args=(jobs,), name="ellroll-run", daemon=True)
            thread.start()
            _worker = (thread, jobs)
        box, done = [], threading.Event()
        _worker[1].put((lib.ellroll_run, args, box, done))
        try:
            while not done.wait(_WAIT):
                pass
        except KeyboardInterrupt:
            lib.ellroll_stop(signal.SIGINT)
            while not done.is_set():
                try:
                    done.wait()
                except KeyboardInterrupt:     # (pressed again: the call still has to return)
                    pass
            if box:
                lib.ellroll_free(box[0])
            raise
        return box[0]
    finally:
        with _flight_lock:
            _in_flight -= 1
            if _in_flight == 0:
                lib.ellroll_stop(0)


def _run_text(text, threads, path, results):
    """The library's run of a namelist text, its results as results(lib, handle) reads them."""
    # (the bounds of `ellroll run --threads`: 1 to the largest C int)
    if threads is not None and (isinstance(threads, (bool, np.bool_)) or not isinstance(threads, (int, np.integer))
                                or not 1 <= threads <= 2**31 - 1):
        raise InputError(f"threads = {threads!r}: give a count from 1 to {2**31 - 1}, or None", _INPUT)
    if path is not None and not isinstance(path, (str, os.PathLike)):
        raise InputError(f"path = {path!r} ({type(path).__name__}): give a file name (str or os.PathLike), "
                         "or None", _INPUT)
    # a path as the file system names it (os.fsencode keeps the bytes of a
    # name os.fsdecode read); the text must be Unicode the library can read
    label = os.fsencode(path) if path is not None else b"<input>"
    try:
        encoded = text.encode()
    except UnicodeEncodeError as error:
        line = text.count("\n", 0, error.start) + 1
        raise InputError(f"{os.fsdecode(label)}: line {line}: the text holds {text[error.start]!r}, a lone surrogate "
                         "(a byte that was not UTF-8), not a character", _INPUT) from None
    lib = _library or _lib()
    handle = _interruptible_run(lib, encoded, len(encoded), label, len(label), int(threads or 0))
    if not handle:
        raise Error("libellroll: out of memory")
    try:
        code = lib.ellroll_error_code(handle)
        if code != 0:
            message = _text(lib.ellroll_error_message, handle)
            raise (InputError if code == _INPUT else Error)(message, code)
        return results(lib, handle)
    finally:
        lib.ellroll_free(handle)
