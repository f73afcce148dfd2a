/* Why an HDF5 call failed, in words: HDF5 keeps its errors on a stack of
 * descriptions; the driver that reads and writes the file records the
 * system's reason there ("errno = 5, error message = 'Input/output error'"). */
#include <hdf5.h>
#include <stdio.h>
#include <string.h>

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
