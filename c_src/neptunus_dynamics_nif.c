/*
 * neptunus_dynamics_nif - the simulator's inner loop in C, for headless speed.
 *
 * Loaded by Neptunus.Dynamics.Native. One function:
 *
 *   run(Kernel, State, Forces, Targets, Lags, TauExt, Current, Dt, N)
 *     -> {State', Forces'} | {singular, Theta} | badarg
 *
 * It performs N steps of Neptunus.Sim's step (for a constant water current): each thruster's
 * force follows its target with the first-order lag {Decay, Mean}; the mean forces and TauExt
 * give tau; one classical RK4 step of Neptunus.Dynamics' right-hand side; phi and psi wrapped
 * to [-pi, pi); the water surface holds z >= 0.
 *
 * The arithmetic is Neptunus.Dynamics' (lib/neptunus/dynamics.ex) transcribed operation by
 * operation, in the same order, with no fused multiply-add (-ffp-contract=off) and the same
 * libm sin/cos/sqrt/floor the BEAM calls: the results are bit-identical to the Elixir code
 * (test/neptunus/dynamics/native_test.exs checks this). Change both together.
 *
 * Kernel is a binary of native-endian doubles built by Neptunus.Dynamics.Params:
 *   m[36] (Coriolis matrix, zeros when none), m_inv[36], d_l[6], d_q[6], wb, gx, gy, gz,
 *   coriolis (0/1), locked (0/1), tether_k, tether_at[3], n_thrusters, wrench[n][6],
 *   m_abs[36] (|m_inv| entry by entry), arm, tether_gain (the sub-step constants).
 *
 * Each step is split into as many RK4 sub-steps as substeps() (Neptunus.Dynamics'
 * count_substeps/4) says: 1 in ordinary conditions, more where the model is stiff.
 * State is a 12-tuple of floats {x y z phi theta psi u v w p q r}; Forces and Targets are lists
 * of n floats; Lags a list of n {Decay, Mean} tuples; TauExt a 6-tuple; Current a 3-tuple (NED) held for
 * all N steps, or a list of N 3-tuples, the current of each step (a varying current).
 *
 * Pure arithmetic on copies of its arguments: no allocation besides the result, no I/O, no
 * state. Each call reports the time it used (enif_consume_timeslice); callers keep N modest
 * (Neptunus.Sim runs at most 1 000 steps per call, well under a millisecond).
 */
#include <erl_nif.h>
#include <math.h>
#include <string.h>

#define MAX_THRUSTERS 16
#define KERNEL_FIXED 95 /* doubles before the wrenches */
#define TWO_PI (2 * 3.141592653589793)
#define PI 3.141592653589793
#define STIFFNESS_DOUBLES 38 /* m_abs[36], arm, gain after the wrenches */
#define RK4_LIMIT 2.0
#define MAX_SUBSTEPS 1000

typedef struct {
  double m[36], m_inv[36], d_l[6], d_q[6];
  double wb, gx, gy, gz;
  int coriolis, locked;
  double kt, at[3];
  int n;
  double wrench[MAX_THRUSTERS][6];
  double m_abs[36], arm, gain;
} kernel_t;

static double gauss_1, gauss_2;
static ERL_NIF_TERM atom_singular;

static int load(ErlNifEnv *env, void **priv, ERL_NIF_TERM info) {
  (void)priv;
  (void)info;
  gauss_1 = 0.5 - sqrt(3.0) / 6.0;
  gauss_2 = 0.5 + sqrt(3.0) / 6.0;
  atom_singular = enif_make_atom(env, "singular");
  return 0;
}

static int get_kernel(ErlNifEnv *env, ERL_NIF_TERM term, kernel_t *k) {
  ErlNifBinary bin;
  double d[KERNEL_FIXED];
  if (!enif_inspect_binary(env, term, &bin) || bin.size < sizeof d) return 0;
  memcpy(d, bin.data, sizeof d);
  memcpy(k->m, d, sizeof k->m);
  memcpy(k->m_inv, d + 36, sizeof k->m_inv);
  memcpy(k->d_l, d + 72, sizeof k->d_l);
  memcpy(k->d_q, d + 78, sizeof k->d_q);
  k->wb = d[84];
  k->gx = d[85];
  k->gy = d[86];
  k->gz = d[87];
  k->coriolis = d[88] != 0.0;
  k->locked = d[89] != 0.0;
  k->kt = d[90];
  memcpy(k->at, d + 91, sizeof k->at);
  if (!(d[94] >= 0.0 && d[94] <= MAX_THRUSTERS)) return 0;
  k->n = (int)d[94];
  const size_t wrenches = (size_t)k->n * 6 * sizeof(double);
  if (bin.size != sizeof d + wrenches + STIFFNESS_DOUBLES * sizeof(double)) return 0;
  memcpy(k->wrench, bin.data + sizeof d, wrenches);
  double st[STIFFNESS_DOUBLES];
  memcpy(st, bin.data + sizeof d + wrenches, sizeof st);
  memcpy(k->m_abs, st, sizeof k->m_abs);
  k->arm = st[36];
  k->gain = st[37];
  return 1;
}

