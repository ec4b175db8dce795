/*
 * neptunus_uart - Erlang port program for one serial line.
 *
 *   neptunus_uart tty DEVICE BAUD   open a serial device (e.g. /dev/ttyO1 115200), 8N1, raw
 *   neptunus_uart pty LINK          create a pseudo-terminal pair, symlink its slave end to
 *                                   LINK and speak on the master end (the SITL board's side)
 *
 * Started by Erlang with open_port({spawn_executable, ...}, [{packet, 2}, binary, exit_status]).
 * Every message in either direction is a {packet, 2} frame (2-byte big-endian length) whose
 * first byte is a tag:
 *
 *   VM -> program   'w' DATA     write DATA to the line (queued while the line is busy)
 *                   's'          ask for counters; answered with 's'
 *   program -> VM   'o' PATH     the line is open and configured (for pty: the slave's path)
 *                   'O'          pty mode: someone opened the slave end (a board link opening
 *                                the line; the SITL board resets on it, as a USB Arduino
 *                                does). Seen with inotify; none where inotify is missing.
 *                   'r' DATA     bytes read from the line
 *                   'd' N        N bytes (decimal text) of a 'w' dropped: output queue full
 *                   's' TEXT     "rx=N tx=N dropped=N queued=N"
 *                   'e' TEXT     what went wrong; the program exits right after (see below)
 *
 * The program never writes anything else to stdout: errors travel as 'e' frames (and to stderr when
 * NEPTUNUS_UART_DEBUG is set).
 *
 * Environment: NEPTUNUS_SLICE_NS=N asks the kernel for a scheduler time slice of N ns for this
 * program (see Neptunus.OS: since Linux 6.12 a short slice wakes it promptly; ignored before).
 * NEPTUNUS_UART_RX_STAMPS=1 sends, before each 'r' frame, a 't' frame with the CLOCK_MONOTONIC
 * time of the read in nanoseconds (decimal text): bench/control_latency times the bytes where
 * they were read. The VM's board link sets neither stamps nor expects them.
 *
 * It exits
 *   0   stdin closed (the VM closed the port or died), after flushing queued output briefly
 *   64  usage error             65  unsupported baud rate
 *   66  open/configure failed   67  the line hung up (EOF, POLLHUP: unplugged, pty closed)
 *   68  I/O error on the line   69  malformed frame from the VM   70  stdout/stdin error
 *
 * Built by `mix compile` (Mix.Tasks.Compile.PortPrograms in mix.exs) into priv/.
 */
#define _DEFAULT_SOURCE
#define _XOPEN_SOURCE 600

#include <errno.h>
#include <fcntl.h>
#include <poll.h>
#include <signal.h>
#include <stdarg.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sched.h>
#include <sys/inotify.h>
#include <sys/ioctl.h>
#include <sys/syscall.h>
#include <termios.h>
#include <time.h>
#include <unistd.h>

#ifndef SCHED_BATCH
#define SCHED_BATCH 3 /* <sched.h> names it only under _GNU_SOURCE */
#endif

#define EXIT_STDIN_CLOSED 0
#define EXIT_USAGE 64
#define EXIT_BAUD 65
#define EXIT_OPEN 66
#define EXIT_HANGUP 67
#define EXIT_IO 68
#define EXIT_FRAME 69
#define EXIT_STDIO 70

#define IN_MAX (2 + 65535)     /* one full {packet, 2} frame */
#define OUT_QUEUE_MAX 65536    /* bytes waiting for the line before writes are dropped */
#define READ_CHUNK 4096
#define FLUSH_ON_EXIT_MS 200

static int line_fd = -1;
static unsigned char in_buf[IN_MAX];
static size_t in_len = 0;
static unsigned char out_queue[OUT_QUEUE_MAX];
static size_t out_len = 0;
static unsigned long long rx_bytes = 0, tx_bytes = 0, dropped_bytes = 0;
static int rx_stamps = 0;

