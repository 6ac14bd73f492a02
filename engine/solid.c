/* solid.c: the signed distance to a closed triangle mesh, see solid.h.
 * Validation (in this order): vertices and indices, degenerate faces, edge
 * pairing and orientation, self-intersection (a uniform grid of the faces'
 * boxes, then an exact-with-tolerance triangle-triangle test on the pairs
 * that share a grid cell), enclosed volume. Evaluation: the BVH closest
 * point (bvh.h), searched once per group of nearby points for the faces
 * that may hold it where those are few (solid_group), signed by the
 * pseudo-normal of its feature. */
#include "solid.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>
#include "distance.h"

typedef struct solid {
  gr_mesh *m;     /* own copy of the mesh */
  gr_bvh *bvh;
  double *fn;     /* 3 per face: unit normal */
  double *en;     /* 9 per face: pseudo-normal of edge k (vertex k to k+1) */
  double *vn;     /* 3 per vertex: angle-weighted pseudo-normal */
  double *el;     /* 4 per face: edge lengths (vertex k to k+1), 1e-9 x the longest */
  uint32_t *patch; /* per face: its planar patch (the lowest face of it) */
  unsigned char *bmask; /* per face: bit k set when edge k bounds its patch */
  double sign;    /* +1, or -1 when the mesh's normals point inward */
} solid;

static void solid_free(void *ud) {
  solid *s = ud;
  if (!s) return;
  gr_bvh_free(s->bvh);
  gr_mesh_free(s->m);
  free(s->fn);
  free(s->en);
  free(s->vn);
  free(s->el);
  free(s->patch);
  free(s->bmask);
  free(s);
}

static double dot(const double *a, const double *b) { return a[0] * b[0] + a[1] * b[1] + a[2] * b[2]; }
static void sub(const double *a, const double *b, double *r) { for (int i = 0; i < 3; i++) r[i] = a[i] - b[i]; }
static void cross(const double *a, const double *b, double *r) {
  r[0] = a[1] * b[2] - a[2] * b[1];
  r[1] = a[2] * b[0] - a[0] * b[2];
  r[2] = a[0] * b[1] - a[1] * b[0];
}
static double norm(const double *a) { return sqrt(dot(a, a)); }
static const double *vtx(const gr_mesh *m, size_t f, int k) { return m->v + 3 * (size_t)m->f[3 * f + k]; }

/* ---- faces: normals, angle weights, degeneracy ---- */
static int face_normals(solid *s, gr_err *e) {
  const gr_mesh *m = s->m;
  size_t bad = 0, first = 0;
  for (size_t t = 0; t < m->nf; t++) {
    const uint32_t *f = m->f + 3 * t;
    double ab[3], ac[3], n[3];
    sub(vtx(m, t, 1), vtx(m, t, 0), ab);
    sub(vtx(m, t, 2), vtx(m, t, 0), ac);
    cross(ab, ac, n);
    double emax = fmax(norm(ab), norm(ac)), nn = norm(n);
    if (f[0] == f[1] || f[1] == f[2] || f[0] == f[2] || !(nn > 1e-14 * emax * emax)) {
      if (!bad++) first = t;
      continue;
    }
    for (int a = 0; a < 3; a++) s->fn[3 * t + a] = n[a] / nn;
    for (int k = 0; k < 3; k++) { /* angle at vertex k */
      double u[3], w[3];
      sub(vtx(m, t, (k + 1) % 3), vtx(m, t, k), u);
      sub(vtx(m, t, (k + 2) % 3), vtx(m, t, k), w);
      double c = dot(u, w) / (norm(u) * norm(w));
      double ang = acos(fmax(-1.0, fmin(1.0, c)));
      for (int a = 0; a < 3; a++) s->vn[3 * (size_t)f[k] + a] += ang * s->fn[3 * t + a];
    }
  }
  if (bad) {
    const double *p = vtx(m, first, 0);
    return gr_fail(e, GR_EGEOM, "solid: %zu degenerate face%s (a repeated vertex or zero area), e.g. face %zu at (%.6g, %.6g, %.6g)",
                   bad, bad > 1 ? "s" : "", first, p[0], p[1], p[2]);
  }
  return GR_OK;
}

