/* field.c: see field.h. Every kind evaluates a batch of points; combinations
 * evaluate their children in chunks of CH points through one scratch buffer
 * allocated per call (not per point, and not on the C stack, so that deep
 * left-leaning unions cannot overflow a worker thread's stack). */
#include "field.h"
#include "vecmath.h"
#include <math.h>
#include <stdarg.h>
#include <stdatomic.h>
#include <stdlib.h>
#include <string.h>
#include "expr.h"

#define CH 256 /* points per chunk in combinations */

enum { K_TPMS, K_EXPR, K_CALLBACK, K_CONST, K_MIN, K_MAX, K_NEG, K_BLEND,
       K_TRANSLATE, K_SCALE };

struct gr_field {
  atomic_int refs;        /* references held */
  int kind;               /* K_* */
  int threadsafe;         /* 0 if eval must stay on one thread */
  double lip;             /* upper bound of |grad|, 1/mm times field unit */
  char desc[256];         /* describe text (truncated) */
  /* K_TPMS */
  int surface;            /* catalogue index */
  double cell[3];         /* Lx, Ly, Lz, mm */
  double origin[3];       /* min corner, mm */
  double level;           /* c */
  double w[3];            /* 2*pi/L per axis, rad/mm */
  /* K_EXPR */
  gr_expr *expr;
  /* K_CALLBACK */
  gr_field_fn fn;
  gr_field_gradfn gradfn; /* NULL: central differences */
  void *ud;
  void (*free_ud)(void *);
  /* K_CONST */
  double c;
  /* combinations */
  gr_field *a, *b, *wf;   /* children (wf: blend weight) */
  double d[3];            /* translation, mm */
  double s;               /* scale factor */
};

/* ---- TPMS catalogue ---- */
enum { S_PRIMITIVE, S_GYROID, S_DIAMOND, S_IWP, S_NEOVIUS, S_FRD, S_FKS,
       S_LIDINOID, S_SPLITP, S_OCTO, S_COUNT };
static const char *const TPMS_NAMES[S_COUNT] = {
  "primitive", "gyroid", "diamond", "iwp", "neovius", "frd",
  "fischer_koch_s", "lidinoid", "split_p", "octo"};
/* Bound of each |d phi / dX| component (sum of |coefficient x derivative
 * factor| of that component's terms); |grad_X phi| <= sqrt(3) * bound. */
static const double TPMS_DBOUND[S_COUNT] = {1, 2, 2, 6, 7, 8, 4, 8, 6, 1.6};

int gr_tpms_count(void) { return S_COUNT; }
const char *gr_tpms_name(int i) { return i >= 0 && i < S_COUNT ? TPMS_NAMES[i] : NULL; }
int gr_tpms_lookup(const char *name) {
  for (int i = 0; name && i < S_COUNT; i++)
    if (!strcmp(name, TPMS_NAMES[i])) return i;
  return -1;
}
const char *gr_tpms_names(void) {
  return "primitive, gyroid, diamond, iwp, neovius, frd, fischer_koch_s, "
         "lidinoid, split_p, octo";
}

/* tpms_trig for the surfaces whose terms take double angles (iwp, frd,
 * fischer_koch_s, lidinoid, split_p): those come from the single ones. */
static double tpms_trig2(int s, double sx, double cx, double sy, double cy, double sz, double cz, double *g) {
  double s2x = 2 * sx * cx, s2y = 2 * sy * cy, s2z = 2 * sz * cz;
  double c2x = 2 * cx * cx - 1, c2y = 2 * cy * cy - 1, c2z = 2 * cz * cz - 1;
  double phi = 0, gx = 0, gy = 0, gz = 0;
  switch (s) {
  case S_IWP:
    phi = 2 * (cx * cy + cy * cz + cz * cx) - (c2x + c2y + c2z);
    gx = -2 * sx * (cy + cz) + 2 * s2x;
    gy = -2 * sy * (cx + cz) + 2 * s2y;
    gz = -2 * sz * (cx + cy) + 2 * s2z;
    break;
  case S_FRD:
    phi = 4 * cx * cy * cz - (c2x * c2y + c2y * c2z + c2z * c2x);
    gx = -4 * sx * cy * cz + 2 * s2x * (c2y + c2z);
    gy = -4 * cx * sy * cz + 2 * s2y * (c2x + c2z);
    gz = -4 * cx * cy * sz + 2 * s2z * (c2x + c2y);
    break;
  case S_FKS:
    phi = c2x * sy * cz + cx * c2y * sz + sx * cy * c2z;
    gx = -2 * s2x * sy * cz - sx * c2y * sz + cx * cy * c2z;
    gy = c2x * cy * cz - 2 * cx * s2y * sz - sx * sy * c2z;
    gz = -c2x * sy * sz + cx * c2y * cz - 2 * sx * cy * s2z;
    break;
  case S_LIDINOID:
    phi = s2x * cy * sz + s2y * cz * sx + s2z * cx * sy -
          (c2x * c2y + c2y * c2z + c2z * c2x) + 0.3;
    gx = 2 * c2x * cy * sz + s2y * cz * cx - s2z * sx * sy + 2 * s2x * (c2y + c2z);
    gy = -s2x * sy * sz + 2 * c2y * cz * sx + s2z * cx * cy + 2 * s2y * (c2x + c2z);
    gz = s2x * cy * cz - s2y * sz * sx + 2 * c2z * cx * sy + 2 * s2z * (c2x + c2y);
    break;
  case S_SPLITP:
    phi = 1.1 * (s2x * sz * cy + s2y * sx * cz + s2z * sy * cx) -
          0.2 * (c2x * c2y + c2y * c2z + c2z * c2x) - 0.4 * (c2x + c2y + c2z);
    gx = 1.1 * (2 * c2x * sz * cy + s2y * cx * cz - s2z * sy * sx) +
         0.4 * s2x * (c2y + c2z) + 0.8 * s2x;
    gy = 1.1 * (-s2x * sz * sy + 2 * c2y * sx * cz + s2z * cy * cx) +
         0.4 * s2y * (c2x + c2z) + 0.8 * s2y;
    gz = 1.1 * (s2x * cz * cy - s2y * sx * sz + 2 * c2z * sy * cx) +
         0.4 * s2z * (c2x + c2y) + 0.8 * s2z;
    break;
  }
  if (g) { g[0] = gx; g[1] = gy; g[2] = gz; }
  return phi;
}

