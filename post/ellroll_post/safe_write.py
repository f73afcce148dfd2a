"""Files ellroll-plot writes: never through a symbolic link, never over a file
it did not make (even with --overwrite), and never half: each is written to a
new temporary file beside it and moved into place when complete, so a command
that fails leaves nothing behind."""
import os
import pathlib
import re
import stat
import tempfile

MARK = "ellroll-plot"              # in every figure's metadata and page it writes
# matplotlib's metadata keys per format
FIGURE_METADATA = {"png": {"Software": MARK}, "pdf": {"Creator": MARK}, "svg": {"Creator": MARK}}
# Each kind of file it writes carries its mark in a fixed place: a figure's
# metadata (as matplotlib writes FIGURE_METADATA), a page's generator, a
# table's own first line (the report's summary.csv, `fragility --format csv`)
# or its own ending (`--format table`) or key (`--format json`). A file that
# merely mentions ellroll-plot, or a table that begins with `case,`, is not
# its own.
FIGURE_MARKS = (re.compile(rb"\A\x89PNG\r\n\x1a\n.*?tEXtSoftware\x00ellroll-plot", re.S),
                re.compile(rb"\A%PDF-.*/Creator \(ellroll-plot\)", re.S),
                re.compile(rb"\A<\?xml[^\n]*\n<!DOCTYPE svg .*?<dc:creator>\s*<cc:Agent>\s*"
                           rb"<dc:title>ellroll-plot</dc:title>", re.S),
                re.compile(rb'\A<!DOCTYPE html>\n<html><head><meta charset="utf-8">'
                           rb'<meta name="generator" content="ellroll-plot">'))
TABLE_FIRST_LINES = (re.compile(rb"case,([^,\n]*,)*status,t_final \[s\],n_steps,n_rejected,n_rhs,[^\n]*"),
                     re.compile(rb"([^,\n]*,)*limit_state,im,units,theta,theta_low,theta_high,beta,beta_low,"
                                rb"beta_high,n_points,n_known,n_exceeded,n_undefined,note\r?"))
TABLE_JSON_START = b'{\n "file": '
TABLE_JSON_SIGN = b'\n "interval": "5-95 %",\n'
TABLE_TEXT_END = (b"P(exceed | IM = x) = Phi(ln(x / theta) / beta), fitted by maximum likelihood to the "
                  b"binomial counts; intervals 5-95 % of a parametric bootstrap\n")


class Interrupted(BaseException):
    """SIGTERM or SIGINT asked the command to stop (request_stop), met at a
    stop point: what it was writing goes as on any failure (a BaseException:
    no `except Exception` takes it)."""

    def __init__(self, signum):
        super().__init__(signum)
        self.signum = signum


_stop_requested = []          # the signals that asked to stop (request_stop)


def request_stop(signum, frame):
    """A signal handler: the command stops at its next stop point. (An
    exception raised in the handler itself could land in a weak reference's
    callback, where Python ignores it.)"""
    _stop_requested.append(signum)


def forget_stop_requests():
    """A new command (main() again in one process) starts with none."""
    _stop_requested.clear()


def stop_point():
    """Interrupted where a signal asked to stop: before each file is moved
    into place, and before a report is."""
    if _stop_requested:
        raise Interrupted(_stop_requested[0])


class OutputExists(Exception):
    """A file the command would write is already there, and may not be replaced."""


class CannotWrite(OSError):
    """A file the command would write cannot be written (the system's reason),
    named by its own path."""


def made_by_us(path):
    """Whether a regular file holds ellroll-plot's mark in its place (a
    figure's metadata, a page's generator, a table's first line, ending or
    key: FIGURE_MARKS and the TABLE_ ones)."""
    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
        handle.seek(max(0, os.fstat(handle.fileno()).st_size - (1 << 16)))
        tail = handle.read()
    first_line = head.split(b"\n", 1)[0]
    return (any(mark.match(head) or mark.match(head + tail) for mark in FIGURE_MARKS)
            or any(line.fullmatch(first_line) for line in TABLE_FIRST_LINES)
            or (head.startswith(TABLE_JSON_START) and TABLE_JSON_SIGN in head)
            or tail.endswith(TABLE_TEXT_END))