/* ---- edges: pairing, orientation, edge pseudo-normals ---- */
typedef struct side { uint32_t lo, hi; uint32_t face; unsigned char k, fwd; } side;
static int side_cmp(const void *pa, const void *pb) {
  const side *a = pa, *b = pb;
  if (a->lo != b->lo) return a->lo < b->lo ? -1 : 1;
  if (a->hi != b->hi) return a->hi < b->hi ? -1 : 1;
  return 0;
}

static int edge_fail(gr_err *e, const gr_mesh *m, const char *what, size_t n, const side *ex) {
  const double *a = m->v + 3 * (size_t)ex->lo, *b = m->v + 3 * (size_t)ex->hi;
  return gr_fail(e, GR_EGEOM, "solid: %s: %zu edge%s, e.g. (%.6g, %.6g, %.6g)-(%.6g, %.6g, %.6g)", what, n,
                 n > 1 ? "s" : "", a[0], a[1], a[2], b[0], b[1], b[2]);
}

/* Planar patches: faces joined across an edge when their normals agree to
 * 1e-12 (1 - cos; about 1.4e-6 rad), by union-find on s->patch. */
static uint32_t patch_root(uint32_t *p, uint32_t t) {
  while (p[t] != t) t = p[t] = p[p[t]];
  return t;
}
static void patch_pair(solid *s, const side *a, const side *b) {
  if (dot(s->fn + 3 * (size_t)a->face, s->fn + 3 * (size_t)b->face) > 1 - 1e-12) {
    uint32_t ra = patch_root(s->patch, a->face), rb = patch_root(s->patch, b->face);
    if (ra < rb) s->patch[rb] = ra;
    else s->patch[ra] = rb;
  } else {
    s->bmask[a->face] |= (unsigned char)(1u << a->k);
    s->bmask[b->face] |= (unsigned char)(1u << b->k);
  }
}

static int edge_normals(solid *s, gr_err *e) {
  const gr_mesh *m = s->m;
  size_t ns = 3 * m->nf;
  side *h = malloc(ns * sizeof *h);
  if (!h) return gr_fail(e, GR_EMEM, "out of memory for %zu face sides", ns);
  for (size_t t = 0; t < m->nf; t++)
    for (int k = 0; k < 3; k++) {
      uint32_t a = m->f[3 * t + k], b = m->f[3 * t + (k + 1) % 3];
      side *x = &h[3 * t + k];
      x->lo = a < b ? a : b;
      x->hi = a < b ? b : a;
      x->face = (uint32_t)t;
      x->k = (unsigned char)k;
      x->fwd = a < b;
    }
  qsort(h, ns, sizeof *h, side_cmp);
  size_t nopen = 0, nmany = 0, nflip = 0;
  const side *xopen = NULL, *xmany = NULL, *xflip = NULL;
  for (size_t i = 0; i < ns;) {
    size_t j = i;
    while (j < ns && !side_cmp(&h[i], &h[j])) j++;
    if (j - i == 1) { if (!nopen++) xopen = &h[i]; }
    else if (j - i > 2) { if (!nmany++) xmany = &h[i]; }
    else if (h[i].fwd == h[i + 1].fwd) { if (!nflip++) xflip = &h[i]; }
    else {
      double n[3];
      for (int a = 0; a < 3; a++) n[a] = s->fn[3 * h[i].face + a] + s->fn[3 * h[i + 1].face + a];
      for (int q = 0; q < 2; q++) memcpy(s->en + 9 * (size_t)h[i + q].face + 3 * h[i + q].k, n, sizeof n);
      patch_pair(s, &h[i], &h[i + 1]);
    }
    i = j;
  }
  for (size_t t = 0; t < m->nf; t++) s->patch[t] = patch_root(s->patch, (uint32_t)t);
  int rc = GR_OK;
  if (nopen) rc = edge_fail(e, m, "the mesh is not closed (open boundary edges, used by one face)", nopen, xopen);
  else if (nmany) rc = edge_fail(e, m, "the mesh is not manifold (edges shared by more than two faces)", nmany, xmany);
  else if (nflip) rc = edge_fail(e, m, "the mesh is not consistently oriented (edges traversed the same way by both faces)", nflip, xflip);
  free(h);
  return rc;
}

