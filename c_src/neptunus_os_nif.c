/*
 * neptunus_os_nif - asks Linux to wake the VM's threads promptly: a short scheduler time slice.
 *
 * Loaded by Neptunus.OS. Four functions, all run on a dirty I/O scheduler:
 *
 *   set_time_slice(Ns) -> {ok, Threads} | {error, Errno}
 *       For every thread of this OS process (/proc/self/task) under the fair scheduler
 *       (SCHED_OTHER, SCHED_BATCH), requests a time slice of Ns nanoseconds with
 *       sched_setattr(2), keeping its policy and nice value. Ns = 0 gives the kernel's default
 *       back. Threads is how many threads were set. Unprivileged: it changes no priority.
 *
 *   time_slices(OsPid) -> {ok, [{Tid, Ns}]} | {error, Errno}
 *       Each thread of process OsPid (0: this one) and the slice sched_getattr(2) reports for
 *       it (sched_runtime), 0 where the kernel reports none.
 *
 *   get_fd_limit() -> {ok, {Soft, Hard}}
 *       The RLIMIT_NOFILE of this OS process: how many file descriptors it may hold (Soft) and
 *       how far an unprivileged process may raise that (Hard); `infinity` for RLIM_INFINITY.
 *
 *   set_fd_limit() -> {ok, {Before, After}} | {error, Errno}
 *       Raises the soft RLIMIT_NOFILE to the hard one (to /proc/sys/fs/nr_open when the hard
 *       limit is RLIM_INFINITY, which the kernel refuses as a soft value). Unprivileged.
 *       Port programs started afterwards inherit the raised limit.
 *
 * Since Linux 6.12 the EEVDF scheduler takes a fair thread's sched_runtime as its slice
 * request (100 us .. 100 ms) and lets a thread with a shorter slice preempt the running one
 * when it wakes: what a control path wants, whose threads sleep until a command arrives. Older
 * kernels accept the call and ignore the value (their sched_getattr then reports 0):
 * Neptunus.OS reads the slices back to tell which.
 */
#define _GNU_SOURCE
#include <dirent.h>
#include <errno.h>
#include <erl_nif.h>
#include <sched.h>
#include <stdint.h>
#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <sys/resource.h>
#include <sys/syscall.h>
#include <unistd.h>

#define MAX_THREADS 4096

/* struct sched_attr (include/uapi/linux/sched/types.h), version 1: 56 bytes */
struct sched_attr_v1 {
  uint32_t size;
  uint32_t sched_policy;
  uint64_t sched_flags;
  int32_t sched_nice;
  uint32_t sched_priority;
  uint64_t sched_runtime;
  uint64_t sched_deadline;
  uint64_t sched_period;
  uint32_t sched_util_min;
  uint32_t sched_util_max;
};

static ERL_NIF_TERM atom_ok, atom_error, atom_infinity;

static int load(ErlNifEnv *env, void **priv, ERL_NIF_TERM info) {
  (void)priv;
  (void)info;
  atom_ok = enif_make_atom(env, "ok");
  atom_error = enif_make_atom(env, "error");
  atom_infinity = enif_make_atom(env, "infinity");
  return 0;
}

static ERL_NIF_TERM error_errno(ErlNifEnv *env, int err) {
  const char *name;
  switch (err) {
  case EPERM: name = "eperm"; break;
  case ENOSYS: name = "enosys"; break;
  case EINVAL: name = "einval"; break;
  case ESRCH: name = "esrch"; break;
  case ENOENT: name = "enoent"; break;
  case EACCES: name = "eacces"; break;
  case E2BIG: name = "too_many_threads"; break;
  case ENOMEM: name = "enomem"; break;
  default: name = "failed"; break;
  }
  return enif_make_tuple2(env, atom_error, enif_make_atom(env, name));
}

static int get_attr(pid_t tid, struct sched_attr_v1 *attr) {
  memset(attr, 0, sizeof *attr);
  return (int)syscall(SYS_sched_getattr, tid, attr, (unsigned int)sizeof *attr, 0U);
}

/* The thread ids of process pid (0: ourselves); -1 and errno on failure. */
static int list_threads(long pid, pid_t *tids, int max) {
  char path[64];
  DIR *dir;
  struct dirent *entry;
  int n = 0;

  if (pid == 0)
    snprintf(path, sizeof path, "/proc/self/task");
  else
    snprintf(path, sizeof path, "/proc/%ld/task", pid);
  dir = opendir(path);
  if (dir == NULL)
    return -1;
  while ((entry = readdir(dir)) != NULL) {
    char *end;
    long tid = strtol(entry->d_name, &end, 10);
    if (*end != '\0' || tid <= 0)
      continue;
    if (n == max) {
      closedir(dir);
      errno = E2BIG;
      return -1;
    }
    tids[n++] = (pid_t)tid;
  }
  closedir(dir);
  return n;
}