/* phi from the sines and cosines of the cell-angle coordinates (X, Y, Z);
 * g (may be NULL) receives d phi / d(X, Y, Z). Double angles come from the
 * single ones, so callers that know the trig values (grids) skip libm; the
 * surfaces without them do not compute them (tpms_trig2 does). */
static double tpms_trig(int s, double sx, double cx, double sy, double cy, double sz,
                        double cz, double *g) {
  double phi = 0, gx = 0, gy = 0, gz = 0;
  switch (s) {
  case S_PRIMITIVE:
    phi = cx + cy + cz;
    gx = -sx; gy = -sy; gz = -sz;
    break;
  case S_GYROID:
    phi = cx * sy + cy * sz + cz * sx;
    gx = -sx * sy + cz * cx;
    gy = cx * cy - sy * sz;
    gz = cy * cz - sz * sx;
    break;
  case S_DIAMOND:
    phi = sx * sy * sz + sx * cy * cz + cx * sy * cz + cx * cy * sz;
    gx = cx * sy * sz + cx * cy * cz - sx * sy * cz - sx * cy * sz;
    gy = sx * cy * sz - sx * sy * cz + cx * cy * cz - cx * sy * sz;
    gz = sx * sy * cz - sx * cy * sz - cx * sy * sz + cx * cy * cz;
    break;
  case S_NEOVIUS:
    phi = 3 * (cx + cy + cz) + 4 * cx * cy * cz;
    gx = -3 * sx - 4 * sx * cy * cz;
    gy = -3 * sy - 4 * cx * sy * cz;
    gz = -3 * sz - 4 * cx * cy * sz;
    break;
  case S_OCTO:
    phi = 0.6 * (cx * cy + cy * cz + cz * cx) - 0.4 * (cx + cy + cz) + 0.25;
    gx = -0.6 * sx * (cy + cz) + 0.4 * sx;
    gy = -0.6 * sy * (cx + cz) + 0.4 * sy;
    gz = -0.6 * sz * (cx + cy) + 0.4 * sz;
    break;
  default:
    return tpms_trig2(s, sx, cx, sy, cy, sz, cz, g);
  }
  if (g) { g[0] = gx; g[1] = gy; g[2] = gz; }
  return phi;
}

/* Sines (into s) and cosines (into c) of the n angles in s, through the
 * vector math library: s and c have room for n rounded up to 4, so that
 * every angle takes the library's vector path (not its 2-wide or scalar
 * tail): an angle's sine is then the same bits whichever batch, grid or
 * position it comes in. */
static size_t vsincos_room(size_t n) { return (n + 3) & ~(size_t)3; }
static void vsincos(size_t n, double *s, double *c) {
  size_t n4 = vsincos_room(n);
  for (size_t i = n; i < n4; i++) s[i] = 0;
  memcpy(c, s, n4 * sizeof *s);
  gr_vsin(n4, s);
  gr_vcos(n4, c);
}

/* The phase of coordinate x along axis a of TPMS field f (rad). */
static double tpms_phase(const gr_field *f, int a, double x) { return f->w[a] * (x - (f->origin[a] + f->cell[a] / 2)); }

/* phi - level of TPMS field f at n points (out, or NULL) and its gradient
 * (gx, gy, gz, or NULL): the sines and cosines of a chunk of points at once
 * through the vector math library (vecmath.h: within 4 ulp, a few times
 * cheaper than one libm call per angle; meshing and the closest-point
 * table evaluate millions of points). */
static void tpms_batch(const gr_field *f, size_t n, const double *x, const double *y, const double *z, double *out,
                       double *gx, double *gy, double *gz) {
  enum { B = 128 };
  double sn[3 * B + 3], cs[3 * B + 3], g[3];
  const double *w = f->w, *pt[3] = {x, y, z};
  for (size_t o = 0; o < n; o += B) {
    size_t m = n - o < B ? n - o : B;
    for (size_t i = 0; i < m; i++)
      for (int a = 0; a < 3; a++) sn[3 * i + a] = tpms_phase(f, a, pt[a][o + i]);
    vsincos(3 * m, sn, cs);
    for (size_t i = 0; i < m; i++) {
      const double *S = sn + 3 * i, *C = cs + 3 * i;
      double v = tpms_trig(f->surface, S[0], C[0], S[1], C[1], S[2], C[2], gx ? g : NULL);
      if (out) out[o + i] = v - f->level;
      if (gx) { gx[o + i] = w[0] * g[0]; gy[o + i] = w[1] * g[1]; gz[o + i] = w[2] * g[2]; }
    }
  }
}

/* ---- construction helpers ---- */
static void setdesc(gr_field *f, const char *fmt, ...) {
  va_list ap;
  va_start(ap, fmt);
  vsnprintf(f->desc, sizeof f->desc, fmt, ap);
  va_end(ap);
}

static gr_field *field_new(int kind) {
  gr_field *f = calloc(1, sizeof *f);
  if (!f) return NULL;
  atomic_init(&f->refs, 1);
  f->kind = kind;
  f->threadsafe = 1;
  return f;
}

gr_field *gr_field_tpms(const char *name, double cell, const double *origin,
                        double level, gr_err *e) {
  double c3[3] = {cell, cell, cell};
  return gr_field_tpms3(name, c3, origin, level, e);
}

gr_field *gr_field_tpms3(const char *name, const double cell[3], const double *origin,
                         double level, gr_err *e) {
  int s = gr_tpms_lookup(name);
  if (s < 0) {
    gr_fail(e, GR_EARG, "unknown TPMS surface '%s' (valid: %s)", name ? name : "(null)",
            gr_tpms_names());
    return NULL;
  }
  for (int a = 0; a < 3; a++)
    if (!(cell[a] > 0) || !isfinite(cell[a])) {
      gr_fail(e, GR_EARG, "cell size must be > 0, got %g", cell[a]);
      return NULL;
    }
  if (!isfinite(level)) {
    gr_fail(e, GR_EARG, "level must be finite, got %g", level);
    return NULL;
  }
  double o[3] = {0, 0, 0};
  if (origin) {
    for (int i = 0; i < 3; i++) {
      if (!isfinite(origin[i])) {
        gr_fail(e, GR_EARG, "origin[%d] must be finite, got %g", i + 1, origin[i]);
        return NULL;
      }
      o[i] = origin[i];
    }
  }
  gr_field *f = field_new(K_TPMS);
  if (!f) { gr_fail(e, GR_EMEM, "out of memory creating a %s field", name); return NULL; }
  f->surface = s;
  memcpy(f->cell, cell, sizeof f->cell);
  memcpy(f->origin, o, sizeof o);
  f->level = level;
  for (int a = 0; a < 3; a++) f->w[a] = 2 * M_PI / cell[a];
  /* |grad phi| <= max_a w_a * sqrt(3) * bound (stretched cells: the shortest axis) */
  f->lip = fmax(f->w[0], fmax(f->w[1], f->w[2])) * sqrt(3.0) * TPMS_DBOUND[s];
  char L[80];
  if (cell[0] == cell[1] && cell[1] == cell[2]) snprintf(L, sizeof L, "%g", cell[0]);
  else snprintf(L, sizeof L, "%gx%gx%g", cell[0], cell[1], cell[2]);
  if (o[0] || o[1] || o[2])
    setdesc(f, "%s(L=%s, origin=(%g, %g, %g), level=%g)", TPMS_NAMES[s], L, o[0], o[1],
            o[2], level);
  else
    setdesc(f, "%s(L=%s, level=%g)", TPMS_NAMES[s], L, level);
  return f;
}