/* ---- self-intersection ---- */
/* Signed distances of a triangle's vertices to the plane (a, unit n). */
static void plane_dist(const double *a, const double *n, const double *const p[3], double d[3]) {
  for (int k = 0; k < 3; k++) {
    double r[3];
    sub(p[k], a, r);
    d[k] = dot(r, n);
  }
}

/* Is x (near the plane of triangle t, unit normal n) inside t, within eps? */
static int in_tri(const double *const t[3], const double *n, const double *x, double eps) {
  for (int k = 0; k < 3; k++) {
    double ed[3], r[3], c[3];
    sub(t[(k + 1) % 3], t[k], ed);
    sub(x, t[k], r);
    cross(ed, r, c);
    if (dot(c, n) < -eps * norm(ed)) return 0;
  }
  return 1;
}

/* Does an edge of A (distances da to B's plane) cross triangle B? */
static int edges_cross(const double *const A[3], const double da[3], const double *const B[3],
                       const double *nb, double eps) {
  for (int k = 0; k < 3; k++) {
    int l = (k + 1) % 3;
    double p = da[k], q = da[l];
    if ((p > eps && q > eps) || (p < -eps && q < -eps)) continue;
    if (fabs(p) <= eps && fabs(q) <= eps) continue; /* in B's plane: another edge decides */
    double t = fabs(p) <= eps ? 0 : fabs(q) <= eps ? 1 : p / (p - q);
    double x[3];
    for (int a = 0; a < 3; a++) x[a] = A[k][a] + t * (A[l][a] - A[k][a]);
    if (in_tri(B, nb, x, eps)) return 1;
  }
  return 0;
}

/* 2-D orientation in the plane dropping axis `ax`. */
static double orient2(const double *a, const double *b, const double *c, int ax) {
  int u = (ax + 1) % 3, v = (ax + 2) % 3;
  return (b[u] - a[u]) * (c[v] - a[v]) - (b[v] - a[v]) * (c[u] - a[u]);
}

static int coplanar_overlap(const double *const A[3], const double *na, const double *const B[3],
                            const double *nb, double eps) {
  for (int k = 0; k < 3; k++)
    if (in_tri(B, nb, A[k], eps) || in_tri(A, na, B[k], eps)) return 1;
  int ax = 0;
  for (int a = 1; a < 3; a++) if (fabs(na[a]) > fabs(na[ax])) ax = a;
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++) {
      const double *p = A[i], *q = A[(i + 1) % 3], *r = B[j], *s = B[(j + 1) % 3];
      double o1 = orient2(p, q, r, ax), o2 = orient2(p, q, s, ax);
      double o3 = orient2(r, s, p, ax), o4 = orient2(r, s, q, ax);
      if (o1 * o2 < 0 && o3 * o4 < 0) return 1;
    }
  return 0;
}

static int tri_tri(const solid *s, size_t ta, size_t tb, double eps) {
  const gr_mesh *m = s->m;
  const double *A[3] = {vtx(m, ta, 0), vtx(m, ta, 1), vtx(m, ta, 2)};
  const double *B[3] = {vtx(m, tb, 0), vtx(m, tb, 1), vtx(m, tb, 2)};
  const double *na = s->fn + 3 * ta, *nb = s->fn + 3 * tb;
  double db[3], da[3];
  plane_dist(A[0], na, B, db);
  if ((db[0] > eps && db[1] > eps && db[2] > eps) || (db[0] < -eps && db[1] < -eps && db[2] < -eps)) return 0;
  plane_dist(B[0], nb, A, da);
  if ((da[0] > eps && da[1] > eps && da[2] > eps) || (da[0] < -eps && da[1] < -eps && da[2] < -eps)) return 0;
  if (fabs(db[0]) <= eps && fabs(db[1]) <= eps && fabs(db[2]) <= eps) return coplanar_overlap(A, na, B, nb, eps);
  return edges_cross(A, da, B, nb, eps) || edges_cross(B, db, A, na, eps);
}

