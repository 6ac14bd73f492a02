/* mc.c: marching cubes without a hand-typed case table.
 *
 * Each cube is handled through its six faces. On each face, marching squares
 * produces oriented segments (positive region on the left, seen from outside
 * the cube); an ambiguous face (diagonal sign pattern) is decided by the face
 * centre (bilinear mean) alone, so the two cubes sharing the face agree and
 * the surface has no cracks. The segments chain into closed loops around the
 * cube (every crossing ends one segment and starts another), and each loop
 * is triangulated by a small dynamic programme that maximises the worst
 * triangle quality while never using a diagonal whose ends lie on a common
 * cube face (such a diagonal could also be chosen by the neighbour cube and
 * make a non-manifold edge). In the rare loop where no such triangulation
 * exists, a vertex at the loop centroid is added and the loop fanned from it.
 * A loop traversed this way has its normal pointing to the positive side.
 *
 * Vertices live on grid edges, one per crossed edge, kept in slab arrays of
 * edge -> vertex index, so nothing is duplicated. */
#include "mc.h"
#include "pool.h"

#include <math.h>
#include <stdlib.h>
#include <string.h>

#define NOV UINT32_MAX
/* Crossing parameter kept in [EPS, 1-EPS] so no vertex sits on a grid corner
 * (distinct vertices then never coincide, even after float32 output). */
#define EPS 1e-3

/* Corner c of a cube is at offset (c&1, (c>>1)&1, (c>>2)&1). Faces list
 * their corners counter-clockwise seen from outside the cube. */
static const int FACE[6][4] = {{0, 4, 6, 2}, {1, 3, 7, 5}, {0, 1, 5, 4},
                               {2, 6, 7, 3}, {0, 2, 3, 1}, {4, 5, 7, 6}};

/* Local edge index of the cube edge joining corners a and b (differ in one
 * bit): axis*4 + the two other offset bits. */
static int edge_id(int a, int b) {
  int lo = a < b ? a : b, d = (a ^ b) == 1 ? 0 : (a ^ b) == 2 ? 1 : 2;
  int o = d == 0 ? (lo >> 1) & 3 : d == 1 ? (lo & 1) | (((lo >> 2) & 1) << 1)
                                          : lo & 3;
  return d * 4 + o;
}

/* Bit mask of the faces containing each local edge, for the diagonal rule. */
static void edge_face_masks(int mask[12]) {
  memset(mask, 0, 12 * sizeof *mask);
  for (int f = 0; f < 6; f++)
    for (int s = 0; s < 4; s++)
      mask[edge_id(FACE[f][s], FACE[f][(s + 1) & 3])] |= 1 << f;
}

typedef struct mc_state {
  gr_mesh *m;
  int nx, ny;
  double x0, y0, z0, hx, hy, hz, iso;
  uint32_t *xe[2], *ye[2], *ze; /* edge -> vertex for planes k, k+1 */
  int fmask[12];
  /* refinement bookkeeping: vertices created in the current slab */
  size_t *rv;          /* vertex index */
  double *rd;          /* per vertex: p0[3], p1[3], v0, v1 */
  size_t nr, capr, capd;
} mc_state;

/* Add the vertex on the edge from p0 (value a) to p0+dir*h (value b). */
static int edge_vertex(mc_state *s, double a, double b, const double p0[3],
                       int axis, double h, uint32_t *out) {
  double t = (s->iso - a) / (b - a);
  if (!(t >= EPS)) t = EPS;
  if (t > 1 - EPS) t = 1 - EPS;
  double p[3] = {p0[0], p0[1], p0[2]};
  p[axis] += t * h;
  long id = gr_mesh_add_vertex(s->m, p[0], p[1], p[2]);
  if (id < 0 || (unsigned long)id >= NOV) return GR_EMEM;
  *out = (uint32_t)id;
  if (s->rd) { /* remember it for refinement */
    if (gr_grow(&s->rv, &s->capr, s->nr + 1, sizeof *s->rv)) return GR_EMEM;
    if (gr_grow(&s->rd, &s->capd, 8 * (s->nr + 1), sizeof *s->rd)) return GR_EMEM;
    double *d = s->rd + 8 * s->nr;
    d[0] = p0[0]; d[1] = p0[1]; d[2] = p0[2];
    d[3] = p0[0]; d[4] = p0[1]; d[5] = p0[2];
    d[3 + axis] += h;
    d[6] = a; d[7] = b;
    s->rv[s->nr++] = (uint32_t)id;
  }
  return GR_OK;
}