/* Each call lists the threads into its own buffer: two dirty schedulers may run these at once. */
static ERL_NIF_TERM set_time_slice(ErlNifEnv *env, int argc, const ERL_NIF_TERM argv[]) {
  pid_t *tids;
  ErlNifUInt64 ns;
  int n, i, set = 0, err = 0;
  (void)argc;

  if (!enif_get_uint64(env, argv[0], &ns) || (ns != 0 && (ns < 100000 || ns > 100000000)))
    return enif_make_badarg(env);
  tids = enif_alloc(MAX_THREADS * sizeof *tids);
  if (tids == NULL)
    return error_errno(env, ENOMEM);
  n = list_threads(0, tids, MAX_THREADS);
  if (n < 0)
    err = errno;
  for (i = 0; i < n && err == 0; i++) {
    struct sched_attr_v1 attr;
    if (get_attr(tids[i], &attr) != 0) {
      if (errno != ESRCH) /* ESRCH: the thread ended meanwhile */
        err = errno;
      continue;
    }
    if (attr.sched_policy != SCHED_OTHER && attr.sched_policy != SCHED_BATCH)
      continue; /* real-time or idle threads keep what they have */
    attr.size = sizeof attr;
    attr.sched_flags = 0;
    attr.sched_runtime = ns;
    attr.sched_deadline = 0;
    attr.sched_period = 0;
    if (syscall(SYS_sched_setattr, tids[i], &attr, 0U) != 0) {
      if (errno != ESRCH)
        err = errno;
      continue;
    }
    set++;
  }
  enif_free(tids);
  return err ? error_errno(env, err) : enif_make_tuple2(env, atom_ok, enif_make_int(env, set));
}

static ERL_NIF_TERM time_slices(ErlNifEnv *env, int argc, const ERL_NIF_TERM argv[]) {
  pid_t *tids;
  long pid;
  int n, i, err = 0;
  ERL_NIF_TERM list = enif_make_list(env, 0);
  (void)argc;

  if (!enif_get_long(env, argv[0], &pid) || pid < 0)
    return enif_make_badarg(env);
  tids = enif_alloc(MAX_THREADS * sizeof *tids);
  if (tids == NULL)
    return error_errno(env, ENOMEM);
  n = list_threads(pid, tids, MAX_THREADS);
  if (n < 0)
    err = errno;
  for (i = n - 1; i >= 0 && err == 0; i--) {
    struct sched_attr_v1 attr;
    if (get_attr(tids[i], &attr) != 0) {
      if (errno != ESRCH)
        err = errno;
      continue;
    }
    list = enif_make_list_cell(
        env,
        enif_make_tuple2(env, enif_make_int(env, tids[i]), enif_make_uint64(env, attr.sched_runtime)),
        list);
  }
  enif_free(tids);
  return err ? error_errno(env, err) : enif_make_tuple2(env, atom_ok, list);
}

static ERL_NIF_TERM make_rlim(ErlNifEnv *env, rlim_t value) {
  return value == RLIM_INFINITY ? atom_infinity : enif_make_uint64(env, (ErlNifUInt64)value);
}

static ERL_NIF_TERM fd_limit(ErlNifEnv *env, int argc, const ERL_NIF_TERM argv[]) {
  struct rlimit limit;
  (void)argc;
  (void)argv;
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0)
    return error_errno(env, errno);
  return enif_make_tuple2(
      env, atom_ok,
      enif_make_tuple2(env, make_rlim(env, limit.rlim_cur), make_rlim(env, limit.rlim_max)));
}

/* The kernel's ceiling for RLIMIT_NOFILE (fs.nr_open); 0 when it cannot be read. */
static rlim_t nr_open(void) {
  unsigned long long value = 0;
  FILE *file = fopen("/proc/sys/fs/nr_open", "r");
  if (file == NULL)
    return 0;
  if (fscanf(file, "%llu", &value) != 1)
    value = 0;
  fclose(file);
  return (rlim_t)value;
}

static ERL_NIF_TERM raise_fd_limit(ErlNifEnv *env, int argc, const ERL_NIF_TERM argv[]) {
  struct rlimit limit;
  rlim_t before;
  (void)argc;
  (void)argv;
  if (getrlimit(RLIMIT_NOFILE, &limit) != 0)
    return error_errno(env, errno);
  before = limit.rlim_cur;
  if (limit.rlim_cur != limit.rlim_max) {
    rlim_t target = limit.rlim_max;
    if (target == RLIM_INFINITY) {
      target = nr_open();
      if (target == 0 || target <= limit.rlim_cur)
        target = limit.rlim_cur;
    }
    if (target != limit.rlim_cur) {
      limit.rlim_cur = target;
      if (setrlimit(RLIMIT_NOFILE, &limit) != 0)
        return error_errno(env, errno);
    }
  }
  return enif_make_tuple2(
      env, atom_ok, enif_make_tuple2(env, make_rlim(env, before), make_rlim(env, limit.rlim_cur)));
}

static ErlNifFunc funcs[] = {
    {"set_time_slice", 1, set_time_slice, ERL_NIF_DIRTY_JOB_IO_BOUND},
    {"time_slices", 1, time_slices, ERL_NIF_DIRTY_JOB_IO_BOUND},
    {"get_fd_limit", 0, fd_limit, ERL_NIF_DIRTY_JOB_IO_BOUND},
    {"set_fd_limit", 0, raise_fd_limit, ERL_NIF_DIRTY_JOB_IO_BOUND},
};

ERL_NIF_INIT(Elixir.Neptunus.OS, funcs, load, NULL, NULL, NULL)
