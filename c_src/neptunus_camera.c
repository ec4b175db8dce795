/*
 * neptunus_camera - Erlang port program for one vehicle camera.
 *
 *   neptunus_camera run [--linger] -- PROGRAM [ARGS...]
 *       runs PROGRAM (ffmpeg on a V4L2 device or an RTSP URL, an exec: source) and passes
 *       its standard output on ('d' messages) and its error output line by line ('e').
 *   neptunus_camera sim WIDTH HEIGHT FPS BOTTOM -- PROGRAM [ARGS...]
 *       renders the simulated camera's view, WIDTHxHEIGHT at FPS frames a second, of a
 *       seabed BOTTOM metres deep, from the vehicle pose the VM sends ('p'), and writes
 *       each picture (raw YUV 4:2:0) to PROGRAM's standard input (ffmpeg, which encodes it);
 *       PROGRAM's output is passed on as in `run`.
 *
 * Started by Erlang with open_port({spawn_executable, ...}, [{packet, 4}, binary,
 * exit_status]). Every message in either direction is a {packet, 4} frame (4-byte big-endian
 * length) whose first byte is a tag:
 *
 *   VM -> program   'p' 15 doubles (big-endian IEEE 754): x y z (m, NED) phi theta psi (rad)
 *                       u v w (m/s, body) p q r (rad/s) lights laser (0..1) tilt (rad, up > 0)
 *                   'a' N    the VM has handled N more bytes of 'd' messages (uint32)
 *                   's' ask for counters; answered with 's'
 *   program -> VM   'd' DATA    bytes of PROGRAM's standard output
 *                   'e' TEXT    a line of PROGRAM's error output (or of this program's)
 *                   't' INDEX TIME   picture INDEX (uint32, from 0: the pictures given to
 *                               PROGRAM) was rendered at TIME (uint64, wall-clock µs)
 *                   's' TEXT    "rendered=N skipped=N render_us=N cpu_us=N" (sim): pictures
 *                               rendered, deadlines skipped, the mean CPU time of a picture's
 *                               rendering and this program's CPU time in all
 *                   'x' CODE    PROGRAM ended; this program exits with CODE (uint8) next.
 *                               Said first, since the VM may never see the exit status: a
 *                               message it writes as this program ends (an 'a') fails with
 *                               EPIPE and closes the port without one, and without
 *                               what it had not read yet. With `run --linger` this
 *                               program then waits for the VM to close its end, so the
 *                               VM reads everything (the dive export, which acknowledges
 *                               every 'd', uses it).
 *
 * Flow control: at most CREDIT bytes of 'd' messages are unacknowledged ('a'); beyond that the
 * program's output is not read until the VM catches up, so a program that floods its output
 * (garbage at the pipe's speed) waits in its pipe instead of filling the VM's memory.
 *
 * The picture: water whose colour and light fade with depth (red first) and whose
 * visibility shrinks with depth; a textured seabed at BOTTOM, seen from the vehicle's
 * position and attitude with the camera tilted; the vehicle's lights brightening what is
 * near; the two laser dots where the beams meet the seabed; marine snow drifting in the
 * water (parallax shows motion); the water surface above. In the top-left corner the render
 * time: 48 blocks of 8x8 pixels, bit 47 first, white for 1, of the wall-clock milliseconds
 * since the Unix epoch modulo 2^48; the row of blocks below it holds the inverted code.
 * Between two poses the pose is extrapolated from the velocities (at most 0.25 s).
 *
 * A picture is rendered at each frame deadline (absolute, on CLOCK_MONOTONIC) unless
 * PROGRAM has not taken the previous one yet: then the deadline is skipped (counted), so a
 * slow encoder gets fewer pictures, never a queue.
 *
 * It exits when its standard input closes (the VM closed the port or died), ending PROGRAM
 * (SIGTERM, then SIGKILL after 1 s); when PROGRAM ends, with PROGRAM's exit status (128 + the
 * signal if a signal ended it), after passing on the rest of its output. 64: usage error;
 * 70: the VM's pipes failed; 71: PROGRAM could not be started.
 *
 * Built by `mix compile` (Mix.Tasks.Compile.PortPrograms in mix.exs) into priv/.
 */
#define _DEFAULT_SOURCE
#define _POSIX_C_SOURCE 200809L

#include <errno.h>
#include <fcntl.h>
#include <math.h>
#include <poll.h>
#include <signal.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/types.h>
#include <sys/wait.h>
#include <time.h>
#include <unistd.h>
#ifdef __linux__
#include <sys/prctl.h>
#endif

#define EXIT_USAGE 64
#define EXIT_VM_IO 70
#define EXIT_START 71

#define PI_F 3.14159265f
#define CREDIT (4u << 20)
#define MAX_LINE 1000
#define IN_MAX 4096

