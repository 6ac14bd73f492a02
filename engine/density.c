/* density.c: density <-> thickness tables from Gradus's own geometry, see
 * density.h.
 *
 * Calibration. The signed distance sd to H (exact closest points) is sampled
 * at the centres of an N^3 grid over one cell (L = 1). The fraction of the
 * cell with sd <= t is the smoothed distribution
 *   F(t) = mean_i S((t - sd_i) / h),  S(x) = clamp(x + 1/2, 0, 1),  h = 1/N,
 * i.e. each sample stands for its grid cube, cut by a plane (|grad sd| = 1).
 * The smoothing is symmetric, so its bias is second order in h; the plain
 * count of samples (a step S) would leave a first-order lattice error. F is
 * kept on a fine grid of t over [-1/2, 1/2] (and cached); every kind's
 * rho(t) is built from it, tabulated at T_STEPS + 1 thicknesses, made
 * monotone, and interpolated linearly both ways (so rho -> T -> rho is exact
 * to rounding). */
#include "density.h"
#include <stdlib.h>
#include <string.h>
#include "distance.h"
#include "field.h"
#include "cli.h"

enum { F_STEPS = 4000, T_STEPS = 2000 };

struct gr_dtable {
  int refs;
  char surface[32];
  double level, ratio, L, track;
  int kind, side, res, clamp;
  double sdlo, sdhi;        /* -min sd, max sd over the samples (L = 1) */
  double F[F_STEPS + 1];    /* F(t) at t = -1/2 + k / F_STEPS (L = 1) */
  double rho[T_STEPS + 1];  /* rho at T / L = k / (2 T_STEPS) */
  double rlo, rhi, tlo, thi;/* reachable range (thicknesses in mm) */
  char key[160];
};

gr_dtable_opts gr_dtable_defaults(void) {
  gr_dtable_opts o;
  memset(&o, 0, sizeof o);
  o.surface = "gyroid";
  o.kind = GR_DENS_SHEET;
  o.side = -1;
  o.ratio = 1;
  o.cell = 2;
  o.track = 0.07;
  o.res = 128;
  return o;
}

static int cmp_d(const void *a, const void *b) {
  double x = *(const double *)a, y = *(const double *)b;
  return (x > y) - (x < y);
}

/* Signed distances at the N^3 cell centres of the unit cell. */
static double *sample_sd(const char *surface, double level, int N, gr_err *e) {
  double org[3] = {0, 0, 0};
  gr_field *phi = gr_field_tpms(surface, 1.0, org, level, e);
  if (!phi) return NULL;
  gr_offset_opts o = gr_offset_defaults();
  o.surface = phi;
  o.cell[0] = o.cell[1] = o.cell[2] = 1;
  o.box_hi[0] = o.box_hi[1] = o.box_hi[2] = 1;
  o.margin = 0.5; /* H around the cell: every sample's closest point is on it */
  o.thickness = 0;
  o.kind = GR_OFFSET_NETWORK;
  o.mode = GR_DIST_EXACT;
  gr_field *f = gr_offset_field_new(&o, e);
  gr_field_free(phi);
  if (!f) return NULL;
  size_t M = (size_t)N * N * N, row = (size_t)N;
  double *sd = malloc(M * sizeof *sd), *buf = malloc(6 * row * sizeof *buf);
  if (!sd || !buf) {
    free(sd), free(buf), gr_field_free(f);
    return gr_fail(e, GR_EMEM, "out of memory for %zu density samples", M), NULL;
  }
  double *x = buf, *y = buf + row, *z = buf + 2 * row, *q = buf + 3 * row;
  for (int k = 0; k < N; k++)
    for (int j = 0; j < N; j++) {
      for (int i = 0; i < N; i++) {
        x[i] = (i + 0.5) / N;
        y[i] = (j + 0.5) / N;
        z[i] = (k + 0.5) / N;
      }
      if (gr_offset_closest(f, row, x, y, z, INFINITY, q, sd + ((size_t)k * N + j) * row, e)) {
        free(sd), free(buf), gr_field_free(f);
        return NULL;
      }
    }
  free(buf);
  gr_field_free(f);
  return sd;
}

