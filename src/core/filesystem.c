/* Questions to the file system that Fortran's inquire cannot ask. */
#include <errno.h>
#include <unistd.h>

/* 0 when files can be created in folder `path` (it exists, is a folder, and
 * this process may write and search it), else the errno value that says why. */
int ellroll_folder_write_error(const char *path)
{
    return access(path, W_OK | X_OK) == 0 ? 0 : errno;
}
