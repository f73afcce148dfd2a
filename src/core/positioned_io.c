/* Writes and reads at a given byte offset of a file (POSIX pwrite, pread),
 * for data whose place in the file is fixed in advance: threads write their
 * own regions at the same time, with no lock and no shared file position.
 * Errors come back as errno values (0: success); ellroll_error_text turns
 * them into words. */
#define _GNU_SOURCE        /* pwritev (BSD and glibc, not POSIX); fallocate (Linux) */
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/uio.h>
#include <unistd.h>

/* A descriptor of an existing file, open for writing and reading
 * (writing != 0) or for reading only (>= 0), or -errno. */
int ellroll_open_descriptor(const char *path, int writing)
{
    int fd;
    do {
        fd = open(path, (writing ? O_RDWR : O_RDONLY) | O_NOFOLLOW | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    return fd < 0 ? -errno : fd;
}

/* The `count` pieces (`bytes[k]` bytes at `pieces[k]`) one after the other
 * from `offset`, in one call (pwritev) instead of one call each: where a
 * piece ends mid-page the kernel handles that page once, not twice, and it
 * takes the file's lock once (8 cases' trajectories: 0.09-0.12 s instead of
 * 0.15 s per 10,000 cases). pwritev may write less than asked (a signal, a
 * nearly full disk), so it is called until all is written. */
int ellroll_write_pieces_at(int fd, void *const *pieces, const int64_t *bytes, int count, int64_t offset)
{
    enum { batch = 64 };
    struct iovec vector[batch];
    int first = 0;
    size_t done_in_first = 0;      /* bytes of pieces[first] already written */
    while (first < count) {
        int n = 0;
        for (int k = first; k < count && n < batch; ++k, ++n) {
            size_t skip = k == first ? done_in_first : 0;
            vector[n].iov_base = (char *)pieces[k] + skip;
            vector[n].iov_len = (size_t)bytes[k] - skip;
        }
        ssize_t written = pwritev(fd, vector, n, (off_t)offset);
        if (written < 0) {
            if (errno == EINTR)
                continue;
            return errno;
        }
        if (written == 0)
            return ENOSPC;
        offset += written;
        /* step over what was written: whole pieces, then part of one */
        while (first < count && (size_t)written >= (size_t)bytes[first] - done_in_first) {
            written -= (ssize_t)((size_t)bytes[first] - done_in_first);
            done_in_first = 0;
            ++first;
        }
        done_in_first += (size_t)written;
    }
    return 0;
}

/* `bytes` bytes from `offset` into `buffer`: 0, an errno value, or -1 where
 * the file ends first. */
int ellroll_read_at(int fd, void *buffer, int64_t bytes, int64_t offset)
{
    char *next = buffer;
    while (bytes > 0) {
        ssize_t got = pread(fd, next, (size_t)bytes, (off_t)offset);
        if (got < 0) {
            if (errno == EINTR)
                continue;
            return errno;
        }
        if (got == 0)
            return -1;
        next += got;
        offset += got;
        bytes -= got;
    }
    return 0;
}

/* Give the file system back the blocks of bytes `from` .. `to` - 1 that
 * are no longer needed (they read as zeros after), to the last whole block
 * before `to` (or the file's end): a block shared with bytes still needed
 * stays, and a file with another name (a hard link) keeps every byte. The
 * file keeps its size. Returns where the freed bytes end (`from` when no
 * whole block lies in between), or -errno: EOPNOTSUPP where the file system
 * cannot. */
int64_t ellroll_release_range(int fd, int64_t from, int64_t to)
{
#ifdef FALLOC_FL_PUNCH_HOLE
    struct stat info;
    if (fstat(fd, &info) != 0)
        return -errno;
    if (info.st_nlink > 1)          /* another name holds it (a backup made with ln): its bytes stay */
        return from;
    int64_t block = info.st_blksize > 0 ? (int64_t)info.st_blksize : 4096;
    if (to > (int64_t)info.st_size)
        to = ((int64_t)info.st_size + block - 1) / block * block;
    int64_t end = to / block * block;
    if (end <= from)
        return from;
    int code;
    do {
        code = fallocate(fd, FALLOC_FL_PUNCH_HOLE | FALLOC_FL_KEEP_SIZE, (off_t)from, (off_t)(end - from));
    } while (code != 0 && errno == EINTR);
    return code == 0 ? end : -errno;
#else
    (void)fd; (void)from; (void)to;
    return -EOPNOTSUPP;
#endif
}

/* 0, or the errno of a failed close (a delayed write error, say). */
int ellroll_close_descriptor(int fd)
{
    return close(fd) == 0 ? 0 : errno;
}

/* The system's words for errno value `code`, null-terminated in `text`
 * (strerror_r: threads may ask at the same time). */
void ellroll_error_text(int code, char *text, size_t size)
{
    char work[256];
    snprintf(text, size, "%s", strerror_r(code, work, sizeof work));
}