/* ---------------------------------------------------------------- messages to the VM */

static int write_all(int fd, const void *buf, size_t len)
{
    const uint8_t *p = buf;
    while (len > 0) {
        ssize_t n = write(fd, p, len);
        if (n < 0) {
            if (errno == EINTR)
                continue;
            return -1;
        }
        p += n;
        len -= (size_t)n;
    }
    return 0;
}

static pid_t child = -1;

static void stop_child(void);

static void send_msg(char tag, const void *data, size_t len)
{
    uint8_t head[5];
    uint32_t n = (uint32_t)len + 1;
    head[0] = (uint8_t)(n >> 24);
    head[1] = (uint8_t)(n >> 16);
    head[2] = (uint8_t)(n >> 8);
    head[3] = (uint8_t)n;
    head[4] = (uint8_t)tag;
    if (write_all(1, head, 5) < 0 || (len > 0 && write_all(1, data, len) < 0)) {
        stop_child();
        exit(EXIT_VM_IO);
    }
}

static void send_text(char tag, const char *text) { send_msg(tag, text, strlen(text)); }

/* ---------------------------------------------------------------- the program we run */

static int child_out = -1, child_err = -1, child_in = -1;
static int linger = 0;        /* run --linger: after PROGRAM's end, wait for the VM to close */
static uint32_t unacked = 0; /* bytes of 'd' messages the VM has not acknowledged */

static void stop_child(void)
{
    if (child <= 0)
        return;
    kill(child, SIGTERM);
    for (int i = 0; i < 100; i++) {
        if (waitpid(child, NULL, WNOHANG) == child) {
            child = -1;
            return;
        }
        struct timespec ts = {0, 10000000};
        nanosleep(&ts, NULL);
    }
    kill(child, SIGKILL);
    waitpid(child, NULL, 0);
    child = -1;
}

static void set_nonblock(int fd) { fcntl(fd, F_SETFL, fcntl(fd, F_GETFL) | O_NONBLOCK); }

/* Starts argv[0] with its output and error output on pipes; with_input: its input too. */
static int start_child(char **argv, int with_input)
{
    int out[2], err[2], in[2] = {-1, -1};
    if (pipe(out) < 0 || pipe(err) < 0 || (with_input && pipe(in) < 0))
        return -1;
    child = fork();
    if (child < 0)
        return -1;
    if (child == 0) {
#ifdef __linux__
        prctl(PR_SET_PDEATHSIG, SIGTERM);
#endif
        signal(SIGPIPE, SIG_DFL);
        if (with_input) {
            dup2(in[0], 0);
        } else {
            int null = open("/dev/null", O_RDONLY);
            if (null >= 0)
                dup2(null, 0);
        }
        dup2(out[1], 1);
        dup2(err[1], 2);
        for (int fd = 3; fd < 256; fd++)
            close(fd);
        execv(argv[0], argv);
        dprintf(2, "cannot start %s: %s\n", argv[0], strerror(errno));
        _exit(127);
    }
    close(out[1]);
    close(err[1]);
    child_out = out[0];
    child_err = err[0];
    set_nonblock(child_out);
    set_nonblock(child_err);
    if (with_input) {
        close(in[0]);
        child_in = in[1];
        set_nonblock(child_in);
    }
    return 0;
}

static char err_line[MAX_LINE + 1];
static size_t err_len = 0;

/* Passes the program's error output on, a line at a time (long lines cut). */
static int pass_errors(void)
{
    char buf[4096];
    ssize_t n = read(child_err, buf, sizeof buf);
    if (n <= 0)
        return (n < 0 && (errno == EAGAIN || errno == EINTR)) ? 0 : -1;
    for (ssize_t i = 0; i < n; i++) {
        char c = buf[i];
        if (c == '\n' || c == '\r' || err_len == MAX_LINE) {
            if (err_len > 0) {
                err_line[err_len] = 0;
                send_text('e', err_line);
            }
            err_len = 0;
            if (c == '\n' || c == '\r')
                continue;
        }
        err_line[err_len++] = c;
    }
    return 0;
}

/* Passes the program's output on; -1 at its end. */
static int pass_output(void)
{
    static uint8_t buf[65536];
    ssize_t n = read(child_out, buf, sizeof buf);
    if (n > 0) {
        send_msg('d', buf, (size_t)n);
        unacked += (uint32_t)n;
        return 0;
    }
    if (n < 0 && (errno == EAGAIN || errno == EINTR))
        return 0;
    return -1;
}