static int share_vertex(const gr_mesh *m, size_t a, size_t b) {
  for (int i = 0; i < 3; i++)
    for (int j = 0; j < 3; j++)
      if (m->f[3 * a + i] == m->f[3 * b + j]) return 1;
  return 0;
}

/* Faces in a uniform grid of cells about the mean face size, each listed in
 * every cell its box touches; a pair is tested once, in the cell holding the
 * low corner of the intersection of their boxes. */
static int self_intersections(const solid *s, gr_err *e) {
  const gr_mesh *m = s->m;
  size_t nf = m->nf;
  double glo[3], ghi[3];
  gr_mesh_bounds(m, glo, ghi);
  double diag = sqrt((ghi[0] - glo[0]) * (ghi[0] - glo[0]) + (ghi[1] - glo[1]) * (ghi[1] - glo[1]) +
                     (ghi[2] - glo[2]) * (ghi[2] - glo[2]));
  double eps = 1e-9 * diag;
  double *box = malloc(6 * nf * sizeof *box);
  if (!box) return gr_fail(e, GR_EMEM, "out of memory for face boxes");
  double h = 0;
  for (size_t t = 0; t < nf; t++) {
    double *b = box + 6 * t, ext = 0;
    for (int a = 0; a < 3; a++) {
      b[a] = fmin(vtx(m, t, 0)[a], fmin(vtx(m, t, 1)[a], vtx(m, t, 2)[a])) - eps;
      b[3 + a] = fmax(vtx(m, t, 0)[a], fmax(vtx(m, t, 1)[a], vtx(m, t, 2)[a])) + eps;
      ext = fmax(ext, b[3 + a] - b[a]);
    }
    h += ext / (double)nf;
  }
  h = fmax(h, 1e-6 * diag + 1e-300);
  size_t n[3], cells, entries;
  for (;;) { /* grow the cell until the grid and its lists stay small */
    cells = 1;
    for (int a = 0; a < 3; a++) { n[a] = (size_t)((ghi[a] - glo[a]) / h) + 1; cells *= n[a]; }
    entries = 0;
    for (size_t t = 0; t < nf && entries <= 16 * nf + 1024; t++) {
      size_t c = 1;
      for (int a = 0; a < 3; a++) c *= (size_t)((box[6 * t + 3 + a] - glo[a]) / h) - (size_t)fmax(0, (box[6 * t + a] - glo[a]) / h) + 1;
      entries += c;
    }
    if (cells <= 4 * nf + 64 && entries <= 16 * nf + 1024) break;
    h *= 1.26;
  }
  size_t *start = calloc(cells + 1, sizeof *start);
  uint32_t *list = malloc((entries ? entries : 1) * sizeof *list);
  if (!start || !list) {
    free(box); free(start); free(list);
    return gr_fail(e, GR_EMEM, "out of memory for the self-intersection grid (%zu cells)", cells);
  }
  for (int pass = 0; pass < 2; pass++) { /* count, then fill */
    for (size_t t = 0; t < nf; t++) {
      size_t c0[3], c1[3];
      for (int a = 0; a < 3; a++) {
        c0[a] = (size_t)fmax(0, (box[6 * t + a] - glo[a]) / h);
        c1[a] = (size_t)((box[6 * t + 3 + a] - glo[a]) / h);
        if (c1[a] >= n[a]) c1[a] = n[a] - 1;
        if (c0[a] > c1[a]) c0[a] = c1[a];
      }
      for (size_t z = c0[2]; z <= c1[2]; z++)
        for (size_t y = c0[1]; y <= c1[1]; y++)
          for (size_t x = c0[0]; x <= c1[0]; x++) {
            size_t c = x + n[0] * (y + n[1] * z);
            if (pass == 0) start[c + 1]++;
            else list[start[c]++] = (uint32_t)t;
          }
    }
    if (pass == 0) for (size_t c = 0; c < cells; c++) start[c + 1] += start[c];
    else for (size_t c = cells; c > 0; c--) start[c] = start[c - 1];
  }
  start[0] = 0;
  size_t found = 0, fa = 0, fb = 0;
  for (size_t c = 0; c < cells; c++) {
    size_t cx = c % n[0], cy = (c / n[0]) % n[1], cz = c / (n[0] * n[1]);
    for (size_t i = start[c]; i < start[c + 1]; i++)
      for (size_t j = i + 1; j < start[c + 1]; j++) {
        const double *a = box + 6 * (size_t)list[i], *b = box + 6 * (size_t)list[j];
        int apart = 0;
        size_t own[3];
        for (int d = 0; d < 3; d++) {
          double lo = fmax(a[d], b[d]);
          if (lo > fmin(a[3 + d], b[3 + d])) apart = 1;
          own[d] = (size_t)fmax(0, (lo - glo[d]) / h);
          if (own[d] >= n[d]) own[d] = n[d] - 1;
        }
        if (apart || own[0] != cx || own[1] != cy || own[2] != cz) continue;
        if (share_vertex(m, list[i], list[j]) || !tri_tri(s, list[i], list[j], eps)) continue;
        if (!found++) { fa = list[i] < list[j] ? list[i] : list[j]; fb = list[i] ^ list[j] ^ fa; }
      }
  }
  free(box);
  free(start);
  free(list);
  if (found) {
    const double *p = vtx(m, fa, 0);
    return gr_fail(e, GR_EGEOM, "solid: the mesh intersects itself: %zu crossing face pair%s, e.g. faces %zu and %zu near (%.6g, %.6g, %.6g)",
                   found, found > 1 ? "s" : "", fa, fb, p[0], p[1], p[2]);
  }
  return GR_OK;
}

