"""Files ellroll-plot writes: never through a symbolic link, never over a file
it did not make (even with --overwrite), and never half: each is written to a
new temporary file beside it and moved into place when complete, so a command
that fails leaves nothing behind."""
import os
import pathlib
import stat
import tempfile

MARK = "ellroll-plot"              # in every figure's metadata, page and table it writes
# matplotlib's metadata keys per format
FIGURE_METADATA = {"png": {"Software": MARK}, "pdf": {"Creator": MARK}, "svg": {"Creator": MARK}}


class OutputExists(Exception):
    """A file the command would write is already there, and may not be replaced."""


def made_by_us(path):
    """Whether a regular file holds ellroll-plot's mark (figures have it in
    their metadata, pages in a comment, tables in their first line)."""
    with open(path, "rb") as handle:
        head = handle.read(1 << 16)
        handle.seek(max(0, os.fstat(handle.fileno()).st_size - (1 << 16)))
        tail = handle.read()
    return MARK.encode() in head or MARK.encode() in tail or head.startswith(b"case,")


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


def write_file(path, overwrite, write):
    """Make path with write(temporary_path), checked first (check_target),
    in a new file beside it, moved into place once complete."""
    path = pathlib.Path(path)
    check_target(path, overwrite)
    handle, temporary = tempfile.mkstemp(prefix=f".{path.name}.", dir=path.parent)
    os.close(handle)
    try:
        os.chmod(temporary, 0o666 & ~_umask())        # as a file opened the usual way would be
        write(temporary)
        check_target(path, overwrite)            # (nothing came there meanwhile)
        os.replace(temporary, path)
    except BaseException:
        pathlib.Path(temporary).unlink(missing_ok=True)
        raise
    return path


def _umask():
    mask = os.umask(0o022)
    os.umask(mask)
    return mask


def write_text(path, overwrite, text):
    return write_file(path, overwrite, lambda name: pathlib.Path(name).write_text(text))


def save_figure(fig, path, overwrite, fmt):
    return write_file(path, overwrite, lambda name: fig.savefig(name, dpi=150, format=fmt,
                                                                metadata=FIGURE_METADATA.get(fmt)))