/* pty mode: the symlink we made and the slave path it points to, removed at exit */
static char link_path[4096];
static char slave_path[256];
static int slave_keepalive_fd = -1;
static int open_watch_fd = -1; /* inotify: opens of the slave end */

/* ---- frames to the VM ------------------------------------------------------------- */

static void write_all(int fd, const unsigned char *buf, size_t len)
{
    while (len > 0) {
        ssize_t n = write(fd, buf, len);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            _exit(EXIT_STDIO); /* the VM is gone; nothing left to tell it */
        }
        buf += n;
        len -= (size_t)n;
    }
}

static void send_frame(char tag, const void *data, size_t len)
{
    unsigned char header[3];
    if (len > 65534)
        len = 65534;
    header[0] = (unsigned char)((len + 1) >> 8);
    header[1] = (unsigned char)((len + 1) & 0xff);
    header[2] = (unsigned char)tag;
    write_all(STDOUT_FILENO, header, sizeof header);
    if (len > 0)
        write_all(STDOUT_FILENO, data, len);
}

static void send_text(char tag, const char *fmt, ...)
{
    char text[1024];
    va_list ap;
    va_start(ap, fmt);
    int n = vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    if (n < 0)
        n = 0;
    if ((size_t)n >= sizeof text)
        n = (int)sizeof text - 1;
    send_frame(tag, text, (size_t)n);
}

/* Tells the VM why (the VM logs it), then exits with `status`. Set NEPTUNUS_UART_DEBUG to
 * also print it on stderr. */
static void fail(int status, const char *fmt, ...)
{
    char text[1024];
    va_list ap;
    va_start(ap, fmt);
    vsnprintf(text, sizeof text, fmt, ap);
    va_end(ap);
    send_frame('e', text, strlen(text));
    if (getenv("NEPTUNUS_UART_DEBUG") != NULL)
        fprintf(stderr, "neptunus_uart: %s\n", text);
    exit(status);
}

/* ---- the line ------------------------------------------------------------------- */

static speed_t baud_constant(long baud)
{
    switch (baud) {
    case 1200: return B1200;
    case 2400: return B2400;
    case 4800: return B4800;
    case 9600: return B9600;
    case 19200: return B19200;
    case 38400: return B38400;
    case 57600: return B57600;
    case 115200: return B115200;
    case 230400: return B230400;
    case 460800: return B460800;
    case 921600: return B921600;
    default: return (speed_t)0;
    }
}

/* Raw 8N1, no flow control, reads return as soon as one byte is there. */
static int configure_raw(int fd, speed_t speed)
{
    struct termios tio;
    if (tcgetattr(fd, &tio) < 0)
        return -1;
    cfmakeraw(&tio);
    tio.c_cflag |= CLOCAL | CREAD;
    tio.c_cflag &= ~(tcflag_t)(CSTOPB | CRTSCTS);
    tio.c_cc[VMIN] = 1;
    tio.c_cc[VTIME] = 0;
    if (speed != (speed_t)0) {
        if (cfsetispeed(&tio, speed) < 0 || cfsetospeed(&tio, speed) < 0)
            return -1;
    }
    /* TCSANOW: TCSAFLUSH would throw away bytes the other side already sent */
    return tcsetattr(fd, TCSANOW, &tio);
}