int gr_field_tpms_info(const gr_field *f, gr_tpms_info *info) {
  if (!f || f->kind != K_TPMS) return 0;
  if (info) {
    info->surface = f->surface;
    info->cell = f->cell[0];
    memcpy(info->lengths, f->cell, sizeof info->lengths);
    memcpy(info->origin, f->origin, sizeof info->origin);
    info->level = f->level;
  }
  return 1;
}

gr_field *gr_field_expr(const char *src, gr_err *e) {
  static const char *const vars[3] = {"x", "y", "z"};
  gr_expr *x = gr_expr_compile(src, 3, vars, 0, NULL, NULL, e);
  if (!x) return NULL;
  gr_field *f = field_new(K_EXPR);
  if (!f) {
    gr_expr_free(x);
    gr_fail(e, GR_EMEM, "out of memory creating expression field '%s'", src);
    return NULL;
  }
  f->expr = x;
  f->lip = INFINITY;
  setdesc(f, "expr(%s)", src);
  return f;
}

gr_field *gr_field_constant(double c) {
  gr_field *f = field_new(K_CONST);
  if (!f) return NULL;
  f->c = c;
  f->lip = 0;
  setdesc(f, "constant(%g)", c);
  return f;
}

gr_field *gr_field_callback(gr_field_fn fn, gr_field_gradfn grad, void *ud,
                            void (*free_ud)(void *), int threadsafe,
                            const char *describe) {
  if (!fn) return NULL;
  gr_field *f = field_new(K_CALLBACK);
  if (!f) return NULL;
  f->fn = fn;
  f->gradfn = grad;
  f->ud = ud;
  f->free_ud = free_ud;
  f->threadsafe = threadsafe;
  f->lip = INFINITY;
  setdesc(f, "%s", describe ? describe : "callback");
  return f;
}

static gr_field *combo(int kind, gr_field *a, gr_field *b, gr_field *w) {
  if (!a || (kind != K_NEG && kind != K_TRANSLATE && kind != K_SCALE && !b) ||
      (kind == K_BLEND && !w))
    return NULL;
  gr_field *f = field_new(kind);
  if (!f) return NULL;
  f->a = gr_field_ref(a);
  f->b = b ? gr_field_ref(b) : NULL;
  f->wf = w ? gr_field_ref(w) : NULL;
  f->threadsafe = a->threadsafe && (!b || b->threadsafe) && (!w || w->threadsafe);
  return f;
}

gr_field *gr_field_min(gr_field *a, gr_field *b) {
  gr_field *f = combo(K_MIN, a, b, NULL);
  if (f) {
    f->lip = fmax(a->lip, b->lip);
    setdesc(f, "min(%s, %s)", a->desc, b->desc);
  }
  return f;
}

gr_field *gr_field_max(gr_field *a, gr_field *b) {
  gr_field *f = combo(K_MAX, a, b, NULL);
  if (f) {
    f->lip = fmax(a->lip, b->lip);
    setdesc(f, "max(%s, %s)", a->desc, b->desc);
  }
  return f;
}

gr_field *gr_field_negate(gr_field *a) {
  gr_field *f = combo(K_NEG, a, NULL, NULL);
  if (f) {
    f->lip = a->lip;
    setdesc(f, "-(%s)", a->desc);
  }
  return f;
}

/* grad = (1-w) ga + w gb + (b - a) gw: |b - a| is unbounded in general, so
 * the bound is only finite for a constant weight. */
gr_field *gr_field_blend(gr_field *a, gr_field *b, gr_field *w) {
  gr_field *f = combo(K_BLEND, a, b, w);
  if (f) {
    f->lip = w->lip == 0 ? fmax(a->lip, b->lip) : INFINITY;
    setdesc(f, "blend(%s, %s, %s)", a->desc, b->desc, w->desc);
  }
  return f;
}

gr_field *gr_field_translate(gr_field *a, const double d[3]) {
  if (!d || !isfinite(d[0]) || !isfinite(d[1]) || !isfinite(d[2])) return NULL;
  gr_field *f = combo(K_TRANSLATE, a, NULL, NULL);
  if (f) {
    memcpy(f->d, d, sizeof f->d);
    f->lip = a->lip;
    setdesc(f, "translate(%s, (%g, %g, %g))", a->desc, d[0], d[1], d[2]);
  }
  return f;
}

/* s*a(p/s) has gradient grad a(p/s): same bound. s must be finite, != 0. */
gr_field *gr_field_scale(gr_field *a, double s) {
  if (!(s != 0) || !isfinite(s)) return NULL;
  gr_field *f = combo(K_SCALE, a, NULL, NULL);
  if (f) {
    f->s = s;
    f->lip = a->lip;
    setdesc(f, "scale(%s, %g)", a->desc, s);
  }
  return f;
}

gr_field *gr_field_ref(gr_field *f) {
  if (f) atomic_fetch_add(&f->refs, 1);
  return f;
}

void gr_field_free(gr_field *f) {
  if (!f || atomic_fetch_sub(&f->refs, 1) != 1) return;
  gr_expr_free(f->expr);
  if (f->free_ud) f->free_ud(f->ud);
  gr_field_free(f->a);
  gr_field_free(f->b);
  gr_field_free(f->wf);
  free(f);
}