/* Vertices on the x and y edges of one plane of samples P at height z. */
static int plane_edges(mc_state *s, const double *P, double z, uint32_t *xe,
                       uint32_t *ye) {
  int nx = s->nx, ny = s->ny;
  for (int j = 0; j < ny; j++)
    for (int i = 0; i < nx; i++) {
      size_t q = (size_t)j * nx + i;
      double p0[3] = {s->x0 + i * s->hx, s->y0 + j * s->hy, z};
      double a = P[q];
      xe[q] = ye[q] = NOV;
      if (i + 1 < nx && ((a >= s->iso) != (P[q + 1] >= s->iso)))
        if (edge_vertex(s, a, P[q + 1], p0, 0, s->hx, &xe[q])) return GR_EMEM;
      if (j + 1 < ny && ((a >= s->iso) != (P[q + nx] >= s->iso)))
        if (edge_vertex(s, a, P[q + nx], p0, 1, s->hy, &ye[q])) return GR_EMEM;
    }
  return GR_OK;
}

/* Vertices on the z edges between planes P0 (height z) and P1. */
static int z_edges(mc_state *s, const double *P0, const double *P1, double z) {
  for (int j = 0; j < s->ny; j++)
    for (int i = 0; i < s->nx; i++) {
      size_t q = (size_t)j * s->nx + i;
      double p0[3] = {s->x0 + i * s->hx, s->y0 + j * s->hy, z};
      s->ze[q] = NOV;
      if ((P0[q] >= s->iso) != (P1[q] >= s->iso))
        if (edge_vertex(s, P0[q], P1[q], p0, 2, s->hz, &s->ze[q])) return GR_EMEM;
    }
  return GR_OK;
}

/* Shape quality of a triangle in [0,1]: 4 sqrt(3) area / sum of squared
 * edge lengths (1 for equilateral, 0 for degenerate). */
static double tri_quality(const double *a, const double *b, const double *c) {
  double u[3], v[3], w[3], n[3];
  for (int i = 0; i < 3; i++) { u[i] = b[i] - a[i]; v[i] = c[i] - a[i]; w[i] = c[i] - b[i]; }
  n[0] = u[1] * v[2] - u[2] * v[1];
  n[1] = u[2] * v[0] - u[0] * v[2];
  n[2] = u[0] * v[1] - u[1] * v[0];
  double area2 = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  double l = u[0] * u[0] + u[1] * u[1] + u[2] * u[2] + v[0] * v[0] +
             v[1] * v[1] + v[2] * v[2] + w[0] * w[0] + w[1] * w[1] + w[2] * w[2];
  return l > 0 ? 2 * sqrt(3.0) * area2 / l : 0;
}

/* Triangulate one loop (vertex ids vid, local edges le, k vertices, in the
 * orientation that makes normals point to the positive side). */