/* F on its grid from M samples (sorted here). */
static int smoothed_cdf(double *sd, size_t M, int N, double *F, double *lo, double *hi, gr_err *e) {
  qsort(sd, M, sizeof *sd, cmp_d);
  double *pre = malloc((M + 1) * sizeof *pre);
  if (!pre) return gr_fail(e, GR_EMEM, "out of memory");
  pre[0] = 0;
  for (size_t i = 0; i < M; i++) pre[i + 1] = pre[i] + sd[i];
  double h = 1.0 / N;
  size_t a = 0, b = 0; /* sd[0..a) < t - h/2, sd[0..b) < t + h/2 */
  for (int k = 0; k <= F_STEPS; k++) {
    double t = -0.5 + (double)k / F_STEPS;
    while (a < M && sd[a] < t - h / 2) a++;
    while (b < M && sd[b] < t + h / 2) b++;
    double ramp = (double)(b - a) * (t / h + 0.5) - (pre[b] - pre[a]) / h;
    F[k] = ((double)a + ramp) / (double)M;
  }
  *lo = -sd[0];
  *hi = sd[M - 1];
  free(pre);
  return GR_OK;
}

static double F_at(const gr_dtable *t, double s) {
  double x = (s + 0.5) * F_STEPS;
  if (x <= 0) return t->F[0];
  if (x >= F_STEPS) return t->F[F_STEPS];
  int k = (int)x;
  if (k >= F_STEPS) k = F_STEPS - 1;
  return t->F[k] + (x - k) * (t->F[k + 1] - t->F[k]);
}

static void cache_path(const gr_dtable_opts *o, char *out, size_t n) {
  snprintf(out, n, "%s/%s_level%.6g_res%d.density", o->cache, o->surface, o->level, o->res);
}

/* Read F from the cache; 1 on success. */
static int cache_read(gr_dtable *t, const char *path) {
  FILE *fp = fopen(path, "r");
  if (!fp) return 0;
  char name[64];
  int res = 0, steps = 0;
  double level = NAN;
  int ok = fscanf(fp, "gradus_density 1 %63s %lf %d %d %lf %lf", name, &level, &res, &steps, &t->sdlo, &t->sdhi) == 6 &&
           !strcmp(name, t->surface) && level == t->level && res == t->res && steps == F_STEPS;
  for (int k = 0; ok && k <= F_STEPS; k++) ok = fscanf(fp, "%lf", &t->F[k]) == 1 && isfinite(t->F[k]);
  fclose(fp);
  return ok;
}

static void cache_write(const gr_dtable *t, const char *path) {
  gr_atomic a;
  gr_err e;
  if (gr_atomic_open(&a, path, &e)) return; /* the cache is optional */
  fprintf(a.fp, "gradus_density 1 %s %.17g %d %d %.17g %.17g\n", t->surface, t->level, t->res, F_STEPS, t->sdlo, t->sdhi);
  for (int k = 0; k <= F_STEPS; k++) fprintf(a.fp, "%.17g\n", t->F[k]);
  gr_atomic_commit(&a, &e);
}

/* rho at T / L = s (L = 1 units) from F. */
static double rho_of(const gr_dtable *t, double s) {
  if (t->kind == GR_DENS_NETWORK) return t->side > 0 ? 1 - F_at(t, -s) : F_at(t, s);
  return F_at(t, s) - F_at(t, -t->ratio * s);
}

/* Reachable thickness range (L = 1 units): walls and pores >= one track. */
static void reach(gr_dtable *t) {
  double tau = t->track / t->L;
  double own = t->side > 0 ? t->sdhi : t->sdlo, gap = t->side > 0 ? t->sdlo : t->sdhi;
  double lo, hi;
  if (t->kind == GR_DENS_NETWORK) {
    lo = fmax(0, tau / 2 - own); /* ligament 2(own + T) */
    hi = gap - tau / 2;          /* pore 2(gap - T) */
  } else {
    lo = tau / (1 + t->ratio);   /* wall (1 + r) T */
    hi = fmin(t->sdhi - tau / 2, (t->sdlo - tau / 2) / t->ratio);
  }
  hi = fmin(hi, 0.5);
  t->tlo = lo * t->L;
  t->thi = hi * t->L;
  t->rlo = lo <= hi ? gr_dtable_rho(t, t->tlo) : NAN;
  t->rhi = lo <= hi ? gr_dtable_rho(t, t->thi) : NAN;
}