/* ---- evaluation ---- */
/* The closest point of the mesh to p. *hint is the unsigned distance at the
 * point `from` (INFINITY: none), an upper bound of the distance at p by the
 * triangle inequality that prunes the BVH search (batches are mostly runs of
 * nearby points); it is updated to p. */
static void solid_hit(const solid *s, const double p[3], double from[3], double *hint, gr_hit *h) {
  double bound = INFINITY;
  if (isfinite(*hint)) {
    double r[3];
    sub(p, from, r);
    bound = (*hint + norm(r)) * (1 + 1e-9) + 1e-12;
  }
  gr_bvh_closest(s->bvh, p, bound, h);
  if (h->tri < 0) gr_bvh_closest(s->bvh, p, INFINITY, h);
  memcpy(from, p, 3 * sizeof *from);
  *hint = h->dist;
}

/* Signed distance at p from its closest point h, and its gradient g (may
 * be NULL). */
static double solid_signed(const solid *s, const double p[3], const gr_hit *h, double *g) {
  const gr_mesh *m = s->m;
  size_t t = (size_t)h->tri;
  const double *V[3] = {vtx(m, t, 0), vtx(m, t, 1), vtx(m, t, 2)}, *el = s->el + 4 * t;
  double r[3], tol = el[3], t4 = 4 * tol * tol;
  /* on a vertex or an edge within tol (each test screened by its square,
   * with room for rounding) */
  const double *n = s->fn + 3 * t; /* inside the face */
  for (int k = 0; k < 3 && n == s->fn + 3 * t; k++) {
    sub(h->q, V[k], r);
    if (dot(r, r) <= t4 && norm(r) <= tol) n = s->vn + 3 * (size_t)m->f[3 * t + k];
  }
  for (int k = 0; k < 3 && n == s->fn + 3 * t; k++) {
    double ed[3], c[3];
    sub(V[(k + 1) % 3], V[k], ed);
    sub(h->q, V[k], r);
    cross(ed, r, c);
    if (dot(c, c) > t4 * el[k] * el[k]) continue;
    double u = dot(r, ed) / dot(ed, ed);
    if (u >= 0 && u <= 1 && norm(c) <= tol * el[k]) n = s->en + 9 * t + 3 * k;
  }
  sub(p, h->q, r);
  double sg = (dot(r, n) >= 0 ? 1 : -1) * s->sign;
  if (g) {
    double l = h->dist > 0 ? h->dist : norm(n);
    for (int a = 0; a < 3; a++) g[a] = sg * (h->dist > 0 ? r[a] : n[a]) / l;
  }
  return sg * h->dist;
}

