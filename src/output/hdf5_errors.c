/* Why an HDF5 call failed, in words: HDF5 keeps its errors on a stack of
 * descriptions; the driver that reads and writes the file records the
 * system's reason there ("errno = 5, error message = 'Input/output error'"). */
#include <fcntl.h>
#include <hdf5.h>
#include <stdio.h>
#include <string.h>
#include <unistd.h>

struct reason {
    char system[160];      /* the system's words, where an entry has them */
    char innermost[240];   /* the most specific entry's description */
};

static herr_t look_at(unsigned n, const H5E_error2_t *entry, void *data)
{
    struct reason *found = data;
    const char *desc = entry->desc ? entry->desc : "";
    if (n == 0)
        snprintf(found->innermost, sizeof found->innermost, "%s", desc);
    const char *words = strstr(desc, "error message = '");
    if (words && found->system[0] == '\0') {
        words += strlen("error message = '");
        const char *end = strchr(words, '\'');
        size_t length = end ? (size_t)(end - words) : strlen(words);
        if (length >= sizeof found->system)
            length = sizeof found->system - 1;
        memcpy(found->system, words, length);
        found->system[length] = '\0';
    }
    return 0;
}

/* The reason of the last failed HDF5 call into text (null-terminated): the
 * system's words where the file's driver recorded them, else HDF5's own
 * description; the error stack is cleared. */
void ellroll_hdf5_error_text(char *text, int size)
{
    struct reason found;
    found.system[0] = '\0';
    found.innermost[0] = '\0';
    H5Ewalk2(H5E_DEFAULT, H5E_WALK_UPWARD, look_at, &found);
    if (found.system[0] != '\0')
        snprintf(text, (size_t)size, "%s", found.system);
    else if (found.innermost[0] != '\0')
        snprintf(text, (size_t)size, "HDF5: %s", found.innermost);
    else
        snprintf(text, (size_t)size, "HDF5 error");
    H5Eclear2(H5E_DEFAULT);
}

/* The first failure of an HDF5 call on this thread, since it was last
 * forgotten, that the file's driver met in a system call: the system's
 * words and the file's name. HDF5 calls report_failure as its automatic
 * error handler, in place of printing its error stack. */
static _Thread_local struct {
    int seen;
    char words[160];
    char file[1024];
} system_failure;

static _Thread_local int handler_set;

static herr_t look_for_file(unsigned n, const H5E_error2_t *entry, void *data)
{
    (void)n;
    const char *desc = entry->desc ? entry->desc : "";
    if (!strstr(desc, "error message = '") || system_failure.file[0] != '\0')
        return 0;
    const char *name = strstr(desc, "filename = '");
    size_t skip = strlen("filename = '");
    if (!name) {
        name = strstr(desc, "name = '");
        skip = strlen("name = '");
    }
    if (!name)
        return 0;
    name += skip;
    const char *end = strchr(name, '\'');
    size_t length = end ? (size_t)(end - name) : strlen(name);
    if (length >= sizeof system_failure.file)
        length = sizeof system_failure.file - 1;
    memcpy(system_failure.file, name, length);
    system_failure.file[length] = '\0';
    (void)data;
    return 0;
}

static herr_t report_failure(hid_t stack, void *unused)
{
    (void)unused;
    if (system_failure.seen)
        return 0;
    struct reason found;
    found.system[0] = '\0';
    found.innermost[0] = '\0';
    H5Ewalk2(stack, H5E_WALK_UPWARD, look_at, &found);
    if (found.system[0] == '\0')
        return 0;
    system_failure.seen = 1;
    snprintf(system_failure.words, sizeof system_failure.words, "%s", found.system);
    system_failure.file[0] = '\0';
    H5Ewalk2(stack, H5E_WALK_UPWARD, look_for_file, NULL);
    return 0;
}

/* HDF5 prints no error stack on this thread (its automatic handler is set
 * per thread in a thread-safe library): failures are reported through
 * ellroll's own errors, and the system's are noted (ellroll_hdf5_system_
 * failure). Once per thread; every HDF5 entry point of ellroll calls it. */
void ellroll_hdf5_quiet(void)
{
    if (handler_set)
        return;
    if (H5Eset_auto2(H5E_DEFAULT, report_failure, NULL) >= 0)
        handler_set = 1;
}

/* Forget the noted system failure of this thread. */
void ellroll_hdf5_forget_failure(void)
{
    system_failure.seen = 0;
    system_failure.words[0] = '\0';
    system_failure.file[0] = '\0';
}

/* 1 when an HDF5 call on this thread failed in a system call since the
 * failure was last forgotten: its words and file (null-terminated, '' when
 * HDF5 did not name it); else 0. */
int ellroll_hdf5_system_failure(char *words, int words_size, char *file, int file_size)
{
    snprintf(words, (size_t)words_size, "%s", system_failure.words);
    snprintf(file, (size_t)file_size, "%s", system_failure.file);
    return system_failure.seen;
}

/* A descriptor (its own, close-on-exec) of the file open as `file` through
 * HDF5's sec2 driver: the very file HDF5 made or opened, not whatever a
 * name holds by then; -1 where HDF5 cannot give it. */
int ellroll_hdf5_descriptor(hid_t file)
{
    void *handle = NULL;
    if (H5Fget_vfd_handle(file, H5P_DEFAULT, &handle) < 0 || handle == NULL)
        return -1;
    int fd = fcntl(*(int *)handle, F_DUPFD_CLOEXEC, 0);
    return fd >= 0 ? fd : dup(*(int *)handle);    /* (a kernel without F_DUPFD_CLOEXEC) */
}

/* The file address of the object header of `name` (below loc): where HDF5
 * put it when this file was made. A copy of the file by another program
 * (h5py, xarray, h5repack) lays its objects out anew. -1: no such object. */
long long ellroll_hdf5_object_address(hid_t loc, const char *name)
{
#if H5_VERSION_GE(1, 12, 0)
    H5O_info2_t info;
    haddr_t address;
    if (H5Oget_info_by_name3(loc, name, &info, H5O_INFO_BASIC, H5P_DEFAULT) < 0)
        return -1;
    if (H5VLnative_token_to_addr(loc, info.token, &address) < 0)
        return -1;
    return (long long)address;
#else
    H5O_info_t info;
    if (H5Oget_info_by_name2(loc, name, &info, H5O_INFO_BASIC, H5P_DEFAULT) < 0)
        return -1;
    return (long long)info.addr;
#endif
}

/* How many files, groups, datasets and attributes HDF5 holds open in this
 * process (not the datatypes: HDF5's Fortran layer holds its predefined
 * ones open); -1 where HDF5 cannot say. */
long long ellroll_hdf5_open_ids(void)
{
    ssize_t n = H5Fget_obj_count(H5F_OBJ_ALL, H5F_OBJ_FILE | H5F_OBJ_DATASET | H5F_OBJ_GROUP | H5F_OBJ_ATTR);
    return n < 0 ? -1 : (long long)n;
}