/* The program closed its output: the rest of its errors, then its exit status. */
static void finish(void)
{
    struct pollfd pfd = {child_err, POLLIN, 0};
    while (child_err >= 0 && poll(&pfd, 1, 200) > 0 && pass_errors() == 0)
        ;
    if (err_len > 0) {
        err_line[err_len] = 0;
        send_text('e', err_line);
    }
    int status = 0;
    for (int i = 0; i < 200; i++) {
        if (waitpid(child, &status, WNOHANG) == child) {
            child = -1;
            break;
        }
        struct timespec ts = {0, 10000000};
        nanosleep(&ts, NULL);
    }
    if (child > 0) {
        /* closed its output but goes on: a camera that stops sending is over */
        kill(child, SIGKILL);
        waitpid(child, &status, 0);
        child = -1;
    }
    uint8_t code = WIFEXITED(status) ? (uint8_t)WEXITSTATUS(status)
                                     : (uint8_t)(WIFSIGNALED(status) ? 128 + WTERMSIG(status) : 1);
    send_msg('x', &code, 1);
    if (linger) {
        /* until the VM closes its end: what it writes meanwhile (an 'a') must not fail, as a
           failed write closes the port before the VM has read what was said above */
        uint8_t sink[4096];
        for (;;) {
            struct pollfd in = {0, POLLIN, 0};
            if (poll(&in, 1, -1) < 0 && errno != EINTR)
                break;
            ssize_t r = read(0, sink, sizeof sink);
            if (r == 0 || (r < 0 && errno != EAGAIN && errno != EINTR))
                break;
        }
    }
    exit(code);
}

/* ---------------------------------------------------------------- the simulated view */

typedef struct {
    float x, y, z, phi, theta, psi, u, v, w, p, q, r, lights, laser, tilt;
} pose_t;

#define TEX_BITS 10
#define TEX_SIZE (1 << TEX_BITS)
#define TEX_LEVELS 7
#define TEX_PER_M 128.0f /* texels per metre at level 0: the texture repeats every 8 m */
#define BIG_SIZE 64      /* a coarser pattern over 64 m, against visible repetition */
#define SNOW 300
#define SNOW_BOX 6.0f
#define FOG_STEPS 2048
#define FOG_STEP 0.04f /* m: the fog table reaches 82 m */

static int W, H, FPS;
static float BOTTOM;
static float focal;
static uint8_t *tex[TEX_LEVELS]; /* seabed albedo, 0..255, mipmapped */
static uint8_t big[BIG_SIZE * BIG_SIZE];
static float snow[SNOW][3];
static float fog[FOG_STEPS];
static pose_t pose = {0, 0, 1.0f, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0, 0};
static double pose_at = 0; /* monotonic s when the pose arrived */
static uint8_t *frame;
static size_t frame_size;
static unsigned long rendered = 0, skipped = 0;
static double render_total_us = 0;

static uint32_t rng = 0x2545F491u;
static uint32_t next_random(void)
{
    rng ^= rng << 13;
    rng ^= rng >> 17;
    rng ^= rng << 5;
    return rng;
}
static float frand(void) { return (float)(next_random() & 0xFFFFFF) / (float)0x1000000; }

/* value noise on a lattice of `cell` texels, wrapping at TEX_SIZE */
#define LATTICE 256
static float lattice[LATTICE * LATTICE];
static float noise(int x, int y, int cell)
{
    int n = TEX_SIZE / cell; /* lattice points per side, <= LATTICE */
    int x0 = x / cell, y0 = y / cell;
    float fx = (float)(x % cell) / (float)cell, fy = (float)(y % cell) / (float)cell;
    fx = fx * fx * (3 - 2 * fx);
    fy = fy * fy * (3 - 2 * fy);
    float a = lattice[(y0 % n) * LATTICE + x0 % n], b = lattice[(y0 % n) * LATTICE + (x0 + 1) % n];
    float c = lattice[((y0 + 1) % n) * LATTICE + x0 % n],
          d = lattice[((y0 + 1) % n) * LATTICE + (x0 + 1) % n];
    return (a + (b - a) * fx) * (1 - fy) + (c + (d - c) * fx) * fy;
}