/* Each face's edge lengths and the feature tolerance solid_signed uses. */
static void edge_lengths(solid *s) {
  const gr_mesh *m = s->m;
  for (size_t t = 0; t < m->nf; t++) {
    double r[3], emax = 0, *el = s->el + 4 * t;
    for (int k = 0; k < 3; k++) {
      sub(vtx(m, t, (k + 1) % 3), vtx(m, t, k), r);
      el[k] = norm(r);
      emax = fmax(emax, el[k]);
    }
    el[3] = 1e-9 * emax;
  }
}

/* Points are taken in groups of up to GROUP (batches are mostly runs of
 * nearby points: the domain grid's 4 x 4 blocks, rows, contours), each
 * within R of its centre c: the triangles within U + 2R of c (U the
 * centre's distance) hold the closest point of every point of the group
 * (its closest point is within U + R of it, so within U + 2R of c). Those
 * are found once, and each point searches only them, when there are at
 * most NEAR_CAP (a mesh of few large triangles, whose boxes prune little in
 * the BVH); otherwise each point searches the BVH. A group that finds more
 * (a fine mesh) makes the next ones search the BVH directly, 1, 2, 4, ... up
 * to 64 groups after each further miss, so that a fine mesh pays little for
 * the try. (Keeping a padded list for the following groups saved 0.9 % more
 * on the L-bracket and, on a slice-grid node lying on a face, where the
 * sign is rounding, took the other one of two tied faces: one contour
 * fragment more in 500 layers. Not done.) */
#define GROUP 16
#define NEAR_CAP 24
typedef struct group_run {
  double from[3], hint; /* solid_hit's */
  int skip, miss;       /* groups left to search directly; consecutive misses */
} group_run;

/* The triangles for a group of n >= 4 points into near[] (their count, or
 * -1: search the BVH). */
static int group_list(const solid *s, size_t n, const double *x, const double *y, const double *z, group_run *w,
                      uint32_t near[NEAR_CAP]) {
  if (w->skip > 0) return w->skip--, -1;
  double lo[3] = {x[0], y[0], z[0]}, hi[3] = {x[0], y[0], z[0]}, c[3], D2 = 0;
  for (size_t i = 1; i < n; i++) {
    double p[3] = {x[i], y[i], z[i]};
    for (int a = 0; a < 3; a++) lo[a] = p[a] < lo[a] ? p[a] : lo[a], hi[a] = p[a] > hi[a] ? p[a] : hi[a];
  }
  for (int a = 0; a < 3; a++) c[a] = 0.5 * (lo[a] + hi[a]), D2 += (hi[a] - lo[a]) * (hi[a] - lo[a]);
  gr_hit h;
  solid_hit(s, c, w->from, &w->hint, &h);
  int k = gr_bvh_near(s->bvh, c, (h.dist + sqrt(D2)) * (1 + 1e-9) + 1e-12, near, NEAR_CAP); /* D = 2R */
  w->miss = k < 0 ? w->miss + 1 : 0;
  w->skip = k < 0 ? 1 << (w->miss < 7 ? w->miss - 1 : 6) : 0;
  return k;
}

static void solid_group(const solid *s, size_t n, const double *x, const double *y, const double *z, double *out,
                        double (*g)[3], group_run *w) {
  uint32_t near[NEAR_CAP];
  int k = n >= 4 ? group_list(s, n, x, y, z, w, near) : -1;
  for (size_t i = 0; i < n; i++) {
    double p[3] = {x[i], y[i], z[i]};
    gr_hit h;
    if (k > 0) gr_bvh_closest_among(s->bvh, near, k, p, &h);
    else solid_hit(s, p, w->from, &w->hint, &h);
    out[i] = solid_signed(s, p, &h, g ? g[i] : NULL);
  }
}

