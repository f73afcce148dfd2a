/* Questions to the file system that Fortran's inquire cannot ask. */
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <sys/stat.h>
#include <unistd.h>

/* 0 when files can be created in folder `path` (it exists, is a folder, and
 * this process may write and search it), else the errno value that says why. */
int ellroll_folder_write_error(const char *path)
{
    return access(path, W_OK | X_OK) == 0 ? 0 : errno;
}

static char file_type(mode_t mode)
{
    if (S_ISREG(mode)) return 'r';
    if (S_ISDIR(mode)) return 'd';
    if (S_ISFIFO(mode)) return 'p';
    if (S_ISCHR(mode)) return 'c';
    if (S_ISBLK(mode)) return 'b';
    if (S_ISSOCK(mode)) return 's';
    return '?';
}

/* Open `path` for reading when it is a regular file (links followed): 0,
 * with its descriptor in *fd and its size in *bytes; an errno value; or -1
 * when it is something else, which *type names ('d' folder, 'p' FIFO, 'c'
 * character device, 'b' block device, 's' socket, '?'). The type is asked
 * before the file is opened, because opening a FIFO waits for a writer and
 * a device may never end; it is asked again of the open descriptor, in
 * case the path changed in between (O_NONBLOCK: that open cannot wait). */
int ellroll_open_regular_file(const char *path, int *fd, int64_t *bytes, char *type)
{
    struct stat info;
    *fd = -1;
    *bytes = 0;
    *type = '?';
    if (stat(path, &info) != 0)
        return errno;
    *type = file_type(info.st_mode);
    if (*type != 'r')
        return -1;
    int opened;
    do {
        opened = open(path, O_RDONLY | O_NONBLOCK | O_NOCTTY | O_CLOEXEC);
    } while (opened < 0 && errno == EINTR);
    if (opened < 0)
        return errno;
    if (fstat(opened, &info) != 0) {
        int code = errno;
        close(opened);
        return code;
    }
    *type = file_type(info.st_mode);
    if (*type != 'r') {
        close(opened);
        return -1;
    }
    *fd = opened;
    *bytes = (int64_t)info.st_size;
    return 0;
}

/* The first `bytes` bytes of the file open as fd, into `text`: 0, an errno
 * value, or -1 when the file ends first (it shrank since it was opened). */
int ellroll_read_text(int fd, char *text, int64_t bytes)
{
    int64_t done = 0;
    while (done < bytes) {
        ssize_t got = pread(fd, text + done, (size_t)(bytes - done), (off_t)done);
        if (got < 0) {
            if (errno == EINTR)
                continue;
            return errno;
        }
        if (got == 0)
            return -1;
        done += got;
    }
    return 0;
}