static void make_textures(void)
{
    static float acc[TEX_SIZE * TEX_SIZE];
    memset(acc, 0, sizeof acc);
    float amp = 0.5f;
    for (int cell = 256; cell >= 4; cell /= 2, amp *= 0.55f) {
        for (int i = 0; i < LATTICE * LATTICE; i++)
            lattice[i] = frand();
        for (int y = 0; y < TEX_SIZE; y++)
            for (int x = 0; x < TEX_SIZE; x++)
                acc[y * TEX_SIZE + x] += amp * noise(x, y, cell);
    }
    /* stones: a finer noise of their own, above a threshold */
    static float stones[TEX_SIZE * TEX_SIZE];
    memset(stones, 0, sizeof stones);
    for (int i = 0; i < LATTICE * LATTICE; i++)
        lattice[i] = frand();
    for (int y = 0; y < TEX_SIZE; y++)
        for (int x = 0; x < TEX_SIZE; x++)
            stones[y * TEX_SIZE + x] = 0.7f * noise(x, y, 32) + 0.3f * noise(x, y, 8);
    tex[0] = malloc(TEX_SIZE * TEX_SIZE);
    for (int y = 0; y < TEX_SIZE; y++) {
        for (int x = 0; x < TEX_SIZE; x++) {
            float v = acc[y * TEX_SIZE + x];
            /* sand ripples (a whole number of them across the tile, which repeats) */
            float phase = (float)(20 * x + 7 * y) * 2 * PI_F / (float)TEX_SIZE;
            float ripple = 0.07f * sinf(phase + 4 * v) * (0.5f + v);
            float shade = 0.62f + 0.7f * (v - 0.5f) + ripple;
            float stone = stones[y * TEX_SIZE + x];
            if (stone > 0.74f)
                shade = 0.25f + 1.5f * (stone - 0.74f) + 0.3f * (v - 0.5f);
            if (shade < 0.05f)
                shade = 0.05f;
            if (shade > 1)
                shade = 1;
            tex[0][y * TEX_SIZE + x] = (uint8_t)(255 * shade);
        }
    }
    for (int l = 1; l < TEX_LEVELS; l++) {
        int n = TEX_SIZE >> l;
        tex[l] = malloc((size_t)n * n);
        for (int y = 0; y < n; y++)
            for (int x = 0; x < n; x++) {
                const uint8_t *s = tex[l - 1];
                int m = n * 2;
                tex[l][y * n + x] = (uint8_t)((s[2 * y * m + 2 * x] + s[2 * y * m + 2 * x + 1] +
                                               s[(2 * y + 1) * m + 2 * x] +
                                               s[(2 * y + 1) * m + 2 * x + 1] + 2) / 4);
            }
    }
    for (int i = 0; i < BIG_SIZE * BIG_SIZE; i++)
        big[i] = (uint8_t)(150 + 105 * frand());
    for (int i = 0; i < SNOW; i++)
        for (int k = 0; k < 3; k++)
            snow[i][k] = SNOW_BOX * frand();
}

static double cpu_s(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_PROCESS_CPUTIME_ID, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static double now_mono(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_MONOTONIC, &ts);
    return (double)ts.tv_sec + (double)ts.tv_nsec * 1e-9;
}

static uint64_t now_wall_us(void)
{
    struct timespec ts;
    clock_gettime(CLOCK_REALTIME, &ts);
    return (uint64_t)ts.tv_sec * 1000000u + (uint64_t)ts.tv_nsec / 1000u;
}

static uint8_t clamp8(float v) { return v < 0 ? 0 : v > 255 ? 255 : (uint8_t)v; }

/* 1/sqrt(x) for x > 0, to about 0.2 %: the bit trick and one Newton step (shading needs no
   more, and it spares the pixel loop a square root and a division) */
static float rsqrt(float x)
{
    uint32_t i;
    float y;
    memcpy(&i, &x, 4);
    i = 0x5f3759df - (i >> 1);
    memcpy(&y, &i, 4);
    return y * (1.5f - 0.5f * x * y * y);
}

/* Draws a disc of luma y and chroma (u, v) blended by alpha (0..1) at (cx, cy). */
static void disc(float cx, float cy, float radius, float y, float u, float v, float alpha)
{
    uint8_t *Y = frame, *U = frame + W * H, *V = U + (W / 2) * (H / 2);
    int x0 = (int)(cx - radius), x1 = (int)(cx + radius + 1), y0 = (int)(cy - radius),
        y1 = (int)(cy + radius + 1);
    if (x0 < 0)
        x0 = 0;
    if (y0 < 0)
        y0 = 0;
    if (x1 > W)
        x1 = W;
    if (y1 > H)
        y1 = H;
    float r2 = radius * radius;
    for (int j = y0; j < y1; j++)
        for (int i = x0; i < x1; i++) {
            float dx = (float)i + 0.5f - cx, dy = (float)j + 0.5f - cy;
            float d2 = dx * dx + dy * dy;
            if (d2 > r2 + radius)
                continue;
            float a = d2 > r2 ? alpha * 0.4f : alpha;
            uint8_t *py = &Y[j * W + i];
            *py = clamp8(*py + (y - *py) * a);
            if (((i | j) & 1) == 0) {
                uint8_t *pu = &U[(j / 2) * (W / 2) + i / 2], *pv = &V[(j / 2) * (W / 2) + i / 2];
                *pu = clamp8(*pu + (u - *pu) * a);
                *pv = clamp8(*pv + (v - *pv) * a);
            }
        }
}