int gr_field_threadsafe(const gr_field *f) { return f ? f->threadsafe : 1; }

void *gr_field_callback_data(const gr_field *f, gr_field_fn fn) {
  return (f && f->kind == K_CALLBACK && f->fn == fn) ? f->ud : NULL;
}
double gr_field_lipschitz(const gr_field *f) { return f ? f->lip : INFINITY; }
void gr_field_set_lipschitz(gr_field *f, double k) { if (f && k > 0) f->lip = k; }
const char *gr_field_describe(const gr_field *f) { return f ? f->desc : "(null)"; }

/* ---- evaluation ---- */
static int eval_(const gr_field *f, size_t n, const double *x, const double *y,
                 const double *z, double *out, gr_err *e);
static int grad_(const gr_field *f, size_t n, const double *x, const double *y,
                 const double *z, double *gx, double *gy, double *gz, gr_err *e);

static double *scratch(size_t k, const gr_field *f, gr_err *e) {
  double *s = malloc(k * CH * sizeof *s);
  if (!s) gr_fail(e, GR_EMEM, "out of memory evaluating %s", f->desc);
  return s;
}

static int eval_(const gr_field *f, size_t n, const double *x, const double *y,
                 const double *z, double *out, gr_err *e) {
  int rc = GR_OK;
  double *t = NULL;
  switch (f->kind) {
  case K_TPMS:
    tpms_batch(f, n, x, y, z, out, NULL, NULL, NULL);
    return GR_OK;
  case K_EXPR: {
    const double *v[3] = {x, y, z};
    return gr_expr_eval(f->expr, n, v, out, e);
  }
  case K_CALLBACK:
    return f->fn(f->ud, n, x, y, z, out, e);
  case K_CONST:
    for (size_t i = 0; i < n; i++) out[i] = f->c;
    return GR_OK;
  case K_NEG:
    rc = eval_(f->a, n, x, y, z, out, e);
    for (size_t i = 0; rc == GR_OK && i < n; i++) out[i] = -out[i];
    return rc;
  case K_MIN: case K_MAX: case K_BLEND:
    if (!(t = scratch(2, f, e))) return GR_EMEM;
    for (size_t o = 0; o < n && rc == GR_OK; o += CH) {
      size_t m = n - o < CH ? n - o : CH;
      double *r = out + o, *vb = t, *vw = t + CH;
      rc = eval_(f->a, m, x + o, y + o, z + o, r, e);
      if (rc == GR_OK) rc = eval_(f->b, m, x + o, y + o, z + o, vb, e);
      if (rc == GR_OK && f->kind == K_BLEND) rc = eval_(f->wf, m, x + o, y + o, z + o, vw, e);
      if (rc != GR_OK) break;
      if (f->kind == K_MIN)
        for (size_t i = 0; i < m; i++) r[i] = vb[i] < r[i] ? vb[i] : r[i];
      else if (f->kind == K_MAX)
        for (size_t i = 0; i < m; i++) r[i] = vb[i] > r[i] ? vb[i] : r[i];
      else
        for (size_t i = 0; i < m; i++) {
          double w = vw[i] < 0 ? 0 : vw[i] > 1 ? 1 : vw[i];
          r[i] = (1 - w) * r[i] + w * vb[i];
        }
    }
    free(t);
    return rc;
  case K_TRANSLATE: case K_SCALE:
    if (!(t = scratch(3, f, e))) return GR_EMEM;
    for (size_t o = 0; o < n && rc == GR_OK; o += CH) {
      size_t m = n - o < CH ? n - o : CH;
      double *px = t, *py = t + CH, *pz = t + 2 * CH;
      for (size_t i = 0; i < m; i++) {
        if (f->kind == K_TRANSLATE) {
          px[i] = x[o + i] - f->d[0]; py[i] = y[o + i] - f->d[1]; pz[i] = z[o + i] - f->d[2];
        } else {
          px[i] = x[o + i] / f->s; py[i] = y[o + i] / f->s; pz[i] = z[o + i] / f->s;
        }
      }
      rc = eval_(f->a, m, px, py, pz, out + o, e);
      if (rc == GR_OK && f->kind == K_SCALE)
        for (size_t i = 0; i < m; i++) out[o + i] *= f->s;
    }
    free(t);
    return rc;
  }
  return gr_fail(e, GR_EARG, "unknown field kind %d", f->kind);
}

/* Central differences with a step relative to the coordinates' size; the
 * step actually taken ((x+h) - (x-h) in floating point) is the divisor. */
static int fd_grad(const gr_field *f, size_t n, const double *x, const double *y,
                   const double *z, double *gx, double *gy, double *gz, gr_err *e) {
  double *t = scratch(4, f, e);
  if (!t) return GR_EMEM;
  int rc = GR_OK;
  for (size_t o = 0; o < n && rc == GR_OK; o += CH) {
    size_t m = n - o < CH ? n - o : CH;
    double *h = t, *q = t + CH, *vp = t + 2 * CH, *vm = t + 3 * CH;
    for (size_t i = 0; i < m; i++) {
      double s = fmax(1.0, fmax(fabs(x[o + i]), fmax(fabs(y[o + i]), fabs(z[o + i]))));
      h[i] = 1e-6 * s;
    }
    for (int ax = 0; ax < 3 && rc == GR_OK; ax++) {
      const double *c = ax == 0 ? x + o : ax == 1 ? y + o : z + o;
      double *g = ax == 0 ? gx + o : ax == 1 ? gy + o : gz + o;
      const double *px = ax == 0 ? q : x + o, *py = ax == 1 ? q : y + o,
                   *pz = ax == 2 ? q : z + o;
      for (size_t i = 0; i < m; i++) q[i] = c[i] + h[i];
      rc = eval_(f, m, px, py, pz, vp, e);
      if (rc != GR_OK) break;
      for (size_t i = 0; i < m; i++) { g[i] = q[i]; q[i] = c[i] - h[i]; }
      rc = eval_(f, m, px, py, pz, vm, e);
      if (rc != GR_OK) break;
      for (size_t i = 0; i < m; i++) g[i] = (vp[i] - vm[i]) / (g[i] - q[i]);
    }
  }
  free(t);
  return rc;
}

