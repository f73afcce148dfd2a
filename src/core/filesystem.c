/* Questions to the file system that Fortran's inquire cannot ask, and the
 * ways ellroll makes, opens, removes and locks files so that it never
 * follows a link or replaces a file it did not make: new files are created
 * with O_EXCL | O_NOFOLLOW, existing ones opened with O_NOFOLLOW, and what
 * is at a name is looked at with lstat. Errors come back as errno values. */
#define _GNU_SOURCE
#include <errno.h>
#include <fcntl.h>
#include <stdint.h>
#include <stdio.h>
#include <string.h>
#include <sys/stat.h>
#include <sys/statvfs.h>
#include <sys/syscall.h>
#include <unistd.h>
#include <linux/capability.h>

/* 0 when files can be created in folder `path` (it exists, is a folder, and
 * this process may write and search it), else the errno value that says why. */
int ellroll_folder_write_error(const char *path)
{
    return access(path, W_OK | X_OK) == 0 ? 0 : errno;
}

/* What is at path, the link itself if it is one: 0 nothing, 1 a regular
 * file, 2 a symbolic link, 3 a folder, 4 something else (a FIFO, a device,
 * a socket); -errno where it cannot be told. */
int ellroll_path_kind(const char *path)
{
    struct stat info;
    if (lstat(path, &info) != 0)
        return errno == ENOENT || errno == ENOTDIR ? 0 : -errno;
    if (S_ISREG(info.st_mode))
        return 1;
    if (S_ISLNK(info.st_mode))
        return 2;
    if (S_ISDIR(info.st_mode))
        return 3;
    return 4;
}

/* Bytes of the regular file at path (a link not followed), or -errno. */
long long ellroll_file_size(const char *path)
{
    struct stat info;
    if (lstat(path, &info) != 0)
        return -errno;
    return (long long)info.st_size;
}

/* A new file at path, open for reading and writing; never a file that was
 * there, never through a link (O_EXCL | O_NOFOLLOW): a descriptor or -errno
 * (-EEXIST when anything is at path). */