static int emit_loop(mc_state *s, const uint32_t *vid, const int *le, int k) {
  gr_mesh *m = s->m;
  if (k == 3) return gr_mesh_add_face(m, vid[0], vid[1], vid[2]);
  double best[12][12];
  int arg[12][12];
  arg[0][k - 1] = -1;
  for (int len = 2; len < k; len++)
    for (int i = 0; i + len < k; i++) {
      int j = i + len;
      best[i][j] = -1;
      arg[i][j] = -1;
      /* diagonal i-j must be allowed unless it is the loop's closing edge */
      if (!(i == 0 && j == k - 1) && (s->fmask[le[i]] & s->fmask[le[j]]))
        continue;
      for (int mm = i + 1; mm < j; mm++) {
        double q = tri_quality(m->v + 3 * (size_t)vid[i], m->v + 3 * (size_t)vid[mm],
                               m->v + 3 * (size_t)vid[j]);
        if (mm - i > 1) q = fmin(q, best[i][mm]);
        if (j - mm > 1) q = fmin(q, best[mm][j]);
        if ((mm - i > 1 && arg[i][mm] < 0) || (j - mm > 1 && arg[mm][j] < 0)) continue;
        if (q > best[i][j]) { best[i][j] = q; arg[i][j] = mm; }
      }
    }
  if (arg[0][k - 1] >= 0) {
    int stack[24][2], sp = 0;
    stack[sp][0] = 0; stack[sp][1] = k - 1; sp++;
    while (sp) {
      sp--;
      int i = stack[sp][0], j = stack[sp][1], mm = arg[i][j];
      if (gr_mesh_add_face(m, vid[i], vid[mm], vid[j])) return GR_EMEM;
      if (mm - i > 1) { stack[sp][0] = i; stack[sp][1] = mm; sp++; }
      if (j - mm > 1) { stack[sp][0] = mm; stack[sp][1] = j; sp++; }
    }
    return GR_OK;
  }
  /* no admissible triangulation: fan from the centroid */
  double c[3] = {0, 0, 0};
  for (int i = 0; i < k; i++)
    for (int d = 0; d < 3; d++) c[d] += m->v[3 * (size_t)vid[i] + d] / k;
  long ci = gr_mesh_add_vertex(m, c[0], c[1], c[2]);
  if (ci < 0) return GR_EMEM;
  for (int i = 0; i < k; i++)
    if (gr_mesh_add_face(m, (uint32_t)ci, vid[i], vid[(i + 1) % k])) return GR_EMEM;
  return GR_OK;
}

/* One cube with corner values v[8] and local edge -> vertex map ev[12]. */
static int do_cube(mc_state *s, const double v[8], const uint32_t ev[12]) {
  int next[12];
  for (int i = 0; i < 12; i++) next[i] = -1;
  for (int f = 0; f < 6; f++) {
    const int *c = FACE[f];
    int pos[4], np = 0;
    for (int i = 0; i < 4; i++) np += pos[i] = v[c[i]] >= s->iso;
    if (np == 0 || np == 4) continue;
    int starts[2], ends[2], ns = 0, ne = 0;
    for (int i = 0; i < 4; i++) {
      int j = (i + 1) & 3;
      if (pos[i] && !pos[j]) starts[ns++] = i;
      else if (!pos[i] && pos[j]) ends[ne++] = i;
    }
    if (ns == 1) {
      next[edge_id(c[starts[0]], c[(starts[0] + 1) & 3])] =
          edge_id(c[ends[0]], c[(ends[0] + 1) & 3]);
      continue;
    }
    /* ambiguous: sum positive pair and negative pair separately so both
     * cubes sharing the face compute the same value bit for bit */
    double sp = pos[0] ? v[c[0]] + v[c[2]] : v[c[1]] + v[c[3]];
    double sn = pos[0] ? v[c[1]] + v[c[3]] : v[c[0]] + v[c[2]];
    int joined = sp + sn >= 4 * s->iso;
    for (int t = 0; t < 2; t++) {
      int i = starts[t], j = joined ? (i + 1) & 3 : (i + 3) & 3;
      next[edge_id(c[i], c[(i + 1) & 3])] = edge_id(c[j], c[(j + 1) & 3]);
    }
  }
  int seen[12] = {0};
  for (int e0 = 0; e0 < 12; e0++) {
    if (next[e0] < 0 || seen[e0]) continue;
    uint32_t vid[12];
    int le[12], k = 0;
    for (int e = e0; !seen[e]; e = next[e]) {
      if (e < 0 || k >= 12 || ev[e] == NOV) return GR_EGEOM; /* cannot happen */
      seen[e] = 1;
      le[k] = e;
      vid[k++] = ev[e];
    }
    if (k >= 3 && emit_loop(s, vid, le, k)) return GR_EMEM;
  }
  return GR_OK;
}