static int grad_(const gr_field *f, size_t n, const double *x, const double *y,
                 const double *z, double *gx, double *gy, double *gz, gr_err *e) {
  int rc = GR_OK;
  double *t = NULL;
  switch (f->kind) {
  case K_TPMS:
    tpms_batch(f, n, x, y, z, NULL, gx, gy, gz);
    return GR_OK;
  case K_EXPR:
    return fd_grad(f, n, x, y, z, gx, gy, gz, e);
  case K_CALLBACK:
    if (f->gradfn) return f->gradfn(f->ud, n, x, y, z, gx, gy, gz, e);
    return fd_grad(f, n, x, y, z, gx, gy, gz, e);
  case K_CONST:
    for (size_t i = 0; i < n; i++) gx[i] = gy[i] = gz[i] = 0;
    return GR_OK;
  case K_NEG:
    rc = grad_(f->a, n, x, y, z, gx, gy, gz, e);
    for (size_t i = 0; rc == GR_OK && i < n; i++) { gx[i] = -gx[i]; gy[i] = -gy[i]; gz[i] = -gz[i]; }
    return rc;
  case K_MIN: case K_MAX:
    /* the gradient of the child that is selected (a on ties) */
    if (!(t = scratch(5, f, e))) return GR_EMEM;
    for (size_t o = 0; o < n && rc == GR_OK; o += CH) {
      size_t m = n - o < CH ? n - o : CH;
      double *va = t, *vb = t + CH, *bx = t + 2 * CH, *by = t + 3 * CH, *bz = t + 4 * CH;
      const double *px = x + o, *py = y + o, *pz = z + o;
      rc = eval_(f->a, m, px, py, pz, va, e);
      if (rc == GR_OK) rc = eval_(f->b, m, px, py, pz, vb, e);
      if (rc == GR_OK) rc = grad_(f->a, m, px, py, pz, gx + o, gy + o, gz + o, e);
      if (rc == GR_OK) rc = grad_(f->b, m, px, py, pz, bx, by, bz, e);
      if (rc != GR_OK) break;
      for (size_t i = 0; i < m; i++) {
        int takeb = f->kind == K_MIN ? vb[i] < va[i] : vb[i] > va[i];
        if (takeb) { gx[o + i] = bx[i]; gy[o + i] = by[i]; gz[o + i] = bz[i]; }
      }
    }
    free(t);
    return rc;
  case K_BLEND:
    if (!(t = scratch(9, f, e))) return GR_EMEM;
    for (size_t o = 0; o < n && rc == GR_OK; o += CH) {
      size_t m = n - o < CH ? n - o : CH;
      double *va = t, *vb = t + CH, *vw = t + 2 * CH, *bx = t + 3 * CH, *by = t + 4 * CH,
             *bz = t + 5 * CH, *wx = t + 6 * CH, *wy = t + 7 * CH, *wz = t + 8 * CH;
      const double *px = x + o, *py = y + o, *pz = z + o;
      double *ax = gx + o, *ay = gy + o, *az = gz + o;
      rc = eval_(f->a, m, px, py, pz, va, e);
      if (rc == GR_OK) rc = eval_(f->b, m, px, py, pz, vb, e);
      if (rc == GR_OK) rc = eval_(f->wf, m, px, py, pz, vw, e);
      if (rc == GR_OK) rc = grad_(f->a, m, px, py, pz, ax, ay, az, e);
      if (rc == GR_OK) rc = grad_(f->b, m, px, py, pz, bx, by, bz, e);
      if (rc == GR_OK) rc = grad_(f->wf, m, px, py, pz, wx, wy, wz, e);
      if (rc != GR_OK) break;
      for (size_t i = 0; i < m; i++) {
        double w = vw[i], k = vb[i] - va[i];
        if (w <= 0) { w = 0; k = 0; } else if (w >= 1) { w = 1; k = 0; }
        ax[i] = (1 - w) * ax[i] + w * bx[i] + k * wx[i];
        ay[i] = (1 - w) * ay[i] + w * by[i] + k * wy[i];
        az[i] = (1 - w) * az[i] + w * bz[i] + k * wz[i];
      }
    }
    free(t);
    return rc;
  case K_TRANSLATE: case K_SCALE:
    if (!(t = scratch(3, f, e))) return GR_EMEM;
    for (size_t o = 0; o < n && rc == GR_OK; o += CH) {
      size_t m = n - o < CH ? n - o : CH;
      double *px = t, *py = t + CH, *pz = t + 2 * CH;
      for (size_t i = 0; i < m; i++) {
        if (f->kind == K_TRANSLATE) {
          px[i] = x[o + i] - f->d[0]; py[i] = y[o + i] - f->d[1]; pz[i] = z[o + i] - f->d[2];
        } else {
          px[i] = x[o + i] / f->s; py[i] = y[o + i] / f->s; pz[i] = z[o + i] / f->s;
        }
      }
      rc = grad_(f->a, m, px, py, pz, gx + o, gy + o, gz + o, e);
    }
    free(t);
    return rc;
  }
  return gr_fail(e, GR_EARG, "unknown field kind %d", f->kind);
}

/* First non-finite entry of v[0..n) (or of three arrays), or -1. */
static long first_bad(size_t n, const double *a, const double *b, const double *c) {
  for (size_t i = 0; i < n; i++)
    if (!isfinite(a[i]) || (b && !isfinite(b[i])) || (c && !isfinite(c[i]))) return (long)i;
  return -1;
}

int gr_field_eval(const gr_field *f, size_t n, const double *x,
                  const double *y, const double *z, double *out, gr_err *e) {
  if (!f) return gr_fail(e, GR_EARG, "field is missing (NULL)");
  int rc = eval_(f, n, x, y, z, out, e);
  if (rc != GR_OK) return rc;
  long i = first_bad(n, out, NULL, NULL);
  if (i >= 0)
    return gr_fail(e, GR_ENUM, "field %s gave %s at x=%.6g, y=%.6g, z=%.6g", f->desc,
                   isnan(out[i]) ? "nan" : out[i] > 0 ? "inf" : "-inf", x[i], y[i], z[i]);
  return GR_OK;
}

int gr_field_grad(const gr_field *f, size_t n, const double *x,
                  const double *y, const double *z, double *gx, double *gy,
                  double *gz, gr_err *e) {
  if (!f) return gr_fail(e, GR_EARG, "field is missing (NULL)");
  int rc = grad_(f, n, x, y, z, gx, gy, gz, e);
  if (rc != GR_OK) return rc;
  long i = first_bad(n, gx, gy, gz);
  if (i >= 0)
    return gr_fail(e, GR_ENUM, "gradient of field %s is not finite at x=%.6g, y=%.6g, z=%.6g",
                   f->desc, x[i], y[i], z[i]);
  return GR_OK;
}