static void render(uint64_t wall_ms)
{
    /* the pose now: the last one moved on by its velocities */
    double age = now_mono() - pose_at;
    float dt = pose_at == 0 ? 0 : (float)(age > 0.25 ? 0.25 : age);
    pose_t s = pose;
    float cf = cosf(s.phi), sf = sinf(s.phi), ct = cosf(s.theta), st = sinf(s.theta),
          cp = cosf(s.psi), sp = sinf(s.psi);
    /* body to NED (ZYX) */
    float R[3][3] = {{cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf},
                     {sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf},
                     {-st, ct * sf, ct * cf}};
    s.x += (R[0][0] * s.u + R[0][1] * s.v + R[0][2] * s.w) * dt;
    s.y += (R[1][0] * s.u + R[1][1] * s.v + R[1][2] * s.w) * dt;
    s.z += (R[2][0] * s.u + R[2][1] * s.v + R[2][2] * s.w) * dt;
    s.phi += s.p * dt;
    s.theta += s.q * dt;
    s.psi += s.r * dt;
    cf = cosf(s.phi), sf = sinf(s.phi), ct = cosf(s.theta), st = sinf(s.theta),
    cp = cosf(s.psi), sp = sinf(s.psi);
    float B[3][3] = {{cp * ct, cp * st * sf - sp * cf, cp * st * cf + sp * sf},
                     {sp * ct, sp * st * sf + cp * cf, sp * st * cf - cp * sf},
                     {-st, ct * sf, ct * cf}};
    /* the camera: the body tilted about its y axis (up for tilt > 0) */
    float ca = cosf(s.tilt), sa = sinf(s.tilt);
    float M[3][3];
    for (int i = 0; i < 3; i++) {
        M[i][0] = B[i][0] * ca - B[i][2] * sa;
        M[i][1] = B[i][1];
        M[i][2] = B[i][0] * sa + B[i][2] * ca;
    }
    float z = s.z < 0.02f ? 0.02f : s.z;
    if (z > BOTTOM - 0.05f)
        z = BOTTOM - 0.05f;
    float lights = s.lights < 0 ? 0 : s.lights > 1 ? 1 : s.lights;

    /* the water at this depth: light from above fades, red first; visibility shrinks */
    float amb = expf(-z / 25.0f);
    float wr = 0.10f * amb * expf(-z / 6.0f), wg = 0.42f * amb, wb = 0.48f * amb;
    float c = 0.12f + 0.005f * z;
    for (int i = 0; i < FOG_STEPS; i++)
        fog[i] = expf(-c * (float)i * FOG_STEP);
    float max_dist = (float)(FOG_STEPS - 1) * FOG_STEP;
    /* light reaching the seabed from above, by colour */
    float ar = 1.6f * expf(-BOTTOM / 25.0f) * expf(-BOTTOM / 8.0f),
          ag = 1.6f * expf(-BOTTOM / 25.0f), ab = 1.4f * expf(-BOTTOM / 25.0f);
    float sand_r = 0.80f, sand_g = 0.72f, sand_b = 0.52f;
    float surf = 0.8f; /* the surface's brightness seen from below, before fog */

    /* the ray through pixel (i, j) is base + i*di + j*dj (world frame, not normalised) */
    float di[3], dj[3], base[3];
    for (int k = 0; k < 3; k++) {
        di[k] = M[k][1] / focal;
        dj[k] = M[k][2] / focal;
        base[k] = M[k][0] + (0.5f - (float)W / 2) * di[k] + (0.5f - (float)H / 2) * dj[k];
    }
    /* seabed texture coordinates relative to the camera, the camera's own split off into
       whole texels (kept small so floats stay exact) */
    double tx = s.x * TEX_PER_M, ty = s.y * TEX_PER_M;
    long tx_int = (long)floor(tx), ty_int = (long)floor(ty);
    float tx_frac = (float)(tx - (double)tx_int), ty_frac = (float)(ty - (double)ty_int);
    const float offset = 65536.0f; /* keeps texel coordinates positive before truncation */
    float lod_scale = TEX_PER_M / focal;

    uint8_t *Y = frame, *U = frame + W * H, *V = U + (W / 2) * (H / 2);
    for (int j = 0; j < H; j++) {
        float rx = base[0] + (float)j * dj[0], ry = base[1] + (float)j * dj[1],
              rz = base[2] + (float)j * dj[2];
        for (int i = 0; i < W; i++, rx += di[0], ry += di[1], rz += di[2]) {
            float len2 = rx * rx + ry * ry + rz * rz;
            float cone = rsqrt(len2); /* cosine of the angle off the camera's axis */
            float len = len2 * cone;
            float up = -rz * cone;
            float r, g, b;
            /* the water itself, brighter towards the surface, lit by the lights near */
            float glow = lights * 0.25f * cone * cone * cone * cone;
            float w_r = wr * (0.7f + 0.5f * up) + glow * 0.5f,
                  w_g = wg * (0.7f + 0.5f * up) + glow * 0.8f,
                  w_b = wb * (0.7f + 0.5f * up) + glow * 0.8f;
            float t = -1, dist = max_dist, inv_rz = 0;
            int seabed = 0;
            if (rz > 1e-4f) {
                inv_rz = 1.0f / rz;
                t = (BOTTOM - z) * inv_rz;
                seabed = 1;
            } else if (rz < -1e-4f) {
                t = -z / rz;
            }
            if (t > 0)
                dist = t * len;
            if (t <= 0 || dist >= max_dist) {
                r = w_r, g = w_g, b = w_b;
            } else {
                float f = fog[(int)(dist * (1.0f / FOG_STEP))];
                float sr, sg, sb;
                if (seabed) {
                    float hx = t * rx, hy = t * ry; /* from the camera, m */
                    float fp = t * len2 * lod_scale * inv_rz;
                    int ifp = fp > 1e6f ? 1000000 : (int)fp, lod = 0;
                    while (ifp > 1 && lod < TEX_LEVELS - 1) {
                        ifp >>= 1;
                        lod++;
                    }
                    int mask = (TEX_SIZE >> lod) - 1;
                    int u = (int)(hx * TEX_PER_M + tx_frac + offset) + (int)(tx_int & 0xFFFF);
                    int v = (int)(hy * TEX_PER_M + ty_frac + offset) + (int)(ty_int & 0xFFFF);
                    /* the coarse pattern, bilinear: cells of TEX_SIZE texels (8 m) */
                    int bu = u >> (TEX_BITS - 6), bv = v >> (TEX_BITS - 6);
                    int cu = (bu >> 6) & (BIG_SIZE - 1), cv = (bv >> 6) & (BIG_SIZE - 1);
                    int cu1 = (cu + 1) & (BIG_SIZE - 1), cv1 = (cv + 1) & (BIG_SIZE - 1);
                    int fu = bu & 63, fv = bv & 63;
                    int top = big[cv * BIG_SIZE + cu] * (64 - fu) + big[cv * BIG_SIZE + cu1] * fu;
                    int bot = big[cv1 * BIG_SIZE + cu] * (64 - fu) + big[cv1 * BIG_SIZE + cu1] * fu;
                    float coarse = (float)(top * (64 - fv) + bot * fv);
                    float albedo = (float)tex[lod][((v >> lod) & mask) * (TEX_SIZE >> lod) +
                                                   ((u >> lod) & mask)] *
                                   coarse * (1.0f / (255.0f * 255.0f * 4096.0f));
                    float lamp = lights * 3.0f * cone * cone * cone / (0.3f + 0.12f * dist * dist);
                    sr = albedo * sand_r * (ar + lamp);
                    sg = albedo * sand_g * (ag + lamp);
                    sb = albedo * sand_b * (ab + lamp);
                } else {
                    /* the surface: brighter where the texture (read as waves) is */
                    int u = (int)(t * rx * 16 + offset), v = (int)(t * ry * 16 + offset);
                    float wave = 0.6f + (float)tex[3][((v >> 3) & 127) * 128 + ((u >> 3) & 127)] *
                                            (0.8f / 255.0f);
                    sr = surf * amb * 0.7f * wave, sg = surf * amb * wave, sb = surf * amb * wave;
                }
                r = sr * f + w_r * (1 - f);
                g = sg * f + w_g * (1 - f);
                b = sb * f + w_b * (1 - f);
            }
            Y[j * W + i] = clamp8(16.0f + 65.481f * r + 128.553f * g + 24.966f * b);
            if (((i | j) & 1) == 0) {
                U[(j / 2) * (W / 2) + i / 2] = clamp8(128.0f - 37.797f * r - 74.203f * g + 112.0f * b);
                V[(j / 2) * (W / 2) + i / 2] = clamp8(128.0f + 112.0f * r - 93.786f * g - 18.214f * b);
            }
        }
    }

    /* marine snow: particles in a box around the camera, drifting down slowly */
    float sink = (float)fmod(now_mono() * 0.03, SNOW_BOX);
    float half = SNOW_BOX / 2;
    for (int k = 0; k < SNOW; k++) {
        float rel[3] = {snow[k][0] - s.x, snow[k][1] - s.y, snow[k][2] + sink - z};
        for (int a = 0; a < 3; a++) {
            rel[a] = fmodf(rel[a] + half, SNOW_BOX);
            if (rel[a] < 0)
                rel[a] += SNOW_BOX;
            rel[a] -= half;
        }
        float cx = M[0][0] * rel[0] + M[1][0] * rel[1] + M[2][0] * rel[2];
        if (cx < 0.15f)
            continue;
        float cy = M[0][1] * rel[0] + M[1][1] * rel[1] + M[2][1] * rel[2];
        float cz = M[0][2] * rel[0] + M[1][2] * rel[1] + M[2][2] * rel[2];
        float px = (float)W / 2 + focal * cy / cx, py = (float)H / 2 + focal * cz / cx;
        if (px < -8 || py < -8 || px > (float)W + 8 || py > (float)H + 8)
            continue;
        float dist = sqrtf(cx * cx + cy * cy + cz * cz);
        float lit = amb * 0.35f + lights * 1.5f / (1.0f + dist * dist);
        float a = lit * expf(-c * dist);
        if (a < 0.02f)
            continue;
        float radius = 0.008f * focal / cx;
        disc(px, py, radius < 0.7f ? 0.7f : radius > 5 ? 5 : radius, 200, 128, 128,
             a > 0.9f ? 0.9f : a);
    }

    /* the lasers: two beams 10 cm apart along the camera's axis, red dots on the seabed */
    if (s.laser > 0 && M[2][0] > 0.01f) {
        for (int side = -1; side <= 1; side += 2) {
            float oz = z + 0.05f * (float)side * M[2][1];
            float along = (BOTTOM - oz) / M[2][0];
            float rel[3];
            for (int a = 0; a < 3; a++)
                rel[a] = 0.05f * (float)side * M[a][1] + along * M[a][0];
            float cx = M[0][0] * rel[0] + M[1][0] * rel[1] + M[2][0] * rel[2];
            float cy = M[0][1] * rel[0] + M[1][1] * rel[1] + M[2][1] * rel[2];
            float cz = M[0][2] * rel[0] + M[1][2] * rel[1] + M[2][2] * rel[2];
            float a = (s.laser > 1 ? 1 : s.laser) * expf(-c * 2 * along);
            if (cx > 0.1f && a > 0.02f)
                disc((float)W / 2 + focal * cy / cx, (float)H / 2 + focal * cz / cx,
                     2.0f + 0.004f * (float)W, 110, 90, 240, a > 1 ? 1 : a);
        }
    }

    /* the render time, bit 47 first: the code, and below it the inverted code */
    for (int k = 0; k < 48; k++) {
        int bit = (int)((wall_ms >> (47 - k)) & 1);
        for (int j = 0; j < 16; j++) {
            uint8_t level = (uint8_t)(((j < 8) ? bit : !bit) ? 235 : 16);
            memset(&Y[j * W + k * 8], level, 8);
        }
    }
    for (int j = 0; j < 8; j++) {
        memset(&U[j * (W / 2)], 128, 48 * 4);
        memset(&V[j * (W / 2)], 128, 48 * 4);
    }
}

