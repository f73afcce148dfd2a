/* Process-wide settings of the C runtime, made once at program start
 * (ellroll and the benchmarks call it).
 *
 * Keep freed memory in the process instead of handing it back to the system
 * at once. Every case allocates its output buffers and frees them once they
 * are written, and a campaign block its journal records (over 128 KiB for
 * 8 cases). With glibc's defaults the heap shrinks after each batch (trim
 * threshold 128 KiB) and blocks over 128 KiB are mapped and unmapped each
 * time (setting the trim threshold also fixes the mmap threshold at its
 * default): the next batch page-faults its memory in again, about 6 ns per
 * case-step of a batch storing every field at 100 Hz (bench/throughput) and
 * 4 % of a campaign (perf, with the writer's windows freed and allocated
 * each time; src/output recycles them). Up to 256 MiB of freed
 * heap is kept for reuse and blocks up to 32 MiB come from the heap; peak
 * memory does not change. Other C libraries (no M_TRIM_THRESHOLD): nothing.
 *
 * Ignore SIGXFSZ: past a file-size limit (ulimit -f, as batch systems set
 * it) a write then fails with EFBIG, which the program reports like any
 * other write error; the signal's default action would end it with a core. */
#ifdef __linux__
#include <malloc.h>
#endif
#include <pthread.h>
#include <signal.h>
#include <sys/resource.h>
#include <unistd.h>

void ellroll_crc32c_init(void);

void ellroll_tune_runtime(void)
{
#ifdef M_TRIM_THRESHOLD
    mallopt(M_TRIM_THRESHOLD, 256 * 1024 * 1024);
#endif
#ifdef M_MMAP_THRESHOLD
    mallopt(M_MMAP_THRESHOLD, 32 * 1024 * 1024);
#endif
    signal(SIGXFSZ, SIG_IGN);
    ellroll_crc32c_init(); /* before threads compute checksums */
}

/* Room for `needed` open files: the soft limit on descriptors raised
 * towards the hard one where it is lower (a merge holds every shard open,
 * and a job array's thousand shards pass the usual soft limit of 1024).
 * The soft limit after it; -1 where it cannot be read. */
long ellroll_open_files_room(long needed)
{
    struct rlimit limit;
    if (getrlimit(RLIMIT_NOFILE, &limit) != 0)
        return -1;
    if (limit.rlim_cur != RLIM_INFINITY && (rlim_t)needed > limit.rlim_cur) {
        rlim_t wanted = limit.rlim_max == RLIM_INFINITY || (rlim_t)needed < limit.rlim_max
                        ? (rlim_t)needed : limit.rlim_max;
        struct rlimit raised = {wanted, limit.rlim_max};
        if (setrlimit(RLIMIT_NOFILE, &raised) == 0)
            limit.rlim_cur = wanted;
    }
    return limit.rlim_cur == RLIM_INFINITY || limit.rlim_cur > (rlim_t)(1L << 40) ? 1L << 40 : (long)limit.rlim_cur;
}

/* The memory this process may hold, bytes: the machine's physical memory,
 * or the soft limit on its address space (ulimit -v) where that is lower;
 * -1 where neither can be read. */
long long ellroll_memory_room(void)
{
    long long room = -1;
    long pages = sysconf(_SC_PHYS_PAGES), page = sysconf(_SC_PAGE_SIZE);
    if (pages > 0 && page > 0)
        room = (long long)pages * page;
    struct rlimit limit;
    if (getrlimit(RLIMIT_AS, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY
        && (room < 0 || (long long)limit.rlim_cur < room))
        room = (long long)limit.rlim_cur;
    return room;
}

/* The lock of the record store (ellroll_record_store): runs of the library
 * read inputs on several threads at once, with or without OpenMP. */
static pthread_mutex_t record_store_lock = PTHREAD_MUTEX_INITIALIZER;

void ellroll_lock_record_store(void)
{
    pthread_mutex_lock(&record_store_lock);
}

void ellroll_unlock_record_store(void)
{
    pthread_mutex_unlock(&record_store_lock);
}
