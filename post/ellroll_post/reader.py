"""Lazy access to an ellroll file: nothing is read until asked for, so a
file of 10^5 cases costs only what is plotted."""
import builtins
import fcntl
import functools
import os
import re
import shlex
import select
import signal
import stat
import struct
import traceback

import h5py
import numpy as np


class NotAnEllrollFile(Exception):
    """The file is missing, unreadable (a damaged HDF5 file), an unfinished
    run's work file, not written by ellroll, or lacks what is asked (a case
    it does not hold included). Its text is one line naming the file."""


# the work files of an output OUT.h5 (docs/usage.md): OUT.h5.partial, and a resume's OUT.h5.partial.new
WORK_SUFFIXES = (".partial.new", ".partial")
# the journal of a run's finished cases, OUT.h5.journal, and how it begins
JOURNAL_SUFFIX, JOURNAL_MAGIC = ".journal", b"ELLROLL"


def from_h5py(exc):
    """Whether an exception was raised inside h5py (a read of the file
    failed), not by a caller's mistake."""
    frames = traceback.extract_tb(exc.__traceback__)
    return bool(frames) and ("h5py" in frames[-1].filename.replace("\\", "/").split("/")
                             or frames[-1].filename.startswith("h5py/"))


def _reason(exc):
    text = exc.args[0] if isinstance(exc, KeyError) and exc.args else exc     # (KeyError's str is a repr)
    return " ".join(str(text).split()) or type(exc).__name__


def output_of(path):
    """OUT.h5 of a work file OUT.h5.partial (or .partial.new); None for another name."""
    for suffix in WORK_SUFFIXES:
        if path.endswith(suffix) and len(path) > len(suffix):
            return path[:-len(suffix)]
    return None


# struct flock as Linux lays it out: l_type, l_whence, l_start, l_len, l_pid (padded to 8 bytes)
_FLOCK = "@hhqqi0q"


def lock_holder(path):
    """The note of the process that holds the lock of the output whose
    file is at path (OUT.h5.lock, an fcntl lock: it holds whatever
    HDF5_USE_FILE_LOCKING says) on one line, 'host h, pid p, started t:
    command'; None where no process holds it. Nothing is taken (F_GETLK),
    so a resume starting meanwhile is not refused."""
    lock = (output_of(path) or path) + ".lock"
    try:
        fd = os.open(lock, os.O_RDONLY | os.O_NOFOLLOW | os.O_NONBLOCK | os.O_CLOEXEC)
    except (OSError, ValueError):
        return None
    try:
        if not stat.S_ISREG(os.fstat(fd).st_mode):
            return None
        query = struct.pack(_FLOCK, fcntl.F_WRLCK, os.SEEK_SET, 0, 0, 0)
        if struct.unpack(_FLOCK, fcntl.fcntl(fd, fcntl.F_GETLK, query))[0] == fcntl.F_UNLCK:
            return None
        note = os.pread(fd, 4096, 0).decode(errors="replace").splitlines()
    except OSError:
        return None
    finally:
        os.close(fd)
    return note[1] if len(note) >= 2 and note[1].strip() else "starting"


def _resume_advice(path):
    """How to finish the run whose work file (or output) is at path: the
    command its lock (OUT.h5.lock) names, with --resume."""
    output = output_of(path) or path
    command = None
    try:
        if not_regular(output + ".lock"):
            raise OSError("not a regular file")
        with builtins.open(output + ".lock", errors="replace") as handle:    # 'ellroll lock', then '...: COMMAND'
            note = handle.read(4096).splitlines()
        if len(note) >= 2 and note[0] == "ellroll lock" and ": ellroll " in note[1]:
            command = note[1][note[1].index(": ellroll ") + 2:].strip()
    except OSError:
        pass
    if command:
        try:
            words = shlex.split(command)
        except ValueError:          # (not a shell's words: named as it stands)
            words = None
        if words and len(words) > 1 and words[1] == "merge":
            # (merge takes no --resume: run again, it starts afresh from the shards)
            return f"finish it by running '{command}' again (the command {output}.lock names, from its folder), " \
                   f"then read {output}"
        if words and "--overwrite" in words:
            # ellroll refuses --resume with --overwrite: a resume continues the run that --overwrite began
            command = shlex.join(w for w in words if w != "--overwrite")
        resume = command if " --resume" in f" {command} " else command + " --resume"
        return f"finish it with '{resume}' (the command {output}.lock names, from its folder), then read {output}"
    return f"finish it with 'ellroll run INPUT -o {output} --resume' (the run's input and options), then read {output}"


