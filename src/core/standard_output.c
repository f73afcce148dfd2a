/* The program's own standard output, written with write(2) so that a failed
 * write is seen: gfortran's runtime drops write errors on its preconnected
 * units (write and flush to a full disk or /dev/full, or an I/O error, all
 * report success), and a lost summary would end with exit 0.
 * Errors come back as errno values (0: success). */
#include <errno.h>
#include <stddef.h>
#include <unistd.h>

int ellroll_write_stdout(const char *text, size_t bytes)
{
    while (bytes > 0) {
        ssize_t done = write(STDOUT_FILENO, text, bytes);
        if (done < 0) {
            if (errno == EINTR) continue;
            return errno;
        }
        text += done;
        bytes -= (size_t)done;
    }
    return 0;
}

/* Closing a second descriptor of standard output reports what the system
 * could only tell at a close (NFS's deferred write errors) and leaves
 * descriptor 1 open, so no file opened later can take its number. */
int ellroll_close_stdout(void)
{
    int copy = dup(STDOUT_FILENO);
    if (copy < 0) return errno == EBADF ? 0 : errno;   /* no standard output: nothing written */
    if (close(copy) != 0 && errno != EINTR) return errno;
    return 0;
}