static int check_opts(const gr_dtable_opts *o, gr_err *e) {
  if (!o->surface || gr_tpms_lookup(o->surface) < 0)
    return gr_fail(e, GR_EARG, "bad option 'surface' (unknown surface '%s'; valid: %s)", o->surface ? o->surface : "", gr_tpms_names());
  if (!(o->cell > 0) || !isfinite(o->cell)) return gr_fail(e, GR_EARG, "bad option 'cell' (must be > 0 mm, got %g)", o->cell);
  if (!(o->track > 0) || !isfinite(o->track)) return gr_fail(e, GR_EARG, "bad option 'track' (must be > 0 mm, got %g)", o->track);
  if (!(o->ratio > 0) || !isfinite(o->ratio)) return gr_fail(e, GR_EARG, "bad option 'ratio' (inside/outside thickness must be > 0, got %g)", o->ratio);
  if (!isfinite(o->level)) return gr_fail(e, GR_EARG, "bad option 'level' (must be finite, got %g)", o->level);
  if (o->res < 8 || o->res > 512) return gr_fail(e, GR_EARG, "bad option 'res' (samples per cell edge must be in 8..512, got %d)", o->res);
  if (o->kind != GR_DENS_SHEET && o->kind != GR_DENS_NETWORK) return gr_fail(e, GR_EARG, "bad option 'kind' (sheet or network)");
  return GR_OK;
}

gr_dtable *gr_dtable_new(const gr_dtable_opts *o, gr_err *e) {
  if (check_opts(o, e)) return NULL;
  gr_dtable *t = calloc(1, sizeof *t);
  if (!t) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  t->refs = 1;
  snprintf(t->surface, sizeof t->surface, "%s", o->surface);
  t->level = o->level;
  t->kind = o->kind;
  t->side = o->side > 0 ? 1 : -1;
  t->ratio = o->kind == GR_DENS_SHEET ? o->ratio : 1;
  t->L = o->cell;
  t->track = o->track;
  t->res = o->res;
  t->clamp = o->clamp;
  char path[4200] = "";
  if (o->cache && *o->cache) cache_path(o, path, sizeof path);
  if (!path[0] || !cache_read(t, path)) {
    double *sd = sample_sd(o->surface, o->level, o->res, e);
    if (!sd) return free(t), NULL;
    int rc = smoothed_cdf(sd, (size_t)o->res * o->res * o->res, o->res, t->F, &t->sdlo, &t->sdhi, e);
    free(sd);
    if (rc) return free(t), NULL;
    if (path[0]) cache_write(t, path);
  }
  double run = 0;
  for (int k = 0; k <= T_STEPS; k++) {
    double r = rho_of(t, 0.5 * k / T_STEPS);
    run = fmax(run, r); /* monotone by construction; this guards rounding */
    t->rho[k] = run;
  }
  reach(t);
  snprintf(t->key, sizeof t->key, "%s %s, level %.9g, side %d, ratio %.9g, res %d", t->surface,
           t->kind == GR_DENS_NETWORK ? "network" : "sheet", t->level, t->side, t->ratio, t->res);
  return t;
}

gr_dtable *gr_dtable_ref(gr_dtable *t) {
  if (t) __atomic_fetch_add(&t->refs, 1, __ATOMIC_RELAXED);
  return t;
}

void gr_dtable_free(gr_dtable *t) {
  if (t && __atomic_sub_fetch(&t->refs, 1, __ATOMIC_ACQ_REL) == 0) free(t);
}

double gr_dtable_rho(const gr_dtable *t, double T) {
  double x = T / t->L * 2 * T_STEPS;
  if (!(x > 0)) return t->rho[0];
  if (x >= T_STEPS) return t->rho[T_STEPS];
  int k = (int)x;
  if (k >= T_STEPS) k = T_STEPS - 1;
  return t->rho[k] + (x - k) * (t->rho[k + 1] - t->rho[k]);
}

double gr_dtable_thickness(const gr_dtable *t, double rho) {
  if (isnan(rho)) return NAN;
  if (rho <= t->rho[0]) return 0;
  if (rho >= t->rho[T_STEPS]) return 0.5 * t->L;
  int a = 0, b = T_STEPS; /* rho[a] < rho <= rho[b] */
  while (b - a > 1) {
    int m = (a + b) / 2;
    if (t->rho[m] < rho) a = m;
    else b = m;
  }
  double f = (rho - t->rho[a]) / (t->rho[b] - t->rho[a]);
  return (a + f) * t->L / (2.0 * T_STEPS);
}

void gr_dtable_range(const gr_dtable *t, double *rho_lo, double *rho_hi, double *t_lo, double *t_hi) {
  if (rho_lo) *rho_lo = t->rlo;
  if (rho_hi) *rho_hi = t->rhi;
  if (t_lo) *t_lo = t->tlo;
  if (t_hi) *t_hi = t->thi;
}