# what a file that is not a regular one is, by its stat.S_IS* test (as `ellroll` names them)
_NOT_REGULAR = (("S_ISDIR", "a folder"), ("S_ISFIFO", "a FIFO (named pipe)"), ("S_ISCHR", "a character device"),
                ("S_ISBLK", "a block device"), ("S_ISSOCK", "a socket"))


def not_regular(path):
    """What path is where it is there and not a regular file (its link
    followed), in words; None for a regular or a missing file. A FIFO is
    never opened: an open waits for a writer, as long as there is none."""
    try:
        mode = os.stat(path).st_mode
    except (OSError, ValueError):
        return None
    if stat.S_ISREG(mode):
        return None
    return next((words for test, words in _NOT_REGULAR if getattr(stat, test)(mode)), "not a regular file")


def _is_journal(path):
    """Whether path begins as ellroll's journal of a run does (OUT.h5.journal)."""
    if not_regular(path):
        return False
    try:
        with builtins.open(path, "rb") as handle:
            return handle.read(len(JOURNAL_MAGIC)) == JOURNAL_MAGIC
    except OSError:
        return False


# how HDF5 names a system call's failure in its error stack
_SYSTEM_FAILURE = re.compile(r"errno = \d+, error message = '([^']*)'")


def read_failure(exc):
    """The system's reason where a read of the file failed in a system call
    (EIO of a failing disk: the file is not judged by it), else None."""
    found = _SYSTEM_FAILURE.search(_reason(exc))
    return found.group(1) if found else None


def _open_failure(path, exc):
    """One line for a file h5py cannot open."""
    text = _reason(exc)
    if isinstance(exc, FileNotFoundError) or "No such file" in text:
        if not os.path.lexists(path + ".partial"):
            return f"{path}: no such file"
        holder = lock_holder(path)            # (its run's work file is there: as `ellroll summary` says it)
        if holder:
            return (f"{path}: not there yet: a running ellroll writes it ({holder}, holding {path}.lock) into "
                    f"{path}.partial; read it when that run ends")
        return f"{path}: not there: {path}.partial is its unfinished run's work file; {_resume_advice(path)}"
    if path.endswith(JOURNAL_SUFFIX) and len(path) > len(JOURNAL_SUFFIX) and _is_journal(path):
        output = path[:-len(JOURNAL_SUFFIX)]
        holder = lock_holder(output)
        if holder:
            return (f"{path}: ellroll's journal of a running ellroll ({holder}, holding {output}.lock: the cases "
                    f"it finished), not an output file; read {output} when that run ends")
        return (f"{path}: ellroll's journal of an unfinished run (the cases it finished, for --resume), not an "
                f"output file; {_resume_advice(output)}")
    locked = "temporarily unavailable" in text or "unable to lock file" in text
    if locked or "already open for write" in text or "consistency flags" in text:
        # HDF5's flock: another process holds the file open to write; with its flock off
        # (HDF5_USE_FILE_LOCKING=FALSE) its writer's mark: the output's own lock names the run (as ellroll summary)
        holder = lock_holder(path)
        if holder:
            return (f"{path}: a running ellroll writes it ({holder}, holding {(output_of(path) or path)}.lock); "
                    f"read it when that run ends")
        if locked:
            return (f"{path}: cannot open the HDF5 file: another process has it open to write; read it when that "
                    f"process ends")
        # HDF5 marks a file open for write in its superblock until it is closed: a run killed
        # (kill -9, a node lost) leaves its work file so; h5clear would not recover its cases
        return (f"{path}: an unfinished run's work file (the run stopped before it closed the file: killed?); "
                f"{_resume_advice(path)}; do not h5clear it")
    if read_failure(exc):
        return f"{path}: cannot read it: {read_failure(exc)}"
    return f"{path}: cannot open as HDF5 ({text})"