static double be_double(const uint8_t *p)
{
    uint64_t bits = 0;
    for (int i = 0; i < 8; i++)
        bits = (bits << 8) | p[i];
    double d;
    memcpy(&d, &bits, sizeof d);
    return d;
}

/* ---------------------------------------------------------------- messages from the VM */

static uint8_t in_buf[IN_MAX];
static size_t in_len = 0;

static void handle(const uint8_t *msg, size_t len)
{
    if (len == 0)
        return;
    if (msg[0] == 'p' && len >= 1 + 15 * 8) {
        float v[15];
        for (int i = 0; i < 15; i++)
            v[i] = (float)be_double(msg + 1 + 8 * i);
        pose = (pose_t){v[0], v[1], v[2], v[3], v[4], v[5], v[6], v[7],
                        v[8], v[9], v[10], v[11], v[12], v[13], v[14]};
        pose_at = now_mono();
    } else if (msg[0] == 'a' && len >= 5) {
        uint32_t n = ((uint32_t)msg[1] << 24) | ((uint32_t)msg[2] << 16) | ((uint32_t)msg[3] << 8) | msg[4];
        unacked = n > unacked ? 0 : unacked - n;
    } else if (msg[0] == 's') {
        char text[200];
        snprintf(text, sizeof text, "rendered=%lu skipped=%lu render_us=%.0f cpu_us=%.0f", rendered,
                 skipped, rendered ? render_total_us / (double)rendered : 0.0, cpu_s() * 1e6);
        send_text('s', text);
    }
}