def check_target(path, overwrite):
    """Refuse (OutputExists) to write path where a link, a folder or a
    device is, where a file is and overwrite is not given, or where a file is
    that ellroll-plot did not make."""
    path = pathlib.Path(path)
    try:
        info = path.lstat()
    except FileNotFoundError:
        return
    if stat.S_ISLNK(info.st_mode):
        raise OutputExists(f"{path} is a symbolic link; ellroll-plot never writes through one")
    if not stat.S_ISREG(info.st_mode):
        raise OutputExists(f"{path} exists and is not a regular file")
    if not overwrite:
        raise OutputExists(f"{path} exists; give --overwrite to replace it")
    if not made_by_us(path):
        raise OutputExists(f"{path} exists and was not made by ellroll-plot; it is never replaced, "
                           "even with --overwrite")


def output_folder(folder, option="--out", make=True, own=False):
    """The folder the outputs go in: an existing one, or one made here whose
    parent exists (only the last level: a mistyped path is not made from
    the root down; make=False: only checked, made by its writer). OutputExists
    where a file (not a folder) is there or the parent is missing, and, for a
    folder that is itself the output (own: a report's), where a symbolic link
    is there: it would write into a folder ellroll-plot did not make."""
    folder = pathlib.Path(folder)
    if own and folder.is_symlink():
        raise OutputExists(f"{option} {folder} is a symbolic link; ellroll-plot never writes a report through one")
    if folder.is_dir():
        return folder
    if folder.exists() or folder.is_symlink():
        raise OutputExists(f"{option} {folder}: not a folder ({option} names the folder the outputs go in)")
    parent = folder.parent
    if not parent.is_dir():
        raise OutputExists(f"{option} {folder}: no folder {parent} to make it in (ellroll-plot makes only the "
                           "last level of a folder)")
    if not make:
        return folder
    try:
        folder.mkdir(exist_ok=True)
    except OSError as exc:
        raise OutputExists(f"{option} {folder}: cannot make the folder ({exc.strerror or exc})") from None
    return folder


def write_file(path, overwrite, write):
    """Make path with write(temporary_path), checked first (check_target),
    in a new file beside it, moved into place once complete."""
    path = pathlib.Path(path)
    stop_point()
    check_target(path, overwrite)
    try:
        handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    except OSError as exc:
        raise CannotWrite(f"{path}: cannot write files in its folder {path.parent} "
                          f"({exc.strerror or exc})") from None
    os.close(handle)
    try:
        os.chmod(temporary, 0o666 & ~_umask())        # as a file opened the usual way would be
        write(temporary)
        sync_to_disk(temporary)                          # (on the disk before its name replaces an old file's)
        stop_point()
        check_target(path, overwrite)            # (nothing came there meanwhile)
        os.replace(temporary, path)
    except BaseException as exc:
        pathlib.Path(temporary).unlink(missing_ok=True)
        if isinstance(exc, OSError) and not isinstance(exc, CannotWrite):
            # (the system's reason, named by the file asked for, not its temporary one)
            raise CannotWrite(f"{path}: cannot write it ({exc.strerror or exc})") from None
        raise
    sync_to_disk(path.parent, path)              # (the new name on the disk too)
    return path


def sync_to_disk(path, made=None):
    """fsync a file or a folder: a crash after the move then finds the new
    file whole, not an empty one in the old one's place. For the folder
    that now holds `made`, a failure says that `made` is there but may not
    last (CannotWrite)."""
    try:
        descriptor = os.open(path, os.O_RDONLY)
        try:
            os.fsync(descriptor)
        finally:
            os.close(descriptor)
    except OSError as exc:
        if made is None:
            raise
        raise CannotWrite(f"{made}: written, but the disk did not confirm its folder {path} "
                          f"({exc.strerror or exc}); it may not last a crash") from None


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(path, overwrite, text):
    return write_file(path, overwrite, lambda name: pathlib.Path(name).write_text(text))


def save_figure(fig, path, overwrite, fmt):
    return write_file(path, overwrite, lambda name: fig.savefig(name, dpi=150, format=fmt,
                                                                metadata=FIGURE_METADATA.get(fmt)))