def damaged(path, exc):
    """One line for a read of an ellroll file that failed inside h5py: a
    system call's failure (as `ellroll summary` says it), or damage."""
    if read_failure(exc):
        return f"{path}: cannot read it: {read_failure(exc)}"
    work = output_of(path)
    hint = f"; an unfinished run's work file: {_resume_advice(path)}" if work else ""
    return f"{path}: a damaged HDF5 file: cannot read it ({_reason(exc)}){hint}"


def _reads(method):
    """A read that fails inside h5py (a damaged file) raises NotAnEllrollFile
    naming the file, not h5py's own exception."""
    @functools.wraps(method)
    def checked(self, *args, **kwargs):
        self._require_open()
        try:
            return method(self, *args, **kwargs)
        except NotAnEllrollFile:
            raise
        except Exception as exc:
            if not from_h5py(exc):
                raise
            raise NotAnEllrollFile(damaged(self.path, exc)) from None
    return checked


_TEXT = h5py.string_dtype()
# the datasets of /case, /summary and /trajectory that ellroll writes as text (every other holds numbers)
TEXT_DATASETS = ("record", "method", "excitation_kind")
_TEXT_IN_MEMORY = h5py.h5t.py_create(_TEXT)


def _read_attribute(attribute):
    """An attribute's value read through h5py's low-level calls (a variable-
    length text as Python objects, through h5py's own memory type)."""
    file_type, space = attribute.get_type(), attribute.get_space()
    if space.get_simple_extent_type() == h5py.h5s.NULL:
        return None
    if isinstance(file_type, h5py.h5t.TypeStringID) and file_type.is_variable_str():
        value = np.empty(space.shape, dtype=_TEXT)
        attribute.read(value, mtype=_TEXT_IN_MEMORY)
    else:
        value = np.empty(space.shape, dtype=file_type.dtype)
        attribute.read(value)
    return value


def tables_seconds(path):
    """The seconds HDF5 may take to read a file's tables and texts: the file
    read at 50 MB/s, and 3 s more (they take 50 ms for an ellroll file of
    a few cases), where a damaged global heap (the texts' store) can make it
    loop for ever."""
    try:
        size = os.stat(path).st_size
    except OSError:                                 # (the open then says why)
        size = 0
    return 3.0 + size / 50e6


def _tables_read_in_time(path, seconds):
    """Whether a child process reads every object, attribute and text
    dataset of the file within `seconds`. HDF5 loops for ever on some
    damaged global heaps (a flipped bit in a heap object's index), inside one
    call that no thread can stop: the child is killed instead. A child that
    fails (an exception) counts as in time: the file's own reads then say why."""
    done_reading, child_end = os.pipe()           # (closed at the child's exit: readable then)
    pid = os.fork()
    if pid == 0:                                    # (the child: only ever _exit)
        os.close(done_reading)
        code = 1
        try:
            with h5py.File(path, "r") as f:
                file_id = f.id

                def visit(name):
                    item = h5py.h5o.open(file_id, name)
                    for index in range(h5py.h5a.get_num_attrs(item)):
                        _read_attribute(h5py.h5a.open(item, index=index))
                    if h5py.h5i.get_type(item) == h5py.h5i.DATASET and f[name].dtype.kind == "O":
                        f[name][()]
                h5py.h5o.visit(file_id, visit)
            code = 0
        finally:
            os._exit(code)
    os.close(child_end)
    try:
        finished = bool(select.select([done_reading], [], [], seconds)[0])
    finally:
        os.close(done_reading)
    if not finished:
        os.kill(pid, signal.SIGKILL)
    try:
        os.waitpid(pid, 0)
    except ChildProcessError:                       # (SIGCHLD ignored: the system reaped it)
        pass
    return finished