/* All cubes between planes P0 and P1 (cube layer k). */
static int cube_layer(mc_state *s, const double *P0, const double *P1) {
  int nx = s->nx;
  for (int j = 0; j + 1 < s->ny; j++)
    for (int i = 0; i + 1 < nx; i++) {
      size_t q = (size_t)j * nx + i;
      double v[8] = {P0[q], P0[q + 1], P0[q + nx], P0[q + nx + 1],
                     P1[q], P1[q + 1], P1[q + nx], P1[q + nx + 1]};
      int np = 0;
      for (int c = 0; c < 8; c++) np += v[c] >= s->iso;
      if (np == 0 || np == 8) continue;
      uint32_t ev[12];
      for (int o = 0; o < 4; o++) {
        int b1 = o & 1, b2 = o >> 1;
        ev[o] = s->xe[b2][q + (size_t)b1 * nx];     /* x edge, y+b1, z+b2 */
        ev[4 + o] = s->ye[b2][q + b1];              /* y edge, x+b1, z+b2 */
        ev[8 + o] = s->ze[q + b1 + (size_t)b2 * nx]; /* z edge, x+b1, y+b2 */
      }
      int rc = do_cube(s, v, ev);
      if (rc) return rc;
    }
  return GR_OK;
}

/* Move the vertices created in this slab onto the field's zero along their
 * edges: Illinois-modified regula falsi, batched over all vertices. */
static int refine_slab(mc_state *s, const gr_field *f, gr_err *e) {
  size_t n = s->nr;
  if (!n) return GR_OK;
  double *buf = malloc(n * 11 * sizeof *buf);
  if (!buf) return gr_fail(e, GR_EMEM, "out of memory refining %zu vertices", n);
  double *x = buf, *y = x + n, *z = y + n, *out = z + n, *ta = out + n,
         *tb = ta + n, *fa = tb + n, *fb = fa + n, *t = fb + n, *side = t + n,
         *tmp = side + n;
  (void)tmp;
  for (size_t i = 0; i < n; i++) {
    const double *d = s->rd + 8 * i;
    ta[i] = 0; tb[i] = 1; fa[i] = d[6] - s->iso; fb[i] = d[7] - s->iso;
    t[i] = fa[i] / (fa[i] - fb[i]);
    side[i] = 0;
  }
  int rc = GR_OK;
  for (int it = 0; it < 6 && rc == GR_OK; it++) {
    for (size_t i = 0; i < n; i++) {
      const double *d = s->rd + 8 * i;
      x[i] = d[0] + t[i] * (d[3] - d[0]);
      y[i] = d[1] + t[i] * (d[4] - d[1]);
      z[i] = d[2] + t[i] * (d[5] - d[2]);
    }
    rc = gr_field_eval(f, n, x, y, z, out, e);
    if (rc) break;
    for (size_t i = 0; i < n; i++) {
      double ft = out[i] - s->iso;
      if (ta[i] == tb[i]) continue; /* on the zero already */
      if (ft == 0) { /* an exact zero (a sample equal to iso at an end, too) */
        ta[i] = tb[i] = t[i];
        continue;
      }
      if ((ft >= 0) == (fa[i] >= 0)) {
        ta[i] = t[i]; fa[i] = ft;
        if (side[i] < 0) fb[i] *= 0.5;
        side[i] = -1;
      } else {
        tb[i] = t[i]; fb[i] = ft;
        if (side[i] > 0) fa[i] *= 0.5;
        side[i] = 1;
      }
      double den = fa[i] - fb[i];
      t[i] = den != 0 ? ta[i] + fa[i] / den * (tb[i] - ta[i]) : 0.5 * (ta[i] + tb[i]);
      if (!(t[i] > ta[i] && t[i] < tb[i])) t[i] = 0.5 * (ta[i] + tb[i]);
    }
  }
  if (rc == GR_OK)
    for (size_t i = 0; i < n; i++) {
      const double *d = s->rd + 8 * i;
      double tt = t[i] < EPS ? EPS : t[i] > 1 - EPS ? 1 - EPS : t[i];
      double *p = s->m->v + 3 * s->rv[i];
      for (int c = 0; c < 3; c++) p[c] = d[c] + tt * (d[3 + c] - d[c]);
    }
  free(buf);
  s->nr = 0;
  return rc;
}