int ellroll_create_new(const char *path)
{
    int fd;
    do {
        fd = open(path, O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
    } while (fd < 0 && errno == EINTR);
    return fd < 0 ? -errno : fd;
}

/* 1 when a and b are the same file (device and inode, links followed), 0
 * when they are not or either is missing. */
int ellroll_same_file(const char *a, const char *b)
{
    struct stat first, second;
    if (stat(a, &first) != 0 || stat(b, &second) != 0)
        return 0;
    return first.st_dev == second.st_dev && first.st_ino == second.st_ino;
}

/* 1 when descriptor fd is the regular file at path (not a link to it). */
int ellroll_descriptor_is_at(int fd, const char *path)
{
    struct stat open_file, named;
    if (fstat(fd, &open_file) != 0 || lstat(path, &named) != 0)
        return 0;
    return S_ISREG(named.st_mode) && open_file.st_dev == named.st_dev && open_file.st_ino == named.st_ino;
}

/* The identity (device, inode) of the regular file at path, a link not
 * followed: 1, or 0 where no regular file is there. */
int ellroll_file_identity(const char *path, int64_t identity[2])
{
    struct stat named;
    if (lstat(path, &named) != 0 || !S_ISREG(named.st_mode))
        return 0;
    identity[0] = (int64_t)named.st_dev;
    identity[1] = (int64_t)named.st_ino;
    return 1;
}

/* The identity (device, inode) of the file open as fd: 1, or 0. */
int ellroll_descriptor_identity(int fd, int64_t identity[2])
{
    struct stat open_file;
    if (fstat(fd, &open_file) != 0)
        return 0;
    identity[0] = (int64_t)open_file.st_dev;
    identity[1] = (int64_t)open_file.st_ino;
    return 1;
}

/* Remove the file at path (a link itself, never its target): 0 or errno. */
int ellroll_remove_path(const char *path)
{
    return unlink(path) == 0 ? 0 : errno;
}

/* Move old over new atomically (rename): 0 or errno. */
int ellroll_rename_path(const char *old, const char *new_path)
{
    return rename(old, new_path) == 0 ? 0 : errno;
}

/* Move old to new where nothing is at new: 0, EEXIST when anything is
 * there (a file, a link, made at any moment before), or another errno.
 * renameat2 RENAME_NOREPLACE decides in one step; a file system without it
 * gets link (which never replaces a name) and unlink; one without hard
 * links, a look (lstat) and rename, which a file made between the two
 * would lose. */
int ellroll_rename_new(const char *old, const char *new_path)
{
#if defined(SYS_renameat2)
    if (syscall(SYS_renameat2, AT_FDCWD, old, AT_FDCWD, new_path, 1u /* RENAME_NOREPLACE */) == 0)
        return 0;
    if (errno != EINVAL && errno != ENOSYS && errno != EOPNOTSUPP)
        return errno;
#endif
    if (link(old, new_path) == 0)
        return unlink(old) == 0 ? 0 : errno;
    if (errno != EPERM && errno != EOPNOTSUPP && errno != ENOSYS && errno != EMLINK)
        return errno;
    struct stat info;
    if (lstat(new_path, &info) == 0)
        return EEXIST;
    if (errno != ENOENT)
        return errno;
    return rename(old, new_path) == 0 ? 0 : errno;
}

/* Whether the file at `copy` is what a copy of the file open as fd that
 * was cut short leaves (a killed resume's): a regular file of one name, no
 * longer than fd's file, whose bytes are its first ones (all of them up
 * to 64 KiB looked at). */
static int stale_copy(int fd, const char *copy)
{
    struct stat named, open_file;
    if (lstat(copy, &named) != 0 || !S_ISREG(named.st_mode) || named.st_nlink != 1 || fstat(fd, &open_file) != 0 ||
        named.st_size > open_file.st_size)
        return 0;
    int other = open(copy, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
    if (other < 0)
        return 0;
    char mine[4096], theirs[4096];
    int same = 1;
    for (off_t at = 0; same && at < named.st_size && at < 65536; at += (off_t)sizeof mine) {
        size_t want = (size_t)(named.st_size - at < (off_t)sizeof mine ? named.st_size - at : (off_t)sizeof mine);
        same = pread(fd, mine, want, at) == (ssize_t)want && pread(other, theirs, want, at) == (ssize_t)want &&
               memcmp(mine, theirs, want) == 0;
    }
    close(other);
    return same;
}

/* A file of one name in place of the regular file open as fd at path when
 * another name holds it too (a backup made with ln or cp -al), so that
 * writing to it leaves the other name's bytes as they are: its bytes are
 * copied to a new file at `copy` (O_EXCL), synced, and moved over path,
 * which must still name fd's file. Returns fd itself when the file has one
 * name, else a new descriptor (read and write) of the copy, which the
 * caller takes in fd's place; or -errno, with no copy left (-EEXIST: a
 * file is at `copy`, other than a killed resume's copy cut short, which
 * goes). */
int ellroll_one_name(int fd, const char *path, const char *copy)
{
    struct stat info;
    if (fstat(fd, &info) != 0)
        return -errno;
    if (info.st_nlink <= 1)
        return fd;
    int out;
    for (int tries = 0;; ++tries) {
        do {
            out = open(copy, O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, info.st_mode & 07777);
        } while (out < 0 && errno == EINTR);
        if (out >= 0 || errno != EEXIST || tries > 0 || !stale_copy(fd, copy))
            break;
        if (unlink(copy) != 0)
            return -errno;
    }
    if (out < 0)
        return -errno;
    char buffer[65536];
    int code = 0;
    for (off_t at = 0; code == 0;) {
        ssize_t got = pread(fd, buffer, sizeof buffer, at);
        if (got < 0 && errno == EINTR)
            continue;
        if (got <= 0) {
            code = got < 0 ? errno : 0;
            break;
        }
        for (ssize_t done = 0; done < got && code == 0;) {
            ssize_t put = pwrite(out, buffer + done, (size_t)(got - done), at + done);
            if (put < 0 && errno != EINTR)
                code = errno;
            else if (put > 0)
                done += put;
        }
        at += got;
    }
    if (code == 0 && fsync(out) != 0)
        code = errno;
    if (code == 0 && !ellroll_descriptor_is_at(fd, path))
        code = ENOENT;                       /* the name went elsewhere meanwhile */
    if (code == 0 && rename(copy, path) != 0)
        code = errno;
    if (code != 0) {
        unlink(copy);
        close(out);
        return -code;
    }
    return out;
}

/* Whether this process holds CAP_FOWNER (the right to remove another
 * user's file from a sticky folder). */
static int may_override_owners(void)
{
    struct __user_cap_header_struct header = {_LINUX_CAPABILITY_VERSION_3, 0};
    struct __user_cap_data_struct data[2];
    memset(data, 0, sizeof data);
    if (syscall(SYS_capget, &header, data) != 0)
        return geteuid() == 0;
    return (data[CAP_FOWNER / 32].effective >> (CAP_FOWNER % 32)) & 1u;
}

/* 0 when the name path (a file there, or nothing) may be replaced or
 * removed by this process as far as the sticky bit of its folder `folder`
 * goes; EPERM when that folder is sticky and neither the file nor the
 * folder is this user's (the kernel's rule for rename and unlink there),
 * its owner's uid in *owner; another errno where it cannot be told. */
int ellroll_sticky_refusal(const char *path, const char *folder, long *owner)
{
    struct stat file, place;
    *owner = -1;
    if (lstat(path, &file) != 0)
        return errno == ENOENT ? 0 : errno;
    if (stat(folder, &place) != 0)
        return errno;
    if (!(place.st_mode & S_ISVTX))
        return 0;
    uid_t me = geteuid();
    if (file.st_uid == me || place.st_uid == me || may_override_owners())
        return 0;
    *owner = (long)file.st_uid;
    return EPERM;
}

/* Write what the file at path holds to the disk, and then the folder's
 * entry of it: 0 or errno. */
int ellroll_sync_path(const char *path)
{
    int fd, code = 0;
    do {
        fd = open(path, O_RDONLY | O_NOFOLLOW | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    if (fd < 0)
        return errno;
    if (fsync(fd) != 0 && errno != EINVAL)
        code = errno;
    if (close(fd) != 0 && code == 0)
        code = errno;
    return code;
}

/* The folder's entries (after a rename or an unlink) to the disk: 0 or errno
 * (a file system that cannot sync a folder is not an error). */
int ellroll_sync_folder(const char *folder)
{
    int fd, code = 0;
    do {
        fd = open(folder, O_RDONLY | O_DIRECTORY | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    if (fd < 0)
        return errno;
    if (fsync(fd) != 0 && errno != EINVAL && errno != EBADF)
        code = errno;
    close(fd);
    return code;
}

/* The first bytes of the regular file at path (a link not followed), for a
 * look at what it is: how many were read, or -errno. */
int ellroll_read_head(const char *path, char *buffer, int size)
{
    int fd, got;
    do {
        fd = open(path, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    if (fd < 0)
        return -errno;
    do {
        got = (int)pread(fd, buffer, (size_t)size, 0);
    } while (got < 0 && errno == EINTR);
    int code = got < 0 ? -errno : got;
    close(fd);
    return code;
}

/* The lock of one output: an exclusive fcntl lock on the lock file at path,
 * which then holds `me` (who holds it). A descriptor (>= 0) while it is
 * held; -EAGAIN when another process holds it, its `me` copied into holder
 * (null-terminated); -EEXIST when path is not a lock file (a link, a
 * folder, a file with other names, or a file that holds something else); other -errno (a file
 * system without locks: -ENOLCK and the like, the file made for the lock
 * removed, a file that was there left alone). A process
 * that releases its lock removes the file first, so one that locked the
 * removed file looks again. */
int ellroll_lock_output(const char *path, const char *me, char *holder, int size)
{
    static const char mark[] = "ellroll lock";
    holder[0] = '\0';
    for (int attempt = 0; attempt < 16; ++attempt) {
        int fd, created = 1;
        do {
            fd = open(path, O_RDWR | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC, 0666);
        } while (fd < 0 && errno == EINTR);
        if (fd < 0 && errno == EEXIST) {
            created = 0;
            do {
                fd = open(path, O_RDWR | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
            } while (fd < 0 && errno == EINTR);
            if (fd < 0 && errno == ENOENT)
                continue;                     /* removed meanwhile: look again */
            if (fd < 0)
                return errno == ELOOP || errno == EISDIR ? -EEXIST : -errno;
        } else if (fd < 0) {
            return -errno;
        }
        struct stat info;
        /* (a lock file of ours has one name: one with more is another's file,
         * empty or not, which a note written here would change) */
        if (fstat(fd, &info) != 0 || !S_ISREG(info.st_mode) || (!created && info.st_nlink > 1)) {
            close(fd);
            return -EEXIST;
        }
        if (!created && info.st_size > 0) {   /* someone's file: only a lock file of ours */
            char head[sizeof mark];
            ssize_t got;
            do {
                got = pread(fd, head, sizeof mark - 1, 0);
            } while (got < 0 && errno == EINTR);
            if (got < 0) {                    /* unread: no verdict on what it holds */
                int code = errno;
                close(fd);
                return -code;
            }
            if (got != (ssize_t)(sizeof mark - 1) || memcmp(head, mark, sizeof mark - 1) != 0) {
                close(fd);
                return -EEXIST;
            }
        }
        struct flock lock;
        memset(&lock, 0, sizeof lock);
        lock.l_type = F_WRLCK;
        lock.l_whence = SEEK_SET;
        if (fcntl(fd, F_SETLK, &lock) != 0) {
            int code = errno;
            if (code == EACCES || code == EAGAIN) {
                ssize_t got = pread(fd, holder, (size_t)(size - 1), 0);
                holder[got > 0 ? got : 0] = '\0';
                close(fd);
                return -EAGAIN;
            }
            /* not locked (a file system without locks: the run goes on
             * unlocked): a file made here for the lock goes at once */
            if (created && ellroll_descriptor_is_at(fd, path))
                unlink(path);
            close(fd);
            return -code;
        }
        if (!ellroll_descriptor_is_at(fd, path)) {   /* its holder removed it as we opened it */
            close(fd);
            continue;
        }
        if (!created) {                       /* a killed run's note, for a refusal to put back */
            ssize_t got;
            do {
                got = pread(fd, holder, (size_t)(size - 1), 0);
            } while (got < 0 && errno == EINTR);
            if (got < 0) {                    /* unread: nothing is taken over */
                int code = errno;
                close(fd);
                return -code;
            }
            holder[got] = '\0';
        }
        size_t length = strlen(me);
        if (ftruncate(fd, 0) != 0 || pwrite(fd, me, length, 0) != (ssize_t)length) {
            int code = errno;
            close(fd);
            unlink(path);
            return -code;
        }
        return fd;
    }
    return -EAGAIN;
}

/* Whether another process holds the lock of an output at path (fcntl
 * F_GETLK: nothing taken, so a resume starting meanwhile is not refused):
 * 1, or 0 where no lock file of ellroll's is held there (none, not a
 * regular file, a link); a regular file's note is copied into holder
 * (null-terminated), held or not (a killed run's names its command). */
int ellroll_lock_held(const char *path, char *holder, int size)
{
    holder[0] = '\0';
    int fd;
    do {
        fd = open(path, O_RDONLY | O_NOFOLLOW | O_NONBLOCK | O_CLOEXEC);
    } while (fd < 0 && errno == EINTR);
    if (fd < 0)
        return 0;
    struct stat info;
    struct flock lock;
    memset(&lock, 0, sizeof lock);
    lock.l_type = F_WRLCK;
    lock.l_whence = SEEK_SET;
    int regular = fstat(fd, &info) == 0 && S_ISREG(info.st_mode);
    int held = regular && fcntl(fd, F_GETLK, &lock) == 0 && lock.l_type != F_UNLCK;
    if (regular) {
        ssize_t got = pread(fd, holder, (size_t)(size - 1), 0);
        holder[got > 0 ? got : 0] = '\0';
    }
    close(fd);
    return held;
}

/* Release a lock of ellroll_lock_output: the file removed, then the lock
 * (closing the descriptor releases it; a failed close loses nothing: the
 * file held only the note). 0 or the errno of the removal. */
int ellroll_unlock_output(int fd, const char *path)
{
    int code = 0;
    if (ellroll_descriptor_is_at(fd, path) && unlink(path) != 0)
        code = errno;
    close(fd);
    return code;
}

/* Release a lock of ellroll_lock_output that a refused command took over
 * from a killed run: the killed run's note put back, the file kept. 0 or
 * errno. */
int ellroll_unlock_keeping(int fd, const char *path, const char *note)
{
    int code = 0;
    size_t length = strlen(note);
    if (ellroll_descriptor_is_at(fd, path) &&
        (ftruncate(fd, 0) != 0 || pwrite(fd, note, length, 0) != (ssize_t)length))
        code = errno;
    close(fd);
    return code;
}

/* This host's name, for the lock's note of its holder. */
void ellroll_host_name(char *name, int size)
{
    if (gethostname(name, (size_t)size) != 0)
        snprintf(name, (size_t)size, "?");
    name[size - 1] = '\0';
}

/* This process's id. */
long ellroll_process_id(void)
{
    return (long)getpid();
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

/* The bytes free to this user on the file system that holds path; -1
 * where it cannot be told. */
long long ellroll_free_bytes(const char *path)
{
    struct statvfs info;
    if (statvfs(path, &info) != 0)
        return -1;
    return (long long)info.f_bavail * (long long)info.f_frsize;
}