int gr_field_eval_grad(const gr_field *f, size_t n, const double *x, const double *y,
                       const double *z, double *out, double *gx, double *gy, double *gz, gr_err *e) {
  if (!f) return gr_fail(e, GR_EARG, "field is missing (NULL)");
  if (f->kind != K_TPMS) {
    int rc = gr_field_eval(f, n, x, y, z, out, e);
    return rc ? rc : gr_field_grad(f, n, x, y, z, gx, gy, gz, e);
  }
  tpms_batch(f, n, x, y, z, out, gx, gy, gz); /* one set of sines and cosines for both */
  long i = first_bad(n, out, gx, gy);
  if (i < 0) i = first_bad(n, gz, NULL, NULL);
  if (i >= 0)
    return gr_fail(e, GR_ENUM, "field %s or its gradient is not finite at x=%.6g, y=%.6g, z=%.6g", f->desc,
                   x[i], y[i], z[i]);
  return GR_OK;
}

/* sin and cos of a small angle d, a Newton step's or a difference step's
 * phase (|d| < 0.1: Taylor terms to d^11 and d^12, the rest below 1e-21;
 * below 2e-3 to d^5 and d^6; else libm's). The coefficients are constants
 * (products, not the ten divisions of the nested form: this runs millions
 * of times a job). */
static void small_sincos(double d, double *s, double *c) {
  if (!(fabs(d) < 0.1)) { *s = sin(d); *c = cos(d); return; }
  static const double S3 = -1.0 / 6, S5 = 1.0 / 120, S7 = -1.0 / 5040, S9 = 1.0 / 362880, S11 = -1.0 / 39916800;
  static const double C2 = -1.0 / 2, C4 = 1.0 / 24, C6 = -1.0 / 720, C8 = 1.0 / 40320, C10 = -1.0 / 3628800,
                      C12 = 1.0 / 479001600;
  double d2 = d * d;
  if (d2 < 4e-6) { /* |d| < 2e-3 (most Newton steps): the terms from d^7 on are below 3e-23 */
    *s = d + d * d2 * (S3 + d2 * S5);
    *c = 1 + d2 * (C2 + d2 * (C4 + d2 * C6));
    return;
  }
  *s = d + d * d2 * (S3 + d2 * (S5 + d2 * (S7 + d2 * (S9 + d2 * S11))));
  *c = 1 + d2 * (C2 + d2 * (C4 + d2 * (C6 + d2 * (C8 + d2 * (C10 + d2 * C12)))));
}

/* Phase a of sn, cs advanced by the angle d (the angle-addition rule). */
static void phase_add(double *sn, double *cs, int a, double d) {
  double sd, cd, s0 = sn[a], c0 = cs[a];
  small_sincos(d, &sd, &cd);
  sn[a] = s0 * cd + c0 * sd;
  cs[a] = c0 * cd - s0 * sd;
}

int gr_field_hess_fd(const gr_field *f, const double p[3], double h, double *v, double g[3], double hs[3][3],
                     gr_err *e) {
  gr_field_at at;
  return gr_field_hess_fd_at(f, p, h, v, g, hs, &at, e);
}

int gr_field_move_grad(const gr_field *f, gr_field_at *at, const double dp[3], double *v, double g[3], gr_err *e) {
  if (!f) return gr_fail(e, GR_EARG, "field is missing (NULL)");
  for (int a = 0; a < 3; a++) at->p[a] += dp[a];
  if (!at->trig) return gr_field_eval_grad(f, 1, &at->p[0], &at->p[1], &at->p[2], v, &g[0], &g[1], &g[2], e);
  const double *w = f->w;
  double gl[3];
  for (int a = 0; a < 3; a++) phase_add(at->sn, at->cs, a, w[a] * dp[a]);
  *v = tpms_trig(f->surface, at->sn[0], at->cs[0], at->sn[1], at->cs[1], at->sn[2], at->cs[2], gl) - f->level;
  for (int c = 0; c < 3; c++) g[c] = w[c] * gl[c];
  if (!isfinite(*v) || first_bad(3, g, NULL, NULL) >= 0)
    return gr_fail(e, GR_ENUM, "field %s or its gradient is not finite at x=%.6g, y=%.6g, z=%.6g", f->desc, at->p[0],
                   at->p[1], at->p[2]);
  return GR_OK;
}

/* A TPMS's value and gradient from the phases' sines and cosines in *at
 * (at->p the point), which becomes valid for moves (trig = 1). */
static int tpms_value_at(const gr_field *f, gr_field_at *at, double *v, double g[3], gr_err *e) {
  double gl[3];
  at->trig = 1;
  *v = tpms_trig(f->surface, at->sn[0], at->cs[0], at->sn[1], at->cs[1], at->sn[2], at->cs[2], gl) - f->level;
  for (int c = 0; c < 3; c++) g[c] = f->w[c] * gl[c];
  if (!isfinite(*v) || first_bad(3, g, NULL, NULL) >= 0)
    return gr_fail(e, GR_ENUM, "field %s or its gradient is not finite at x=%.6g, y=%.6g, z=%.6g", f->desc, at->p[0],
                   at->p[1], at->p[2]);
  return GR_OK;
}

int gr_field_grad_at(const gr_field *f, const double p[3], double *v, double g[3], gr_field_at *at, gr_err *e) {
  if (!f) return gr_fail(e, GR_EARG, "field is missing (NULL)");
  memcpy(at->p, p, sizeof at->p);
  at->trig = 0;
  if (f->kind != K_TPMS) return gr_field_eval_grad(f, 1, &p[0], &p[1], &p[2], v, &g[0], &g[1], &g[2], e);
  for (int a = 0; a < 3; a++) {
    double X = tpms_phase(f, a, p[a]);
    at->sn[a] = sin(X);
    at->cs[a] = cos(X);
  }
  return tpms_value_at(f, at, v, g, e);
}