static int solid_eval(void *ud, size_t n, const double *x, const double *y, const double *z, double *out,
                      gr_err *e) {
  (void)e;
  group_run w = {.hint = INFINITY};
  for (size_t i = 0; i < n; i += GROUP) {
    size_t m = n - i < GROUP ? n - i : GROUP;
    solid_group(ud, m, x + i, y + i, z + i, out + i, NULL, &w);
  }
  return GR_OK;
}

static int solid_grad(void *ud, size_t n, const double *x, const double *y, const double *z, double *gx,
                      double *gy, double *gz, gr_err *e) {
  (void)e;
  group_run w = {.hint = INFINITY};
  double v[GROUP], g[GROUP][3];
  for (size_t i = 0; i < n; i += GROUP) {
    size_t m = n - i < GROUP ? n - i : GROUP;
    solid_group(ud, m, x + i, y + i, z + i, v, g, &w);
    for (size_t k = 0; k < m; k++) gx[i + k] = g[k][0], gy[i + k] = g[k][1], gz[i + k] = g[k][2];
  }
  return GR_OK;
}

static gr_mesh *copy_mesh(const gr_mesh *m) {
  gr_mesh *c = gr_mesh_new();
  if (!c) return NULL;
  for (size_t i = 0; i < m->nv; i++)
    if (gr_mesh_add_vertex(c, m->v[3 * i], m->v[3 * i + 1], m->v[3 * i + 2]) < 0) return gr_mesh_free(c), NULL;
  for (size_t i = 0; i < m->nf; i++)
    if (gr_mesh_add_face(c, m->f[3 * i], m->f[3 * i + 1], m->f[3 * i + 2])) return gr_mesh_free(c), NULL;
  return c;
}

gr_field *gr_solid_field(const gr_mesh *m, gr_err *e) {
  solid *s = calloc(1, sizeof *s);
  if (!s) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  s->m = m ? copy_mesh(m) : NULL;
  if (m && !s->m) return solid_free(s), gr_fail(e, GR_EMEM, "out of memory for a copy of the mesh"), NULL;
  /* the BVH first: it refuses empty meshes, non-finite vertices and missing indices */
  if (!(s->bvh = gr_bvh_new(s->m, e))) return solid_free(s), NULL;
  s->fn = calloc(3 * m->nf, sizeof *s->fn);
  s->en = calloc(9 * m->nf, sizeof *s->en);
  s->vn = calloc(3 * m->nv, sizeof *s->vn);
  s->el = calloc(4 * m->nf, sizeof *s->el);
  s->patch = malloc(m->nf * sizeof *s->patch);
  s->bmask = calloc(m->nf, sizeof *s->bmask);
  if (!s->fn || !s->en || !s->vn || !s->el || !s->patch || !s->bmask) {
    solid_free(s);
    return gr_fail(e, GR_EMEM, "out of memory for a solid of %zu faces", m->nf), NULL;
  }
  for (size_t t = 0; t < m->nf; t++) s->patch[t] = (uint32_t)t;
  if (face_normals(s, e) || edge_normals(s, e) || self_intersections(s, e)) return solid_free(s), NULL;
  edge_lengths(s);
  double vol = gr_mesh_volume(s->m);
  if (!(fabs(vol) > 0)) return solid_free(s), gr_fail(e, GR_EGEOM, "solid: the mesh encloses no volume"), NULL;
  s->sign = vol > 0 ? 1 : -1;
  gr_field *f = gr_field_callback(solid_eval, solid_grad, s, solid_free, 1, "solid");
  if (!f) return solid_free(s), gr_fail(e, GR_EMEM, "out of memory"), NULL;
  gr_field_set_lipschitz(f, 1);
  return f;
}

int gr_solid_view_of(const gr_field *f, gr_solid_view *v) {
  const solid *s = gr_field_callback_data(f, solid_eval);
  if (!s) return 0;
  v->m = s->m;
  v->bvh = s->bvh;
  v->fn = s->fn;
  v->patch = s->patch;
  v->bmask = s->bmask;
  return 1;
}