static int get_number(ErlNifEnv *env, ERL_NIF_TERM term, double *out) {
  ErlNifSInt64 i;
  if (enif_get_double(env, term, out)) return 1;
  if (enif_get_int64(env, term, &i)) {
    *out = (double)i;
    return 1;
  }
  return 0;
}

static int get_tuple(ErlNifEnv *env, ERL_NIF_TERM term, int arity, double *out) {
  const ERL_NIF_TERM *items;
  int n;
  if (!enif_get_tuple(env, term, &n, &items) || n != arity) return 0;
  for (int i = 0; i < n; i++)
    if (!get_number(env, items[i], &out[i])) return 0;
  return 1;
}

static int get_list(ErlNifEnv *env, ERL_NIF_TERM list, int n, double *out) {
  unsigned len;
  ERL_NIF_TERM head;
  if (!enif_get_list_length(env, list, &len) || (int)len != n) return 0;
  for (int i = 0; i < n; i++) {
    if (!enif_get_list_cell(env, list, &head, &list) || !get_number(env, head, &out[i])) return 0;
  }
  return 1;
}

static int get_lags(ErlNifEnv *env, ERL_NIF_TERM list, int n, double lags[][2]) {
  unsigned len;
  ERL_NIF_TERM head;
  if (!enif_get_list_length(env, list, &len) || (int)len != n) return 0;
  for (int i = 0; i < n; i++) {
    if (!enif_get_list_cell(env, list, &head, &list) || !get_tuple(env, head, 2, lags[i])) return 0;
  }
  return 1;
}

/* mat_vec/7 of Neptunus.Dynamics */
static void mat_vec(const double m[36], const double v[6], double out[6]) {
  for (int i = 0; i < 6; i++) {
    const double *row = m + 6 * i;
    out[i] = row[0] * v[0] + row[1] * v[1] + row[2] * v[2] + row[3] * v[3] + row[4] * v[4] +
             row[5] * v[5];
  }
}