static void open_tty(const char *device, const char *baud_text)
{
    char *end = NULL;
    long baud = strtol(baud_text, &end, 10);
    speed_t speed = baud_constant(baud);
    if (end == baud_text || *end != '\0' || speed == (speed_t)0)
        fail(EXIT_BAUD, "unsupported baud rate %s", baud_text);

    line_fd = open(device, O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (line_fd < 0)
        fail(EXIT_OPEN, "open %s: %s", device, strerror(errno));
    if (!isatty(line_fd))
        fail(EXIT_OPEN, "%s is not a terminal device", device);
    if (configure_raw(line_fd, speed) < 0)
        fail(EXIT_OPEN, "configure %s: %s", device, strerror(errno));
    /* Nobody else (but root) may open the line while we have it. */
    (void)ioctl(line_fd, TIOCEXCL);
    /* Bytes that waited in the driver before we opened belong to an earlier session (stale
     * telemetry): drop them. What the board sends from now on is kept. */
    (void)tcflush(line_fd, TCIFLUSH);
    send_frame('o', device, strlen(device));
}

static void remove_link(void)
{
    char target[sizeof slave_path];
    ssize_t n;
    if (link_path[0] == '\0')
        return;
    n = readlink(link_path, target, sizeof target - 1);
    if (n > 0) {
        target[n] = '\0';
        if (strcmp(target, slave_path) == 0)
            unlink(link_path);
    }
}

static void open_pty(const char *link)
{
    char tmp[sizeof link_path + 16];
    const char *name;

    if (strlen(link) >= sizeof link_path)
        fail(EXIT_USAGE, "link path too long");
    line_fd = posix_openpt(O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (line_fd < 0 || grantpt(line_fd) < 0 || unlockpt(line_fd) < 0)
        fail(EXIT_OPEN, "create pty: %s", strerror(errno));
    name = ptsname(line_fd);
    if (name == NULL || strlen(name) >= sizeof slave_path)
        fail(EXIT_OPEN, "ptsname: %s", strerror(errno));
    strcpy(slave_path, name);

    /* Keep one slave descriptor open for the program's life: the master then never sees a
     * hangup while the board side closes and reopens its end. It also carries the raw
     * termios settings, which belong to the pair. */
    slave_keepalive_fd = open(slave_path, O_RDWR | O_NOCTTY | O_NONBLOCK);
    if (slave_keepalive_fd < 0 || configure_raw(slave_keepalive_fd, (speed_t)0) < 0)
        fail(EXIT_OPEN, "open %s: %s", slave_path, strerror(errno));

    /* Best effort: without inotify the board just never hears of opens. */
    open_watch_fd = inotify_init1(IN_NONBLOCK | IN_CLOEXEC);
    if (open_watch_fd >= 0 && inotify_add_watch(open_watch_fd, slave_path, IN_OPEN) < 0) {
        close(open_watch_fd);
        open_watch_fd = -1;
    }

    strcpy(link_path, link);
    snprintf(tmp, sizeof tmp, "%s.%ld", link, (long)getpid());
    unlink(tmp);
    if (symlink(slave_path, tmp) < 0 || rename(tmp, link) < 0) {
        int err = errno;
        unlink(tmp);
        link_path[0] = '\0';
        fail(EXIT_OPEN, "link %s -> %s: %s", link, slave_path, strerror(err));
    }
    atexit(remove_link);
    send_frame('o', slave_path, strlen(slave_path));
}

/* Writes as much of the queue as the line takes now. */
static void drain_queue(void)
{
    while (out_len > 0) {
        ssize_t n = write(line_fd, out_queue, out_len);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            if (errno == EAGAIN || errno == EWOULDBLOCK)
                return;
            if (errno == EIO)
                fail(EXIT_HANGUP, "hangup: write: %s", strerror(errno));
            fail(EXIT_IO, "write: %s", strerror(errno));
        }
        tx_bytes += (unsigned long long)n;
        out_len -= (size_t)n;
        memmove(out_queue, out_queue + n, out_len);
    }
}

static void read_line_fd(void)
{
    unsigned char buf[READ_CHUNK];
    for (;;) {
        ssize_t n = read(line_fd, buf, sizeof buf);
        if (n > 0) {
            rx_bytes += (unsigned long long)n;
            if (rx_stamps) {
                struct timespec ts;
                clock_gettime(CLOCK_MONOTONIC, &ts);
                send_text('t', "%lld", (long long)ts.tv_sec * 1000000000LL + ts.tv_nsec);
            }
            send_frame('r', buf, (size_t)n);
            if ((size_t)n < sizeof buf)
                return;
            continue;
        }
        if (n == 0)
            fail(EXIT_HANGUP, "hangup: end of file on the line");
        if (errno == EINTR)
            continue;
        if (errno == EAGAIN || errno == EWOULDBLOCK)
            return;
        if (errno == EIO)
            fail(EXIT_HANGUP, "hangup: %s", strerror(errno));
        fail(EXIT_IO, "read: %s", strerror(errno));
    }
}

/* pty mode: one 'O' frame for every open of the slave end since the last read. */
static void read_open_watch(void)
{
    unsigned char buf[4096] __attribute__((aligned(__alignof__(struct inotify_event))));
    for (;;) {
        ssize_t n = read(open_watch_fd, buf, sizeof buf);
        size_t pos = 0;
        if (n < 0 && errno == EINTR)
            continue;
        if (n <= 0)
            return;
        while (pos + sizeof(struct inotify_event) <= (size_t)n) {
            const struct inotify_event *event = (const struct inotify_event *)(buf + pos);
            if (event->mask & IN_OPEN)
                send_frame('O', NULL, 0);
            pos += sizeof(struct inotify_event) + event->len;
        }
    }
}

/* ---- commands from the VM: the dispatch table ------------------------------------- */

static void cmd_write(const unsigned char *data, size_t len)
{
    if (out_len + len > OUT_QUEUE_MAX) {
        dropped_bytes += len;
        send_text('d', "%zu", len);
        return;
    }
    memcpy(out_queue + out_len, data, len);
    out_len += len;
    drain_queue();
}

static void cmd_stats(const unsigned char *data, size_t len)
{
    (void)data;
    (void)len;
    send_text('s', "rx=%llu tx=%llu dropped=%llu queued=%zu", rx_bytes, tx_bytes,
              dropped_bytes, out_len);
}

struct command {
    char tag;
    void (*handler)(const unsigned char *data, size_t len);
};

static const struct command commands[] = {
    {'w', cmd_write},
    {'s', cmd_stats},
};

static void dispatch(const unsigned char *frame, size_t len)
{
    size_t i;
    if (len == 0)
        fail(EXIT_FRAME, "empty frame from the VM");
    for (i = 0; i < sizeof commands / sizeof commands[0]; i++) {
        if (commands[i].tag == (char)frame[0]) {
            commands[i].handler(frame + 1, len - 1);
            return;
        }
    }
    fail(EXIT_FRAME, "unknown tag 0x%02x from the VM", frame[0]);
}

static long long now_ms(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (long long)ts.tv_sec * 1000 + ts.tv_nsec / 1000000;
}

/* stdin closed: give queued output (e.g. a last neutral go()) a moment to reach the line. */
static void flush_and_exit(void)
{
    long long deadline = now_ms() + FLUSH_ON_EXIT_MS;
    while (out_len > 0) {
        struct pollfd p = {line_fd, POLLOUT, 0};
        long long left = deadline - now_ms();
        if (left <= 0 || poll(&p, 1, (int)left) <= 0 || (p.revents & (POLLERR | POLLHUP)))
            break;
        drain_queue();
    }
    exit(EXIT_STDIN_CLOSED);
}

static void read_stdin(void)
{
    ssize_t n;
    size_t pos = 0;
    do {
        n = read(STDIN_FILENO, in_buf + in_len, sizeof in_buf - in_len);
    } while (n < 0 && errno == EINTR);
    if (n == 0)
        flush_and_exit();
    if (n < 0)
        fail(EXIT_STDIO, "read stdin: %s", strerror(errno));
    in_len += (size_t)n;

    while (in_len - pos >= 2) {
        size_t frame_len = ((size_t)in_buf[pos] << 8) | in_buf[pos + 1];
        if (in_len - pos < 2 + frame_len)
            break;
        dispatch(in_buf + pos + 2, frame_len);
        pos += 2 + frame_len;
    }
    memmove(in_buf, in_buf + pos, in_len - pos);
    in_len -= pos;
}

/* Killed (not closed): still remove the pty link, so nobody opens a reused /dev/pts/N. */
static void on_signal(int sig)
{
    remove_link();
    _exit(128 + sig);
}

/* NEPTUNUS_SLICE_NS: a short time slice for this program (Neptunus.OS says why). Best effort:
 * kernels before 6.12 ignore it, and nothing depends on it. */
static void request_time_slice(void)
{
    struct {
        uint32_t size, policy;
        uint64_t flags;
        int32_t nice;
        uint32_t priority;
        uint64_t runtime, deadline, period;
        uint32_t util_min, util_max;
    } attr;
    const char *value = getenv("NEPTUNUS_SLICE_NS");
    char *end;
    unsigned long long ns;

    if (value == NULL || *value == '\0')
        return;
    ns = strtoull(value, &end, 10);
    if (*end != '\0' || ns < 100000ULL || ns > 100000000ULL)
        return;
    memset(&attr, 0, sizeof attr);
    if (syscall(SYS_sched_getattr, 0, &attr, (unsigned int)sizeof attr, 0U) != 0)
        return;
    if (attr.policy != SCHED_OTHER && attr.policy != SCHED_BATCH)
        return;
    attr.size = sizeof attr;
    attr.flags = 0;
    attr.runtime = ns;
    attr.deadline = 0;
    attr.period = 0;
    (void)syscall(SYS_sched_setattr, 0, &attr, 0U);
}

int main(int argc, char **argv)
{
    const char *stamps = getenv("NEPTUNUS_UART_RX_STAMPS");
    rx_stamps = stamps != NULL && strcmp(stamps, "1") == 0;
    request_time_slice();
    signal(SIGPIPE, SIG_IGN);
    signal(SIGTERM, on_signal);
    signal(SIGINT, on_signal);
    signal(SIGHUP, on_signal);

    if (argc == 4 && strcmp(argv[1], "tty") == 0) {
        open_tty(argv[2], argv[3]);
    } else if (argc == 3 && strcmp(argv[1], "pty") == 0) {
        open_pty(argv[2]);
    } else {
        if (isatty(STDOUT_FILENO)) /* run by hand */
            fprintf(stderr, "usage: neptunus_uart tty DEVICE BAUD | neptunus_uart pty LINK\n");
        fail(EXIT_USAGE, "usage: neptunus_uart tty DEVICE BAUD | pty LINK");
    }

    for (;;) {
        struct pollfd fds[3];
        fds[0].fd = STDIN_FILENO;
        fds[0].events = POLLIN;
        fds[0].revents = 0;
        fds[1].fd = line_fd;
        fds[1].events = (short)(POLLIN | (out_len > 0 ? POLLOUT : 0));
        fds[1].revents = 0;
        fds[2].fd = open_watch_fd; /* -1 (ignored by poll) unless in pty mode */
        fds[2].events = POLLIN;
        fds[2].revents = 0;

        if (poll(fds, 3, -1) < 0) {
            if (errno == EINTR)
                continue;
            fail(EXIT_IO, "poll: %s", strerror(errno));
        }
        if (fds[0].revents & (POLLIN | POLLHUP | POLLERR))
            read_stdin();
        /* an open is reported before the bytes the opener then writes: the event is queued
         * by open() itself, before any write could be made */
        if (fds[2].revents & POLLIN)
            read_open_watch();
        if (fds[1].revents & POLLIN)
            read_line_fd(); /* a hangup with data pending reads the data first, then EOF */
        else if (fds[1].revents & (POLLHUP | POLLERR | POLLNVAL))
            fail(EXIT_HANGUP, "hangup: the line was closed or unplugged");
        if (fds[1].revents & POLLOUT)
            drain_queue();
    }
}