int gr_field_grad_at_n(const gr_field *f, size_t n, const double *p, double *v, double *g, gr_field_at *at,
                       gr_err *e) {
  if (!f) return gr_fail(e, GR_EARG, "field is missing (NULL)");
  if (f->kind != K_TPMS) {
    for (size_t i = 0; i < n; i++)
      if (gr_field_grad_at(f, p + 3 * i, v + i, g + 3 * i, at + i, e)) return e->code;
    return GR_OK;
  }
  enum { B = 128 };
  double sn[3 * B], cs[3 * B];
  for (size_t s = 0; s < n; s += B) {
    size_t m = n - s < B ? n - s : B;
    for (size_t i = 0; i < m; i++)
      for (int a = 0; a < 3; a++) sn[3 * i + a] = cs[3 * i + a] = tpms_phase(f, a, p[3 * (s + i) + a]);
    gr_vsin(3 * m, sn);
    gr_vcos(3 * m, cs);
    for (size_t i = 0; i < m; i++) {
      gr_field_at *t = at + s + i;
      memcpy(t->p, p + 3 * (s + i), sizeof t->p);
      memcpy(t->sn, sn + 3 * i, sizeof t->sn);
      memcpy(t->cs, cs + 3 * i, sizeof t->cs);
      if (tpms_value_at(f, t, v + s + i, g + 3 * (s + i), e)) return e->code;
    }
  }
  return GR_OK;
}

void gr_field_step_init(const gr_field *f, double h, gr_field_step *st) {
  st->h = h;
  for (int a = 0; a < 3; a++) {
    st->sn[a] = 0;
    st->cs[a] = 1;
    if (f && f->kind == K_TPMS) small_sincos(f->w[a] * h, &st->sn[a], &st->cs[a]);
  }
}

int gr_field_hess_fd_at(const gr_field *f, const double p[3], double h, double *v, double g[3], double hs[3][3],
                        gr_field_at *at, gr_err *e) {
  gr_field_step st;
  gr_field_step_init(f, h, &st);
  return gr_field_hess_fd_step(f, p, &st, v, g, hs, at, e);
}

int gr_field_hess_fd_step(const gr_field *f, const double p[3], const gr_field_step *st, double *v, double g[3],
                          double hs[3][3], gr_field_at *at, gr_err *e) {
  int rc = gr_field_grad_at(f, p, v, g, at, e); /* (the step is checked by gr_field_hess_fd_moved) */
  return rc ? rc : gr_field_hess_fd_moved(f, at, st, g, hs, e);
}

int gr_field_hess_fd_moved(const gr_field *f, const gr_field_at *at, const gr_field_step *st, const double g[3],
                           double hs[3][3], gr_err *e) {
  double h = st->h;
  const double *p = at->p;
  if (!f) return gr_fail(e, GR_EARG, "field is missing (NULL)");
  if (!(h > 0) || !isfinite(h)) return gr_fail(e, GR_EARG, "Hessian step must be > 0, got %g", h);
  int rc = GR_OK;
  if (!at->trig) {
    for (int a = 0; a < 3 && rc == GR_OK; a++) {
      double y[3] = {p[0], p[1], p[2]};
      y[a] += h;
      rc = gr_field_grad(f, 1, &y[0], &y[1], &y[2], &hs[a][0], &hs[a][1], &hs[a][2], e);
      for (int c = 0; c < 3 && rc == GR_OK; c++) hs[a][c] = (hs[a][c] - g[c]) / h;
    }
    return rc;
  }
  const double *w = f->w;
  for (int a = 0; a < 3; a++) {
    double s2[3] = {at->sn[0], at->sn[1], at->sn[2]}, c2[3] = {at->cs[0], at->cs[1], at->cs[2]}, g2[3];
    /* phase_add(s2, c2, a, w[a] * h), its small_sincos made once in st */
    double s0 = s2[a], c0 = c2[a];
    s2[a] = s0 * st->cs[a] + c0 * st->sn[a];
    c2[a] = c0 * st->cs[a] - s0 * st->sn[a];
    tpms_trig(f->surface, s2[0], c2[0], s2[1], c2[1], s2[2], c2[2], g2);
    for (int c = 0; c < 3; c++) hs[a][c] = (w[c] * g2[c] - g[c]) / h;
  }
  if (first_bad(3, hs[0], hs[1], hs[2]) >= 0)
    return gr_fail(e, GR_ENUM, "field %s or its derivatives are not finite at x=%.6g, y=%.6g, z=%.6g", f->desc, p[0],
                   p[1], p[2]);
  return GR_OK;
}

/* ---- sampling ---- */
#define GRID_LIMIT_BYTES 4294967296.0 /* 4 GiB */
#define SAMPLE_CHUNK 4096

static int check_axes(int dim, const double *lo, const double *hi, const int *n, gr_err *e) {
  static const char ax[3] = {'x', 'y', 'z'};
  for (int i = 0; i < dim; i++) {
    if (n[i] < 2) return gr_fail(e, GR_EARG, "grid samples along %c must be >= 2, got %d", ax[i], n[i]);
    if (!isfinite(lo[i]) || !isfinite(hi[i]) || !(hi[i] > lo[i]))
      return gr_fail(e, GR_EARG, "grid bounds along %c must be finite with hi > lo, got lo=%g, hi=%g",
                     ax[i], lo[i], hi[i]);
  }
  return GR_OK;
}

/* Evaluate f at `total` grid points whose coordinates coord(k) gives, in
 * chunks, straight into v. */
typedef struct grid_axes {
  int dim;              /* 2 or 3 */
  int n[3];             /* samples per axis */
  double lo[3], h[3];   /* start and step, mm */
  double z;             /* plane height for dim 2 */
} grid_axes;

/* Plain TPMS fields on a grid: the sines and cosines of each axis' samples
 * are computed once (nx + ny + nz pairs instead of 3 per sample). */
static int fill_grid_tpms(const gr_field *f, const grid_axes *g, double *v, gr_err *e) {
  int nz = g->dim == 3 ? g->n[2] : 1, cnt = g->n[0] + g->n[1] + nz;
  size_t room = vsincos_room((size_t)cnt);
  double *t = malloc(2 * room * sizeof *t);
  if (!t) return gr_fail(e, GR_EMEM, "out of memory sampling %s", f->desc);
  double *s[3] = {t, t + g->n[0], t + g->n[0] + g->n[1]};
  double *c[3] = {s[0] + room, s[1] + room, s[2] + room};
  for (int a = 0; a < 3; a++) {
    int n = a < 2 ? g->n[a] : nz;
    for (int i = 0; i < n; i++) s[a][i] = tpms_phase(f, a, a == 2 && g->dim == 2 ? g->z : g->lo[a] + i * g->h[a]);
  }
  vsincos((size_t)cnt, t, t + room); /* as tpms_batch: the same bits as gr_field_eval */
  size_t q = 0;
  for (int k = 0; k < nz; k++)
    for (int j = 0; j < g->n[1]; j++)
      for (int i = 0; i < g->n[0]; i++)
        v[q++] = tpms_trig(f->surface, s[0][i], c[0][i], s[1][j], c[1][j], s[2][k], c[2][k],
                           NULL) - f->level;
  free(t);
  return GR_OK;
}