/* Reads the VM's messages; -1 when its pipe has closed. */
static int read_vm(void)
{
    ssize_t n = read(0, in_buf + in_len, IN_MAX - in_len);
    if (n == 0)
        return -1;
    if (n < 0)
        return (errno == EINTR || errno == EAGAIN) ? 0 : -1;
    in_len += (size_t)n;
    size_t at = 0;
    while (in_len - at >= 4) {
        uint32_t len = ((uint32_t)in_buf[at] << 24) | ((uint32_t)in_buf[at + 1] << 16) |
                       ((uint32_t)in_buf[at + 2] << 8) | in_buf[at + 3];
        if (len > IN_MAX - 4)
            return -1; /* not our VM */
        if (in_len - at - 4 < len)
            break;
        handle(in_buf + at + 4, len);
        at += 4 + len;
    }
    memmove(in_buf, in_buf + at, in_len - at);
    in_len -= at;
    return 0;
}

/* ---------------------------------------------------------------- main loop */

static int usage(void)
{
    fprintf(stderr, "usage: neptunus_camera run [--linger] -- PROGRAM [ARGS...]\n"
                    "       neptunus_camera sim WIDTH HEIGHT FPS BOTTOM -- PROGRAM [ARGS...]\n");
    return EXIT_USAGE;
}