int gr_dtable_check(const gr_dtable *t, double rho, const double p[3], const char *what, gr_err *e) {
  int por = what && !strcmp(what, "porosity");
  if (!isfinite(rho))
    return gr_fail(e, GR_ENUM, "%s %g at x=%.4g y=%.4g z=%.4g: not a number", por ? "porosity" : "density", por ? 1 - rho : rho, p[0], p[1], p[2]);
  if (t->clamp || (rho >= t->rlo && rho <= t->rhi)) return GR_OK;
  const char *kind = t->kind == GR_DENS_NETWORK ? "network" : (t->ratio != 1 ? "asymmetric sheet" : "sheet");
  if (!(t->rlo <= t->rhi))
    return gr_fail(e, GR_EARG, "%s %.4g at x=%.4g y=%.4g z=%.4g: %s %s, L=%g mm, nothing reachable with a %g mm track (walls or pores thinner than one track)",
                   por ? "porosity" : "density", por ? 1 - rho : rho, p[0], p[1], p[2], t->surface, kind, t->L, t->track);
  /* the range rounded inwards to 4 decimals, the value to 6 digits: a refused
   * value never prints inside the printed range */
  double a = ceil((por ? 1 - t->rhi : t->rlo) * 1e4) / 1e4, b = floor((por ? 1 - t->rlo : t->rhi) * 1e4) / 1e4;
  return gr_fail(e, GR_EARG, "%s %.6g at x=%.4g y=%.4g z=%.4g: %s %s, L=%g mm, reachable %.4f..%.4f with a %g mm track",
                 por ? "porosity" : "density", por ? 1 - rho : rho, p[0], p[1], p[2], t->surface, kind, t->L, a, b, t->track);
}

void gr_dtable_apply(const gr_dtable *t, size_t n, double *v) {
  for (size_t i = 0; i < n; i++) {
    double r = v[i];
    if (t->clamp && t->rlo <= t->rhi) r = fmin(fmax(r, t->rlo), t->rhi);
    v[i] = gr_dtable_thickness(t, r);
  }
}

const char *gr_dtable_key(const gr_dtable *t) { return t->key; }
double gr_dtable_ratio(const gr_dtable *t) { return t->ratio; }

void gr_dtable_extent(const gr_dtable *t, double *lo, double *hi) {
  *lo = t->sdlo;
  *hi = t->sdhi;
}

/* ---- achieved density: ring areas inside a box ---- */
/* Clip polygon (n points in a) against the half plane s*(coord ax) <= s*c
 * into b; returns the new count. */
static size_t clip_half(const double *a, size_t n, double *b, int ax, double c, int s) {
  size_t m = 0;
  for (size_t i = 0; i < n; i++) {
    const double *p = a + 2 * i, *q = a + 2 * gr_ring_next(i, n);
    double dp = s * (p[ax] - c), dq = s * (q[ax] - c);
    if (dp <= 0) { b[2 * m] = p[0]; b[2 * m + 1] = p[1]; m++; }
    if ((dp < 0 && dq > 0) || (dp > 0 && dq < 0)) {
      double f = dp / (dp - dq);
      b[2 * m] = p[0] + f * (q[0] - p[0]);
      b[2 * m + 1] = p[1] + f * (q[1] - p[1]);
      m++;
    }
  }
  return m;
}

double gr_ring_area_in_box(const double *xy, size_t n, const double lo[2], const double hi[2]) {
  if (n >= 2 && xy[0] == xy[2 * (n - 1)] && xy[1] == xy[2 * (n - 1) + 1]) n--; /* repeated first point */
  if (n < 3) return 0;
  /* each half-plane clip at most multiplies the count by 3/2: 1.5^4 < 6 */
  double *a = malloc(2 * (6 * n + 16) * sizeof *a), *b = malloc(2 * (6 * n + 16) * sizeof *b);
  if (!a || !b) { free(a); free(b); return NAN; }
  memcpy(a, xy, 2 * n * sizeof *a);
  size_t m = n;
  m = clip_half(a, m, b, 0, hi[0], 1);
  m = clip_half(b, m, a, 0, lo[0], -1);
  m = clip_half(a, m, b, 1, hi[1], 1);
  m = clip_half(b, m, a, 1, lo[1], -1);
  double s = 0;
  for (size_t i = 0; i < m; i++) {
    const double *p = a + 2 * i, *q = a + 2 * ((i + 1) % m);
    s += p[0] * q[1] - q[0] * p[1];
  }
  free(a);
  free(b);
  return 0.5 * s;
}