/* f/4 of Neptunus.Dynamics: {eta_dot, nu_dot}; -1 at the pitch singularity */
static int deriv(const kernel_t *k, const double s[12], const double tau[6], const double c[3],
                 double out[12]) {
  const double phi = s[3], theta = s[4], psi = s[5];
  const double u = s[6], v = s[7], w = s[8], p = s[9], q = s[10], r = s[11];
  const double cn = c[0], ce = c[1], cd = c[2];
  const double sphi = sin(phi), cphi = cos(phi), sth = sin(theta), cth = cos(theta);
  const double spsi = sin(psi), cpsi = cos(psi);

  if (fabs(cth) < 1.0e-6) return -1;

  const double r11 = cpsi * cth;
  const double r12 = -spsi * cphi + cpsi * sth * sphi;
  const double r13 = spsi * sphi + cpsi * cphi * sth;
  const double r21 = spsi * cth;
  const double r22 = cpsi * cphi + sphi * sth * spsi;
  const double r23 = -cpsi * sphi + sth * spsi * cphi;
  const double r31 = -sth;
  const double r32 = cth * sphi;
  const double r33 = cth * cphi;

  out[0] = r11 * u + r12 * v + r13 * w;
  out[1] = r21 * u + r22 * v + r23 * w;
  out[2] = r31 * u + r32 * v + r33 * w;

  if (k->locked) {
    out[3] = 0.0;
    out[4] = 0.0;
    out[5] = r;
  } else {
    const double rot = sphi * q + cphi * r;
    out[3] = p + rot * sth / cth;
    out[4] = cphi * q - sphi * r;
    out[5] = rot / cth;
  }

  const double uc = r11 * cn + r21 * ce + r31 * cd;
  const double vc = r12 * cn + r22 * ce + r32 * cd;
  const double wc = r13 * cn + r23 * ce + r33 * cd;
  const double ur = u - uc, vr = v - vc, wr = w - wc;

  double cor[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  if (k->coriolis) {
    const double nu_r[6] = {ur, vr, wr, p, q, r};
    double ab[6];
    mat_vec(k->m, nu_r, ab);
    const double a1 = ab[0], a2 = ab[1], a3 = ab[2], b1 = ab[3], b2 = ab[4], b3 = ab[5];
    cor[0] = q * a3 - r * a2;
    cor[1] = r * a1 - p * a3;
    cor[2] = p * a2 - q * a1;
    cor[3] = vr * a3 - wr * a2 + q * b3 - r * b2;
    cor[4] = wr * a1 - ur * a3 + r * b1 - p * b3;
    cor[5] = ur * a2 - vr * a1 + p * b2 - q * b1;
  }

  double ext[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  if (k->kt > 0.0) {
    const double kt = k->kt, ax = k->at[0], ay = k->at[1], az = k->at[2];
    const double vx = u + q * az - r * ay;
    const double vy = v + r * ax - p * az;
    const double vz = w + p * ay - q * ax;
    const double vn = r11 * vx + r12 * vy + r13 * vz;
    const double ve = r21 * vx + r22 * vy + r23 * vz;
    const double w1n = gauss_1 * vn - cn;
    const double w1e = gauss_1 * ve - ce;
    const double w2n = gauss_2 * vn - cn;
    const double w2e = gauss_2 * ve - ce;
    const double m1 = gauss_1 * sqrt(w1n * w1n + w1e * w1e);
    const double m2 = gauss_2 * sqrt(w2n * w2n + w2e * w2e);
    const double f_n = -kt * 0.5 * (m1 * w1n + m2 * w2n);
    const double f_e = -kt * 0.5 * (m1 * w1e + m2 * w2e);
    const double fx = r11 * f_n + r21 * f_e;
    const double fy = r12 * f_n + r22 * f_e;
    const double fz = r13 * f_n + r23 * f_e;
    ext[0] = fx;
    ext[1] = fy;
    ext[2] = fz;
    ext[3] = ay * fz - az * fy;
    ext[4] = az * fx - ax * fz;
    ext[5] = ax * fy - ay * fx;
  }

  /* kinetics/17: restoring forces, then M^-1 (tau + ext - C - D - g) */
  const double cthcphi = cth * cphi, cthsphi = cth * sphi;
  const double wb = k->wb, gx = k->gx, gy = k->gy, gz = k->gz;
  const double g[6] = {wb * sth,
                       -wb * cthsphi,
                       -wb * cthcphi,
                       -gy * cthcphi + gz * cthsphi,
                       gz * sth + gx * cthcphi,
                       -gx * cthsphi - gy * sth};
  const double nu[6] = {ur, vr, wr, p, q, r};
  double rhs[6], nd[6];
  for (int i = 0; i < 6; i++)
    rhs[i] = tau[i] + ext[i] - cor[i] - (k->d_l[i] + k->d_q[i] * fabs(nu[i])) * nu[i] - g[i];
  mat_vec(k->m_inv, rhs, nd);

  out[6] = nd[0] + (vc * r - wc * q);
  out[7] = nd[1] + (wc * p - uc * r);
  out[8] = nd[2] + (uc * q - vc * p);
  out[9] = nd[3];
  out[10] = nd[4];
  out[11] = nd[5];
  return 0;
}

static void axpy(const double s[12], double h, const double d[12], double out[12]) {
  for (int i = 0; i < 12; i++) out[i] = s[i] + h * d[i];
}

/* wrap_pi/1 of Neptunus.Dynamics */
static double wrap_pi(double angle) {
  double wrapped = angle - TWO_PI * floor((angle + PI) / TWO_PI);
  if (wrapped >= PI) return wrapped - TWO_PI;
  if (wrapped < -PI) return wrapped + TWO_PI;
  return wrapped + 0.0;
}

/* count_substeps/4 of Neptunus.Dynamics: RK4 sub-steps for a step of dt from s in c */
static int substeps(const kernel_t *k, const double s[12], const double c[3], double dt) {
  const double u = s[6], v = s[7], w = s[8], p = s[9], q = s[10], r = s[11];
  const double cn = c[0], ce = c[1], cd = c[2];
  const double vel = fabs(u) + fabs(v) + fabs(w);
  const double rot = fabs(p) + fabs(q) + fabs(r);
  const double c1 = fabs(cn) + fabs(ce) + fabs(cd);
  const double slope[6] = {k->d_l[0] + 2.0 * k->d_q[0] * (fabs(u) + c1),
                           k->d_l[1] + 2.0 * k->d_q[1] * (fabs(v) + c1),
                           k->d_l[2] + 2.0 * k->d_q[2] * (fabs(w) + c1),
                           k->d_l[3] + 2.0 * k->d_q[3] * (fabs(p) + c1),
                           k->d_l[4] + 2.0 * k->d_q[4] * (fabs(q) + c1),
                           k->d_l[5] + 2.0 * k->d_q[5] * (fabs(r) + c1)};
  double b[6];
  mat_vec(k->m_abs, slope, b);
  double lam_d = b[0];
  for (int i = 1; i < 6; i++) lam_d = b[i] > lam_d ? b[i] : lam_d;
  const double lam_t = k->kt * (vel + rot * k->arm + (fabs(cn) + fabs(ce))) * k->gain;
  const double lam = lam_d + lam_t + 2.0 * rot;
  const double n = ceil(dt * lam / RK4_LIMIT);
  if (!(n > 1.0)) return 1;
  if (n >= MAX_SUBSTEPS) return MAX_SUBSTEPS;
  return (int)n;
}

/* one step of Neptunus.Sim (constant current): lag, tau, RK4 (sub-stepped), wrap, surface */
static int sim_step(const kernel_t *k, double s[12], double forces[], const double targets[],
                    const double lags[][2], const double tau_ext[6], const double c[3], double dt) {
  double tau[6] = {0.0, 0.0, 0.0, 0.0, 0.0, 0.0};
  for (int i = 0; i < k->n; i++) {
    const double diff = forces[i] - targets[i];
    const double mean = targets[i] + diff * lags[i][1];
    forces[i] = targets[i] + diff * lags[i][0];
    for (int j = 0; j < 6; j++) tau[j] = tau[j] + mean * k->wrench[i][j];
  }
  for (int j = 0; j < 6; j++) tau[j] = tau[j] + tau_ext[j];

  const int n = substeps(k, s, c, dt);
  const double hs = dt / n;
  const double h = hs / 2;
  double k1[12], k2[12], k3[12], k4[12], tmp[12];
  for (int j = 0; j < n; j++) {
    if (deriv(k, s, tau, c, k1)) return -1;
    axpy(s, h, k1, tmp);
    if (deriv(k, tmp, tau, c, k2)) return -1;
    axpy(s, h, k2, tmp);
    if (deriv(k, tmp, tau, c, k3)) return -1;
    axpy(s, hs, k3, tmp);
    if (deriv(k, tmp, tau, c, k4)) return -1;
    for (int i = 0; i < 12; i++)
      s[i] = s[i] + hs * ((k1[i] + 2.0 * k2[i] + 2.0 * k3[i] + k4[i]) / 6.0);
  }

  s[3] = wrap_pi(s[3]);
  s[5] = wrap_pi(s[5]);
  if (s[2] < 0.0) {
    s[2] = 0.0;
    if (s[8] < 0.0) s[8] = 0.0;
  }
  return 0;
}

static ERL_NIF_TERM run(ErlNifEnv *env, int argc, const ERL_NIF_TERM argv[]) {
  kernel_t k;
  double s[12], forces[MAX_THRUSTERS], targets[MAX_THRUSTERS], lags[MAX_THRUSTERS][2];
  double tau_ext[6], c[3], dt;
  ErlNifSInt64 n;
  unsigned currents = 0;
  ERL_NIF_TERM list_of_currents = argv[6], item;
  (void)argc;

  if (!get_kernel(env, argv[0], &k) || !get_tuple(env, argv[1], 12, s) ||
      !get_list(env, argv[2], k.n, forces) || !get_list(env, argv[3], k.n, targets) ||
      !get_lags(env, argv[4], k.n, lags) || !get_tuple(env, argv[5], 6, tau_ext) ||
      !get_number(env, argv[7], &dt) || !(dt > 0.0) || !enif_get_int64(env, argv[8], &n) ||
      n < 1 || n > 100000)
    return enif_make_badarg(env);
  /* the current: one {n, e, d} for every step, or a list of one per step */
  if (enif_get_list_length(env, argv[6], &currents)) {
    if ((ErlNifSInt64)currents != n) return enif_make_badarg(env);
  } else if (!get_tuple(env, argv[6], 3, c)) {
    return enif_make_badarg(env);
  }

  for (ErlNifSInt64 i = 0; i < n; i++) {
    if (currents) {
      if (!enif_get_list_cell(env, list_of_currents, &item, &list_of_currents) ||
          !get_tuple(env, item, 3, c))
        return enif_make_badarg(env);
    }
    if (sim_step(&k, s, forces, targets, lags, tau_ext, c, dt))
      return enif_make_tuple2(env, atom_singular, enif_make_double(env, s[4]));
  }
  /* about 1 us per step: 1 000 steps is roughly one millisecond, a full timeslice */
  enif_consume_timeslice(env, n >= 1000 ? 100 : (int)(n / 10) + 1);

  ERL_NIF_TERM state[12], list[MAX_THRUSTERS];
  for (int i = 0; i < 12; i++) state[i] = enif_make_double(env, s[i]);
  for (int i = 0; i < k.n; i++) list[i] = enif_make_double(env, forces[i]);
  return enif_make_tuple2(env, enif_make_tuple_from_array(env, state, 12),
                          enif_make_list_from_array(env, list, (unsigned)k.n));
}

static ErlNifFunc funcs[] = {{"run", 9, run, 0}};

ERL_NIF_INIT(Elixir.Neptunus.Dynamics.Native, funcs, load, NULL, NULL, NULL)