static int fill_grid(const gr_field *f, const grid_axes *g, size_t total, double *v, gr_err *e) {
  if (f->kind == K_TPMS) return fill_grid_tpms(f, g, v, e);
  double *buf = malloc(3 * SAMPLE_CHUNK * sizeof *buf);
  if (!buf) return gr_fail(e, GR_EMEM, "out of memory sampling %s", f->desc);
  double *px = buf, *py = buf + SAMPLE_CHUNK, *pz = buf + 2 * SAMPLE_CHUNK;
  int rc = GR_OK;
  size_t nx = (size_t)g->n[0], ny = (size_t)g->n[1];
  for (size_t o = 0; o < total && rc == GR_OK; o += SAMPLE_CHUNK) {
    size_t m = total - o < SAMPLE_CHUNK ? total - o : SAMPLE_CHUNK;
    size_t k = o;
    size_t i = k % nx, j = (k / nx) % ny, l = k / (nx * ny);
    for (size_t q = 0; q < m; q++) {
      px[q] = g->lo[0] + (double)i * g->h[0];
      py[q] = g->lo[1] + (double)j * g->h[1];
      pz[q] = g->dim == 3 ? g->lo[2] + (double)l * g->h[2] : g->z;
      if (++i == nx) { i = 0; if (++j == ny) { j = 0; l++; } }
    }
    rc = gr_field_eval(f, m, px, py, pz, v + o, e);
  }
  free(buf);
  return rc;
}

int gr_field_plane(const gr_field *f, double z, const double lo[2], const double h[2], const int n[2], double *out,
                   gr_err *e) {
  if (!f || !lo || !h || !n || !out) return gr_fail(e, GR_EARG, "plane sample: missing argument");
  if (n[0] < 1 || n[1] < 1) return gr_fail(e, GR_EARG, "plane sample: %d x %d samples", n[0], n[1]);
  grid_axes a = {2, {n[0], n[1], 1}, {lo[0], lo[1], 0}, {h[0], h[1], 0}, z};
  return fill_grid(f, &a, (size_t)n[0] * n[1], out, e);
}

gr_grid3 *gr_grid3_sample(const gr_field *f, const double lo[3],
                          const double hi[3], const int n[3], gr_err *e) {
  if (!f || !lo || !hi || !n) { gr_fail(e, GR_EARG, "grid3 sample: missing argument"); return NULL; }
  if (check_axes(3, lo, hi, n, e)) return NULL;
  double count = (double)n[0] * n[1] * n[2], bytes = count * sizeof(double);
  if (bytes > GRID_LIMIT_BYTES || count > (double)SIZE_MAX / sizeof(double)) {
    gr_fail(e, GR_EMEM, "grid of %d x %d x %d samples needs %.0f MB, over the %.0f MB limit; "
            "use fewer samples or a smaller box", n[0], n[1], n[2], bytes / 1048576.0,
            GRID_LIMIT_BYTES / 1048576.0);
    return NULL;
  }
  gr_grid3 *g = calloc(1, sizeof *g);
  if (g) g->v = malloc((size_t)count * sizeof *g->v);
  if (!g || !g->v) {
    free(g);
    gr_fail(e, GR_EMEM, "out of memory: grid of %d x %d x %d samples needs %.0f MB", n[0], n[1],
            n[2], bytes / 1048576.0);
    return NULL;
  }
  g->nx = n[0]; g->ny = n[1]; g->nz = n[2];
  g->x0 = lo[0]; g->y0 = lo[1]; g->z0 = lo[2];
  g->hx = (hi[0] - lo[0]) / (n[0] - 1);
  g->hy = (hi[1] - lo[1]) / (n[1] - 1);
  g->hz = (hi[2] - lo[2]) / (n[2] - 1);
  grid_axes a = {3, {n[0], n[1], n[2]}, {lo[0], lo[1], lo[2]}, {g->hx, g->hy, g->hz}, 0};
  if (fill_grid(f, &a, (size_t)count, g->v, e)) { gr_grid3_free(g); return NULL; }
  return g;
}

gr_grid2 *gr_grid2_sample(const gr_field *f, double z, const double lo[2],
                          const double hi[2], const int n[2], gr_err *e) {
  if (!f || !lo || !hi || !n) { gr_fail(e, GR_EARG, "grid2 sample: missing argument"); return NULL; }
  if (check_axes(2, lo, hi, n, e)) return NULL;
  if (!isfinite(z)) { gr_fail(e, GR_EARG, "plane height z must be finite, got %g", z); return NULL; }
  double count = (double)n[0] * n[1], bytes = count * sizeof(double);
  if (bytes > GRID_LIMIT_BYTES || count > (double)SIZE_MAX / sizeof(double)) {
    gr_fail(e, GR_EMEM, "grid of %d x %d samples needs %.0f MB, over the %.0f MB limit; "
            "use fewer samples or a smaller box", n[0], n[1], bytes / 1048576.0,
            GRID_LIMIT_BYTES / 1048576.0);
    return NULL;
  }
  gr_grid2 *g = calloc(1, sizeof *g);
  if (g) g->v = malloc((size_t)count * sizeof *g->v);
  if (!g || !g->v) {
    free(g);
    gr_fail(e, GR_EMEM, "out of memory: grid of %d x %d samples needs %.0f MB", n[0], n[1],
            bytes / 1048576.0);
    return NULL;
  }
  g->nx = n[0]; g->ny = n[1];
  g->x0 = lo[0]; g->y0 = lo[1]; g->z = z;
  g->hx = (hi[0] - lo[0]) / (n[0] - 1);
  g->hy = (hi[1] - lo[1]) / (n[1] - 1);
  double h[2] = {g->hx, g->hy};
  if (gr_field_plane(f, z, lo, h, n, g->v, e)) { gr_grid2_free(g); return NULL; }
  return g;
}

void gr_grid3_free(gr_grid3 *g) {
  if (!g) return;
  free(g->v);
  free(g);
}

void gr_grid2_free(gr_grid2 *g) {
  if (!g) return;
  free(g->v);
  free(g);
}