/* Length of ring edges inside the box (Liang-Barsky per edge). */
static double ring_len_in_box(const double *xy, size_t n, const double lo[2], const double hi[2]) {
  double s = 0;
  for (size_t i = 0; i + 1 < n; i++) {
    double px = xy[2 * i], py = xy[2 * i + 1], dx = xy[2 * i + 2] - px, dy = xy[2 * i + 3] - py;
    double a = 0, b = 1, pp[4] = {-dx, dx, -dy, dy}, qq[4] = {px - lo[0], hi[0] - px, py - lo[1], hi[1] - py};
    int in = 1;
    for (int k = 0; k < 4 && in; k++) {
      if (pp[k] == 0) in = qq[k] >= 0;
      else if (pp[k] < 0) a = fmax(a, qq[k] / pp[k]);
      else b = fmin(b, qq[k] / pp[k]);
    }
    if (in && b > a) s += (b - a) * sqrt(dx * dx + dy * dy);
  }
  return s;
}

typedef struct ach {
  const gr_achieved_opts *o;
  double *vol;
} ach;

static int ach_layer(void *ud, const gr_layer *l, gr_err *e) {
  (void)e;
  const ach *a = ud;
  const gr_achieved_opts *o = a->o;
  double L = o->cell, b = o->beam_offset;
  int k = (int)floor((l->z - o->layer / 2 - o->origin[2]) / L);
  if (k < 0 || k >= o->n[2]) return GR_OK;
  for (size_t q = 0; q < l->nb; q++) {
    const gr_block *bk = &l->b[q];
    if (bk->kind != GR_CONTOUR || bk->shape != GR_CLOSED || bk->n < 4) continue;
    const double *xy = l->xy + 2 * bk->start;
    double rlo[2] = {INFINITY, INFINITY}, rhi[2] = {-INFINITY, -INFINITY}, s = 0;
    for (size_t i = 0; i < bk->n; i++)
      for (int c = 0; c < 2; c++) { rlo[c] = fmin(rlo[c], xy[2 * i + c]); rhi[c] = fmax(rhi[c], xy[2 * i + c]); }
    for (size_t i = 0; i + 1 < bk->n; i++) s += xy[2 * i] * xy[2 * i + 3] - xy[2 * i + 2] * xy[2 * i + 1];
    int i0 = (int)floor((rlo[0] - o->origin[0]) / L), i1 = (int)floor((rhi[0] - o->origin[0]) / L);
    int j0 = (int)floor((rlo[1] - o->origin[1]) / L), j1 = (int)floor((rhi[1] - o->origin[1]) / L);
    int hi0 = (int)floor((xy[0] - o->origin[0]) / L), hj0 = (int)floor((xy[1] - o->origin[1]) / L);
    for (int j = j0 < 0 ? 0 : j0; j <= j1 && j < o->n[1]; j++)
      for (int i = i0 < 0 ? 0 : i0; i <= i1 && i < o->n[0]; i++) {
        double lo[2] = {o->origin[0] + i * L, o->origin[1] + j * L}, hi[2] = {lo[0] + L, lo[1] + L};
        double area = gr_ring_area_in_box(xy, bk->n, lo, hi);
        if (b > 0) {
          area += b * ring_len_in_box(xy, bk->n, lo, hi);
          if (i == hi0 && j == hj0) area += (s > 0 ? 1 : -1) * M_PI * b * b;
        }
        a->vol[i + o->n[0] * (j + (size_t)o->n[1] * k)] += area * o->layer;
      }
  }
  return GR_OK;
}

int gr_density_achieved(const char *cli, const gr_achieved_opts *o, double *vol, gr_err *e) {
  if (!(o->cell > 0) || !(o->layer > 0) || !(o->beam_offset >= 0) || o->n[0] < 1 || o->n[1] < 1 || o->n[2] < 1)
    return gr_fail(e, GR_EARG, "achieved density: bad grid (cell %g, layer %g, beam offset %g, %dx%dx%d voxels)",
                   o->cell, o->layer, o->beam_offset, o->n[0], o->n[1], o->n[2]);
  memset(vol, 0, (size_t)o->n[0] * o->n[1] * o->n[2] * sizeof *vol);
  ach a = {o, vol};
  gr_cli_header h;
  return gr_cli_read(cli, &h, ach_layer, &a, e);
}