int main(int argc, char **argv)
{
    int sim = 0, program = 0;
    if (argc >= 4 && strcmp(argv[1], "run") == 0 && strcmp(argv[2], "--") == 0) {
        program = 3;
    } else if (argc >= 5 && strcmp(argv[1], "run") == 0 && strcmp(argv[2], "--linger") == 0 &&
               strcmp(argv[3], "--") == 0) {
        program = 4;
        linger = 1;
    } else if (argc >= 8 && strcmp(argv[1], "sim") == 0 && strcmp(argv[6], "--") == 0) {
        sim = 1;
        program = 7;
        W = atoi(argv[2]);
        H = atoi(argv[3]);
        FPS = atoi(argv[4]);
        BOTTOM = (float)atof(argv[5]);
        if (W < 384 || H < 64 || W > 4096 || H > 4096 || (W | H) & 1 || FPS < 1 || FPS > 60 ||
            !(BOTTOM >= 1.0f))
            return usage();
    } else {
        return usage();
    }
    signal(SIGPIPE, SIG_IGN);

    if (sim) {
        focal = ((float)W / 2) / tanf(40.0f * PI_F / 180.0f); /* 80 degrees across */
        frame_size = (size_t)W * H * 3 / 2;
        frame = malloc(frame_size);
        make_textures();
    }
    if (start_child(argv + program, sim) < 0) {
        char text[300];
        snprintf(text, sizeof text, "cannot start %s: %s", argv[program], strerror(errno));
        send_text('e', text);
        return EXIT_START;
    }

    double period = sim ? 1.0 / FPS : 0, next = now_mono() + period;
    size_t pending = 0; /* bytes of the current picture not yet taken by the program */
    uint32_t index = 0;

    for (;;) {
        struct pollfd fds[4] = {{0, POLLIN, 0},
                                {unacked < CREDIT ? child_out : -1, POLLIN, 0},
                                {child_err, POLLIN, 0},
                                {pending ? child_in : -1, POLLOUT, 0}};
        int timeout = -1;
        if (sim) {
            double wait = next - now_mono();
            timeout = wait <= 0 ? 0 : (int)(wait * 1000) + 1;
        }
        int n = poll(fds, 4, timeout);
        if (n < 0 && errno != EINTR) {
            stop_child();
            return EXIT_VM_IO;
        }
        if (n > 0) {
            if (fds[0].revents & (POLLIN | POLLHUP | POLLERR)) {
                if (read_vm() < 0) {
                    stop_child();
                    return 0;
                }
            }
            if ((fds[2].revents & (POLLIN | POLLHUP | POLLERR)) && pass_errors() < 0) {
                /* its error output closed (its output may go on): stop watching it */
                close(child_err);
                child_err = -1;
            }
            if (fds[1].revents & (POLLIN | POLLHUP | POLLERR)) {
                if (pass_output() < 0)
                    finish();
            }
            if (pending && (fds[3].revents & (POLLOUT | POLLERR | POLLHUP))) {
                ssize_t w = write(child_in, frame + frame_size - pending, pending);
                if (w > 0)
                    pending -= (size_t)w;
                else if (w < 0 && errno != EAGAIN && errno != EINTR)
                    pending = 0; /* the encoder is gone: its output's end tells why */
            }
        }
        if (sim && now_mono() >= next) {
            if (pending) {
                skipped++;
            } else {
                double started = cpu_s();
                uint64_t wall_us = now_wall_us();
                render(wall_us / 1000);
                uint8_t stamp[12];
                for (int i = 0; i < 4; i++)
                    stamp[i] = (uint8_t)(index >> (24 - 8 * i));
                for (int i = 0; i < 8; i++)
                    stamp[4 + i] = (uint8_t)(wall_us >> (56 - 8 * i));
                send_msg('t', stamp, sizeof stamp);
                index++;
                pending = frame_size;
                rendered++;
                render_total_us += (cpu_s() - started) * 1e6;
            }
            next += period;
            /* far behind (the machine stalled): skip the lost deadlines, do not catch up */
            double now = now_mono();
            if (next < now - period) {
                skipped += (unsigned long)((now - next) / period);
                next = now + period;
            }
        }
    }
}