typedef int (*plane_fn)(void *ud, int k, double *out, gr_err *e);

/* The slab loop shared by gr_mc and gr_mc_field. Planes are fetched one at a
 * time through get (into one of two buffers); f != NULL refines crossings. */
static gr_mesh *mc_run(mc_state *s, int nz, plane_fn get, void *ud,
                       const gr_field *f, gr_err *e) {
  size_t np = (size_t)s->nx * s->ny;
  s->m = gr_mesh_new();
  double *P[2] = {malloc(np * sizeof(double)), malloc(np * sizeof(double))};
  uint32_t *buf = malloc(5 * np * sizeof *buf);
  int rc = GR_OK;
  if (!s->m || !P[0] || !P[1] || !buf) {
    rc = gr_fail(e, GR_EMEM, "out of memory for marching cubes (%d x %d slab)",
                 s->nx, s->ny);
    goto done;
  }
  s->xe[0] = buf; s->xe[1] = buf + np; s->ye[0] = buf + 2 * np;
  s->ye[1] = buf + 3 * np; s->ze = buf + 4 * np;
  edge_face_masks(s->fmask);
  if ((rc = get(ud, 0, P[0], e))) goto done;
  if (plane_edges(s, P[0], s->z0, s->xe[0], s->ye[0])) goto oom;
  for (int k = 0; k + 1 < nz; k++) {
    if ((rc = get(ud, k + 1, P[1], e))) goto done;
    double z = s->z0 + k * s->hz;
    if (plane_edges(s, P[1], z + s->hz, s->xe[1], s->ye[1])) goto oom;
    if (z_edges(s, P[0], P[1], z)) goto oom;
    if (f && (rc = refine_slab(s, f, e))) goto done;
    rc = cube_layer(s, P[0], P[1]);
    if (rc == GR_EMEM) goto oom;
    if (rc) { gr_fail(e, rc, "marching cubes: inconsistent loop in layer %d", k); goto done; }
    double *tp = P[0]; P[0] = P[1]; P[1] = tp;
    uint32_t *t1 = s->xe[0]; s->xe[0] = s->xe[1]; s->xe[1] = t1;
    uint32_t *t2 = s->ye[0]; s->ye[0] = s->ye[1]; s->ye[1] = t2;
  }
  goto done;
oom:
  rc = gr_fail(e, GR_EMEM, "out of memory in marching cubes (%zu vertices, %zu faces so far)",
               s->m->nv, s->m->nf);
done:
  free(P[0]); free(P[1]); free(buf); free(s->rv); free(s->rd);
  if (rc) { gr_mesh_free(s->m); return NULL; }
  return s->m;
}

static int grid_plane(void *ud, int k, double *out, gr_err *e) {
  (void)e;
  const gr_grid3 *g = ud;
  size_t np = (size_t)g->nx * g->ny;
  memcpy(out, g->v + np * k, np * sizeof *out);
  return GR_OK;
}

static int check_dims(const int n[3], gr_err *e) {
  const char *ax = "xyz";
  for (int i = 0; i < 3; i++)
    if (n[i] < 2)
      return gr_fail(e, GR_EARG, "samples along %c must be >= 2, got %d", ax[i], n[i]);
  return GR_OK;
}

gr_mesh *gr_mc(const gr_grid3 *g, double iso, gr_err *e) {
  gr_err_clear(e);
  if (!g || !g->v) { gr_fail(e, GR_EARG, "grid must not be NULL"); return NULL; }
  int n[3] = {g->nx, g->ny, g->nz};
  if (check_dims(n, e)) return NULL;
  if (!isfinite(iso)) { gr_fail(e, GR_ENUM, "iso must be finite, got %g", iso); return NULL; }
  mc_state s = {0};
  s.nx = g->nx; s.ny = g->ny; s.iso = iso;
  s.x0 = g->x0; s.y0 = g->y0; s.z0 = g->z0; s.hx = g->hx; s.hy = g->hy; s.hz = g->hz;
  return mc_run(&s, g->nz, grid_plane, (void *)g, NULL, e);
}