class EllrollFile:
    def __init__(self, path):
        self.path = str(path)
        what = not_regular(self.path)
        if what == "a folder":
            raise NotAnEllrollFile(f"{self.path}: a folder, not an ellroll file")
        if what:
            raise NotAnEllrollFile(f"{self.path}: {what}, not a regular file (an ellroll file is one)")
        seconds = tables_seconds(self.path)
        if not _tables_read_in_time(self.path, seconds):
            raise NotAnEllrollFile(f"{self.path}: a damaged HDF5 file: HDF5 does not finish reading its tables "
                                   f"(stopped after {seconds:.3g} s)")
        try:
            self._h5 = h5py.File(self.path, "r")
        except (OSError, ValueError) as exc:
            raise NotAnEllrollFile(_open_failure(self.path, exc)) from None
        self._contents = self._contents_now()
        try:
            try:
                program = self._h5.attrs["program"]
            except KeyError as exc:         # (no such attribute, or its read failed: damaged() tells which)
                if read_failure(exc):
                    raise
                program = None
            if program != "ellroll":
                raise NotAnEllrollFile(f"{self.path}: not an ellroll file (no program='ellroll' attribute)")
            self._check_tables()
            self.cases                                  # (read once: every case argument is looked up in it)
        except Exception as exc:
            self._h5.close()
            if isinstance(exc, NotAnEllrollFile):
                raise
            raise NotAnEllrollFile(damaged(self.path, exc)) from None

    def _check_tables(self):
        """Open every object of the file and read its attributes: a file whose
        HDF5 tables are damaged (a flipped bit) fails here, at open, with one
        message, not later in a figure. Reads no dataset's data. (h5py's
        low-level calls: its high-level objects cost three times as much.)"""
        file_id = self._h5.id

        def visit(name):
            item = h5py.h5o.open(file_id, name)
            for index in range(h5py.h5a.get_num_attrs(item)):
                _read_attribute(h5py.h5a.open(item, index=index))
            if h5py.h5i.get_type(item) == h5py.h5i.DATASET:
                item.get_type(), item.get_space(), item.get_create_plist()
        h5py.h5o.visit(file_id, visit)
        for group in ("case", "summary", "trajectory"):
            if not isinstance(self._h5.get(group), h5py.Group):
                raise NotAnEllrollFile(f"{self.path}: not an ellroll file (no group /{group})")
        self._check_shapes()

    def _check_shapes(self):
        """Every dataset of /case, /summary and /trajectory holds a row per
        case, each trajectory a sample per time, and /summary/status names
        its values: else one line (a file another program changed), not a
        figure's numpy error later. Reads shapes and attributes only."""
        def changed(what):
            return NotAnEllrollFile(f"{self.path}: not laid out as ellroll writes its files ({what}; changed by "
                                    "another program?)")
        status = self._h5.get("summary/status")
        if not isinstance(status, h5py.Dataset) or status.ndim != 1:
            raise changed("no /summary/status of one value per case")
        for attribute in ("flag_values", "flag_meanings"):
            if attribute not in status.attrs:
                raise changed(f"/summary/status has no attribute {attribute}")
        if len(np.ravel(status.attrs["flag_values"])) != len(str(status.attrs["flag_meanings"]).split()):
            raise changed("/summary/status: flag_values and flag_meanings differ in length")
        rows = status.shape[0]
        time = self._h5.get("time")
        samples = time.shape[0] if isinstance(time, h5py.Dataset) and time.ndim == 1 else None
        for group in ("case", "summary", "trajectory"):
            for name, item in self._h5[group].items():
                if not isinstance(item, h5py.Dataset) or (group, name) == ("trajectory", "time"):
                    continue
                holds = "numbers" if item.dtype.kind in "fiu" else "text"
                if holds != ("text" if name in TEXT_DATASETS else "numbers"):
                    raise changed(f"/{group}/{name} holds {holds}, where ellroll writes "
                                  f"{'text' if holds == 'numbers' else 'numbers'}")
                if item.ndim == 0 or item.shape[0] != rows:
                    raise changed(f"/{group}/{name} holds {item.shape[0] if item.ndim else 'no'} rows, "
                                  f"/summary/status {rows}")
                if group == "trajectory" and item.ndim >= 2 and samples is not None and item.shape[1] != samples:
                    raise changed(f"/{group}/{name} holds {item.shape[1]} samples per case, /time {samples}")

    def close(self):
        self._h5.close()

    def _contents_now(self):
        """The open file's size and last modification (fstat of HDF5's own
        descriptor): what tells that it was written to since it was opened."""
        info = os.fstat(self._h5.id.get_vfd_handle())
        return info.st_size, info.st_mtime_ns

    def _require_open(self):
        """NotAnEllrollFile where the file was closed (close(), or a with
        block ended), or written to since it was opened (another output
        copied over it in place, a truncation): HDF5 would read its cached
        tables against the new bytes, zeros and NaN without an error."""
        if not self._h5.id.valid:
            raise NotAnEllrollFile(f"{self.path}: closed; ellroll_post.open it again to read it")
        if self._contents_now() != self._contents:
            raise NotAnEllrollFile(f"{self.path}: written to since it was opened (copied over, truncated or "
                                   "changed in place); ellroll_post.open it again to read it")

    def __enter__(self):
        return self

    def __exit__(self, *exc):
        self.close()

    # ---------------------------------------------------------- layout
    @property
    def attrs(self):
        self._require_open()
        return dict(self._h5.attrs)

    @property
    def n_cases(self):
        return self._dataset("summary/status").shape[0]

    @property
    @_reads
    def time(self):
        return self._dataset("time")[:]

    @property
    @_reads
    def fields(self):
        return sorted(set(self._h5["trajectory"]) - {"case", "time"} - set(self._coordinates("trajectory")))

    @property
    def summary_names(self):
        return sorted(self.summary_figures)

    @property
    @_reads
    def summary_figures(self):
        """The figures of /summary in the file's order (its members are kept
        in the order they were made, the order of ellroll's summary table),
        without the case index, the status, the checksum and the varied
        inputs."""
        return [n for n in self._h5["summary"]
                if n not in {"case", "status", "checksum", *self._coordinates("summary")}]

    def _coordinates(self, group):
        """The varied inputs a group holds as coordinates of its cases (CF's
        `coordinates` attribute, the same on each of its variables); looked
        up once a group (a figure asks often, and the lookup visits every
        member)."""
        known = self.__dict__.setdefault("_coordinates_of", {})
        if group not in known:
            known[group] = next((item.attrs["coordinates"].split() for item in self._h5[group].values()
                                 if "coordinates" in item.attrs), [])
        return list(known[group])

    def _dataset(self, name):
        self._require_open()
        if name not in self._h5:
            raise NotAnEllrollFile(f"{self.path}: no dataset /{name} in this file")
        return self._h5[name]

    @property
    def cases(self):
        """The global case index of each case (row) the file holds
        (/case/index): 0..n-1 for a whole campaign, I, I+N, ... for shard
        I/N. Every `case` argument is such an index."""
        if not hasattr(self, "_cases"):
            rows = self._dataset("summary/status").shape[0]
            index = self._h5.get("case/index")
            cases = np.asarray(index[:], dtype=np.int64) if index is not None else np.arange(rows)
            if cases.shape != (rows,):
                raise NotAnEllrollFile(damaged(self.path, f"/case/index holds {cases.shape} values, "
                                                          f"/summary/status {rows}"))
            pending = self._pending_rows()
            if pending.any():
                # an unfinished file (OUT.h5.partial) writes a case's /case/index with its results; its
                # pending rows' indices are those of the case dimension, written when the file was made
                scale = self._h5.get("case/case")
                if scale is None or scale.shape != (rows,):
                    raise NotAnEllrollFile(damaged(self.path, f"no /case/case of {rows} values for its "
                                                              "pending cases"))
                cases[pending] = np.asarray(scale[:], dtype=np.int64)[pending]
            self._cases = cases
            self._rows = {int(c): row for row, c in enumerate(cases)}
        return self._cases

    def _pending_rows(self):
        """Whether each row is a case not run yet (status pending: an unfinished run's work file)."""
        status = self._dataset("summary/status")
        return np.asarray(self._status_meanings(status[:])) == "pending"

    def case_index(self, case=None):
        """The global index of a case; None: the file's first case."""
        return int(self.cases[self.row(case)])

    def row(self, case=None):
        """The row that holds a case, by its global index (None: the first
        row); NotAnEllrollFile naming the cases held where the file holds no
        such case."""
        self.cases
        if case is None:
            if not self._rows:
                raise NotAnEllrollFile(f"{self.path}: holds no case")
            return 0
        if isinstance(case, (bool, np.bool_)) or not isinstance(case, (int, np.integer)):
            raise NotAnEllrollFile(f"{self.path}: a case is an integer index, not {case!r}")
        row = self._rows.get(int(case))
        if row is None:
            held = _held(self._cases)
            if np.array_equal(self._cases, np.arange(len(self._cases))) and len(self._cases):
                raise NotAnEllrollFile(f"{self.path}: case {case} out of range (the file has cases "
                                       f"0..{len(self._cases) - 1})")
            shard = f": shard {self.attrs.get('shard')}" if self._h5.attrs.get("shard") else ""
            raise NotAnEllrollFile(f"{self.path}: case {case} is not in this file (it holds cases {held}{shard})")
        return row

    def check_case(self, case):
        """The row of a case (its global index), or NotAnEllrollFile."""
        return self.row(case)

    @_reads
    def units(self, name):
        return self._dataset(name).attrs.get("units", "")

    # ------------------------------------------------------------ data
    @_reads
    def trajectory(self, field, case=None):
        """One case's samples of a trajectory field: (nt,) or (nt, 3); case:
        its global index (None: the file's first case)."""
        row = self.row(case)
        dataset = self._dataset(f"trajectory/{field}")
        if dataset.dtype.kind == "f" and self.status_name(case) == "pending":
            # a pending case's samples are not written yet: HDF5 reads them as 0, not the fill value
            return np.full(dataset.shape[1:], np.nan)
        return dataset[row]

    @property
    @_reads
    def inputs(self):
        """{input: (/case dataset, component or None)}: every input the file
        holds, named as a sweep names it (omega_z), in the file's order. Each
        /case dataset of inputs names them in its `input_names` attribute,
        one per component; a file written before that attribute gives its
        real /case datasets of one value per case under their own names."""
        if not hasattr(self, "_inputs"):
            group = self._h5["case"]
            named = {d: v.attrs["input_names"].split() for d, v in group.items() if "input_names" in v.attrs}
            if not named:
                named = {d: [d] for d, v in group.items() if v.dtype.kind == "f" and v.ndim == 1}
            self._inputs = {name: (dataset, component if len(names) > 1 else None)
                            for dataset, names in named.items() for component, name in enumerate(names)}
        return self._inputs

    def _input(self, name):
        """(/case dataset, component) of an input, by its name (omega_z) or
        its /case dataset's (omega)."""
        return self.inputs.get(name, (name, None))

    @_reads
    def case_input(self, name, case=None):
        """A resolved input of one case, by its name (omega_z) or /case name (omega)."""
        row = self.row(case)
        dataset, component = self._input(name)
        value = self._dataset(f"case/{dataset}")[row]
        if component is not None:
            value = value[component]
        return value.decode() if isinstance(value, bytes) else value

    def input_units(self, name):
        """The units of an input, by its name (omega_z) or /case name."""
        return self.units("case/" + self._input(name)[0])

    @_reads
    def input_column(self, name):
        """An input over all cases (for sweeps), from /case; a varied one's
        rows /case does not hold yet (a stopped run's pending cases) from
        its coordinate in /summary, written for every case."""
        dataset, component = self._input(name)
        values = self._dataset(f"case/{dataset}")
        values = values[:, component] if component is not None else values[:]
        coordinate = f"summary/{name}"
        if name not in self._coordinates("summary") or coordinate not in self._h5:
            return values
        if values.dtype.kind == "f" and self._h5[coordinate].dtype.kind == "f" and np.isnan(values).any():
            unwritten = np.isnan(values)
            values[unwritten] = self._h5[coordinate][:][unwritten]
        elif values.dtype.kind == "O" and self._h5[coordinate].dtype.kind == "O":     # (a suite's record names)
            unwritten = np.array([not bytes(v).strip() for v in values], dtype=bool)
            if unwritten.any():
                values[unwritten] = self._h5[coordinate][:][unwritten]
        return values

    @_reads
    def swept_inputs(self):
        """The inputs that differ between cases, by name."""
        if self.n_cases < 2:
            return []
        # a file still being written (OUT.h5.partial) has no inputs yet for its pending cases
        written = np.array(self.status_names()) != "pending"
        if written.sum() < 2:
            return []
        swept = []
        for name in self.inputs:
            column = self.input_column(name)[written]
            # NaN (an input left unset) is the same as NaN: unset in every case is not varied
            same = (column == column[0]) | (np.isnan(column) & np.isnan(column[0]))
            if not np.all(same):
                swept.append(name)
        if "weight" in swept and "mass" in swept:
            swept.remove("mass" if np.unique(self.input_column("g")).size == 1 else "weight")
        return swept

    def varied_inputs(self):
        """The inputs that vary between the cases, as the file names its
        coordinates (sweeps, samples, then a suite's record); for a file
        without them, the inputs that differ (swept_inputs) and the record."""
        return self._coordinates("summary") or self.swept_inputs() + (["record"] if any(self.record_names()) else [])

    @_reads
    def record_names(self):
        """Each case's record of a suite (&record name), or blanks."""
        if "case/record" not in self._h5:
            return [""] * self.n_cases
        return [n.decode().strip() if isinstance(n, bytes) else str(n).strip() for n in self.input_column("record")]

    @_reads
    def summary(self, name, case=None):
        """A /summary figure over all cases, or of one case (its global index)."""
        ds = self._dataset(f"summary/{name}")
        if case is None:
            return ds[:]
        return ds[self.row(case)]

    @_reads
    def switches(self, case=None):
        """One case's switches of regime, in order: (times in s, kinds by
        name, 'to_sliding' or 'to_rolling'), from /switches (a campaign
        with &ball slip = 'slide'); empty for a case that never slid."""
        row = self.row(case)
        if "switches" not in self._h5:
            raise NotAnEllrollFile(f"{self.path}: no /switches in this file (no case may slide: "
                                   "&ball slip = 'slide' stores them)")
        group = self._h5["switches"]
        first, count = int(group["first"][row]), int(group["count"][row])
        if count < 0:
            raise ValueError(f"{self.path}: case {self.case_index(case)} was never run ({self.status_name(case)})")
        kinds = group["switch_kind"]
        values = np.asarray(kinds.attrs["flag_values"])
        names = np.array(kinds.attrs["flag_meanings"].split())
        codes = kinds[first:first + count]
        return group["switch_time"][first:first + count], names[np.searchsorted(values, codes)]

    @_reads
    def status_names(self):
        """Each case's status by name (the flag_meanings of its flag_values)."""
        return self._status_meanings(self._dataset("summary/status")[:]).tolist()

    @_reads
    def status_name(self, case=None):
        row = self.row(case)
        return str(self._status_meanings(self._dataset("summary/status")[row:row + 1])[0])

    def _status_meanings(self, codes):
        """The flag_meanings of codes; "unknown" for a code outside flag_values (a file
        from a later version, or altered), as `ellroll summary` names and counts it."""
        attrs = self._dataset("summary/status").attrs
        values = np.asarray(attrs["flag_values"])
        order = np.argsort(values)
        names = np.array(attrs["flag_meanings"].split())[order]
        codes = np.asarray(codes)
        at = np.minimum(np.searchsorted(values[order], codes), len(values) - 1)
        return np.where(values[order][at] == codes, names[at], "unknown")


def _held(cases):
    """The case indices held, short: 0..9, 0, 4, 8, or 1, 5, 9, ..., 97."""
    cases = [int(c) for c in cases]
    if not cases:
        return "none"
    if len(cases) > 1 and cases == list(range(cases[0], cases[-1] + 1)):
        return f"{cases[0]}..{cases[-1]}"
    if len(cases) <= 6:
        return ", ".join(map(str, cases))
    return ", ".join(map(str, cases[:3])) + ", ..., " + str(cases[-1])


def open(path):  # noqa: A001 - mirrors h5py.File / xarray.open_dataset naming
    """Open an ellroll file for reading."""
    return EllrollFile(path)
