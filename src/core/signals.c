/* Signals that end a run early, turned into a request the program polls.
 *
 * SIGTERM (Slurm at the time limit, or earlier with --signal) and SIGINT
 * (Ctrl-C) only set a flag: the campaign stops starting cases, drops the
 * cases under way, and leaves with the journal and the partial file closed,
 * so that --resume finishes the rest. A second SIGINT (Ctrl-C pressed
 * again) ends the process at once, as if it had not been caught; more
 * SIGTERMs change nothing (scancel and a job script's trap may both send
 * one; the batch system's SIGKILL follows if the run does not end).
 *
 * SIGHUP (the terminal or ssh connection that started the run closed) stops
 * it as SIGTERM does, where it is not ignored (nohup): its lock and files
 * are left as a stopped run leaves them, for --resume.
 *
 * SIGPIPE (whoever read standard output or error is gone: a `| head`, a
 * dropped ssh connection's tee) is ignored: the write fails with EPIPE
 * instead of ending the process. The run goes on, its progress lines and
 * messages lost, and finishes its file; a summary that cannot be written
 * to standard output is then exit 3, as any failed write of it. */
#include <signal.h>
#include <string.h>
#include <unistd.h>

static volatile sig_atomic_t stop_signal = 0;

static void on_stop_signal(int sig)
{
    if (stop_signal != 0 && sig == SIGINT) {
        signal(sig, SIG_DFL);
        raise(sig);
        return;
    }
    if (stop_signal == 0)
        stop_signal = sig;
}

void ellroll_catch_stop_signals(void)
{
    struct sigaction action;
    memset(&action, 0, sizeof action);
    action.sa_handler = on_stop_signal;
    sigemptyset(&action.sa_mask);
    action.sa_flags = SA_RESTART;
    sigaction(SIGTERM, &action, NULL);
    sigaction(SIGINT, &action, NULL);
    struct sigaction hangup;
    if (sigaction(SIGHUP, NULL, &hangup) == 0 && hangup.sa_handler != SIG_IGN)
        sigaction(SIGHUP, &action, NULL);
    signal(SIGPIPE, SIG_IGN);
}

/* The signal that asked the run to stop, or 0. Read atomically: a
 * library caller's thread may set it (ellroll_request_stop) while the
 * run's threads poll it. */
int ellroll_stop_signal(void)
{
    return __atomic_load_n(&stop_signal, __ATOMIC_RELAXED);
}

/* Ask every run of the process under way to stop as if sig had come (a
 * library caller's Ctrl-C: the process's own handler is Python's), or,
 * with 0, let runs go on again (when none is under way). */
void ellroll_request_stop(int sig)
{
    __atomic_store_n(&stop_signal, sig, __ATOMIC_RELAXED);
}

/* A read that HDF5 may never finish: it loops for ever, inside one call, on
 * some damaged global heaps (the store of variable-length texts). For a
 * command that writes nothing (summary), an alarm after `seconds` writes
 * `message` and a newline to standard error and ends the process with
 * exit 2, as for any damaged input; 0 seconds disarms it. */
static char watchdog_text[4608];
static size_t watchdog_length;

static void on_watchdog(int sig)
{
    (void)sig;
    ssize_t written = write(STDERR_FILENO, watchdog_text, watchdog_length);
    (void)written;
    _exit(2);
}

void ellroll_read_watchdog(const char *message, int seconds)
{
    struct sigaction action;
    size_t n;
    if (seconds <= 0) {
        alarm(0);
        return;
    }
    n = strlen(message);
    if (n > sizeof watchdog_text - 1)
        n = sizeof watchdog_text - 1;
    memcpy(watchdog_text, message, n);
    watchdog_text[n] = '\n';
    watchdog_length = n + 1;
    memset(&action, 0, sizeof action);
    action.sa_handler = on_watchdog;
    sigemptyset(&action.sa_mask);
    sigaction(SIGALRM, &action, NULL);
    alarm((unsigned)seconds);
}