typedef struct field_planes {
  const gr_field *f;
  mc_state *s;
  double *all; /* every plane's samples (taken in parallel), or NULL: one at a time */
} field_planes;

/* Plane k's samples into out. */
static int sample_plane(const field_planes *fp, int k, double *out, gr_err *e) {
  const mc_state *s = fp->s;
  double lo[2] = {s->x0, s->y0}, h[2] = {s->hx, s->hy};
  int n[2] = {s->nx, s->ny};
  return gr_field_plane(fp->f, s->z0 + k * s->hz, lo, h, n, out, e);
}

static int field_plane(void *ud, int k, double *out, gr_err *e) {
  field_planes *fp = ud;
  size_t np = (size_t)fp->s->nx * fp->s->ny;
  if (fp->all) {
    memcpy(out, fp->all + np * k, np * sizeof *out);
    return GR_OK;
  }
  return sample_plane(fp, k, out, e);
}

/* Pool item: plane k sampled into fp->all. */
static int plane_item(void *ud, int k, gr_err *e) {
  field_planes *fp = ud;
  size_t np = (size_t)fp->s->nx * fp->s->ny;
  return sample_plane(fp, k, fp->all + np * k, e);
}

/* Samples of all planes held at once for parallel sampling up to this size. */
#define MC_ALL_BYTES (256.0 * 1024 * 1024)

gr_mesh *gr_mc_field(const gr_field *f, const double lo[3], const double hi[3],
                     const int n[3], int refine, gr_err *e) {
  return gr_mc_field_mt(f, lo, hi, n, refine, 1, e);
}

gr_mesh *gr_mc_field_mt(const gr_field *f, const double lo[3], const double hi[3],
                        const int n[3], int refine, int threads, gr_err *e) {
  gr_err_clear(e);
  if (!f) { gr_fail(e, GR_EARG, "field must not be NULL"); return NULL; }
  if (check_dims(n, e)) return NULL;
  const char *ax = "xyz";
  for (int i = 0; i < 3; i++)
    if (!isfinite(lo[i]) || !isfinite(hi[i]) || !(hi[i] > lo[i])) {
      gr_fail(e, GR_EARG, "box must have hi > lo, got %c from %g to %g", ax[i], lo[i], hi[i]);
      return NULL;
    }
  mc_state s = {0};
  s.nx = n[0]; s.ny = n[1]; s.iso = 0;
  s.x0 = lo[0]; s.y0 = lo[1]; s.z0 = lo[2];
  s.hx = (hi[0] - lo[0]) / (n[0] - 1);
  s.hy = (hi[1] - lo[1]) / (n[1] - 1);
  s.hz = (hi[2] - lo[2]) / (n[2] - 1);
  size_t np = (size_t)n[0] * n[1];
  if (np > ((size_t)1 << 31) / 8) {
    gr_fail(e, GR_EMEM, "marching cubes slab of %d x %d samples needs about %.1f GB",
            n[0], n[1], np * 64.0 / 1e9);
    return NULL;
  }
  field_planes fp = {f, &s, NULL};
  if (refine) { /* mark refinement on: rd non-NULL */
    s.capd = 64;
    s.rd = malloc(s.capd * sizeof *s.rd);
    if (!s.rd) { gr_fail(e, GR_EMEM, "out of memory"); return NULL; }
  }
  if (threads > 1 && gr_field_threadsafe(f) && (double)np * n[2] * sizeof(double) <= MC_ALL_BYTES &&
      (fp.all = malloc(np * (size_t)n[2] * sizeof *fp.all)) &&
      gr_pool_for(n[2], plane_item, &fp, threads, NULL, NULL, NULL, e)) {
    free(fp.all);
    free(s.rd);
    return NULL;
  }
  gr_mesh *m = mc_run(&s, n[2], field_plane, &fp, refine ? f : NULL, e);
  free(fp.all);
  return m;
}
