/* bvh.c: closest points on triangle meshes, see bvh.h. */
#include "bvh.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

typedef struct bnode {
  double lo[3], hi[3];
  double nrm[3], slo, shi; /* slab: its triangles lie within slo <= nrm . x <= shi */
  int left;   /* child index, or -1 for a leaf */
  int right;
  int first, count; /* leaf: triangles tri[first .. first+count) */
} bnode;

struct gr_bvh {
  const gr_mesh *m;
  bnode *node;
  int nnode;
  uint32_t *tri;   /* triangle order */
  double *cen;     /* centroids 3*nf (while building) */
  double *box;     /* triangle boxes 6*nf: lo[3], hi[3] (while building) */
  double *pl;      /* triangle planes 4*nf: unit normal, offset (0s when degenerate) */
};

/* Triangle t's plane: unit normal n and offset n . a (all 0 for a triangle
 * without area: its plane distance then bounds nothing). */
static void tri_plane(const gr_mesh *m, uint32_t t, double *pl) {
  const double *a = m->v + 3 * m->f[3 * t], *b = m->v + 3 * m->f[3 * t + 1], *c = m->v + 3 * m->f[3 * t + 2];
  double u[3] = {b[0] - a[0], b[1] - a[1], b[2] - a[2]}, w[3] = {c[0] - a[0], c[1] - a[1], c[2] - a[2]};
  double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
  double l = sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
  for (int k = 0; k < 4; k++) pl[k] = 0;
  if (!(l > 0)) return;
  for (int k = 0; k < 3; k++) pl[k] = n[k] / l;
  pl[3] = pl[0] * a[0] + pl[1] * a[1] + pl[2] * a[2];
}


static void tri_box(const gr_mesh *m, uint32_t t, double *box) {
  for (int a = 0; a < 3; a++) { box[a] = INFINITY; box[3 + a] = -INFINITY; }
  for (int k = 0; k < 3; k++) {
    const double *v = m->v + 3 * m->f[3 * t + k];
    for (int a = 0; a < 3; a++) { box[a] = gr_lo(box[a], v[a]); box[3 + a] = gr_hi(box[3 + a], v[a]); }
  }
}

#define SLAB_MAX 64 /* triangles: larger nodes get no slab */

/* The slab of node n (triangles tri[first .. first+count)): along the mean
 * of their unit normals, the range of their vertices; near a smooth surface a
 * small node's slab is thin, so a point beside the surface is seen to be
 * far from it even where the node's box is near. Without a mean direction
 * (normals cancelling) the slab is unbounded. */
static void node_slab(gr_bvh *b, bnode *n, int first, int count) {
  n->slo = -INFINITY;
  n->shi = INFINITY;
  for (int a = 0; a < 3; a++) n->nrm[a] = 0;
  if (count > SLAB_MAX) return; /* so large that its surface has turned (and building stays quick) */
  double s[3] = {0, 0, 0};
  for (int i = first; i < first + count; i++)
    for (int a = 0; a < 3; a++) s[a] += b->pl[4 * (size_t)b->tri[i] + a];
  double l = sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
  if (!(l > 0.5 * count)) return; /* normals spread over more than 60 degrees on average */
  for (int a = 0; a < 3; a++) n->nrm[a] = s[a] / l;
  n->slo = INFINITY;
  n->shi = -INFINITY;
  const gr_mesh *m = b->m;
  for (int i = first; i < first + count; i++)
    for (int k = 0; k < 3; k++) {
      const double *v = m->v + 3 * m->f[3 * (size_t)b->tri[i] + k];
      double d = n->nrm[0] * v[0] + n->nrm[1] * v[1] + n->nrm[2] * v[2];
      n->slo = gr_lo(n->slo, d);
      n->shi = gr_hi(n->shi, d);
    }
}

static int build(gr_bvh *b, int first, int count) {
  int id = b->nnode++;
  bnode *n = &b->node[id];
  for (int a = 0; a < 3; a++) { n->lo[a] = INFINITY; n->hi[a] = -INFINITY; }
  double clo[3] = {INFINITY, INFINITY, INFINITY}, chi[3] = {-INFINITY, -INFINITY, -INFINITY};
  for (int i = first; i < first + count; i++) {
    const double *bx = b->box + 6 * (size_t)b->tri[i];
    for (int a = 0; a < 3; a++) {
      n->lo[a] = gr_lo(n->lo[a], bx[a]);
      n->hi[a] = gr_hi(n->hi[a], bx[3 + a]);
      double c = b->cen[3 * b->tri[i] + a];
      clo[a] = gr_lo(clo[a], c);
      chi[a] = gr_hi(chi[a], c);
    }
  }
  node_slab(b, n, first, count);
  if (count <= 4) {
    n->left = n->right = -1;
    n->first = first;
    n->count = count;
    return id;
  }
  int ax = 0;
  for (int a = 1; a < 3; a++) if (chi[a] - clo[a] > chi[ax] - clo[ax]) ax = a;
  double mid = 0.5 * (clo[ax] + chi[ax]);
  int i = first, j = first + count - 1;
  while (i <= j) {
    if (b->cen[3 * b->tri[i] + ax] < mid) i++;
    else { uint32_t t = b->tri[i]; b->tri[i] = b->tri[j]; b->tri[j] = t; j--; }
  }
  int nl = i - first;
  if (nl == 0 || nl == count) nl = count / 2; /* all centroids equal along ax */
  int l = build(b, first, nl);
  int r = build(b, first + nl, count - nl);
  n = &b->node[id];
  n->left = l;
  n->right = r;
  n->first = n->count = 0;
  return id;
}

gr_bvh *gr_bvh_new(const gr_mesh *m, gr_err *e) {
  if (!m || m->nf == 0) return gr_fail(e, GR_EARG, "distance: the mesh is empty"), NULL;
  for (size_t i = 0; i < 3 * m->nv; i++)
    if (!isfinite(m->v[i])) return gr_fail(e, GR_EGEOM, "distance: mesh vertex %zu is not finite", i / 3), NULL;
  for (size_t i = 0; i < 3 * m->nf; i++)
    if (m->f[i] >= m->nv) return gr_fail(e, GR_EGEOM, "distance: face %zu refers to missing vertex %u", i / 3, m->f[i]), NULL;
  gr_bvh *b = calloc(1, sizeof *b);
  if (!b) return gr_fail(e, GR_EMEM, "out of memory"), NULL;
  b->m = m;
  b->node = malloc(2 * m->nf * sizeof *b->node);
  b->tri = malloc(m->nf * sizeof *b->tri);
  b->cen = malloc(3 * m->nf * sizeof *b->cen);
  b->box = malloc(6 * m->nf * sizeof *b->box);
  b->pl = malloc(4 * m->nf * sizeof *b->pl);
  if (!b->node || !b->tri || !b->cen || !b->box || !b->pl) { gr_bvh_free(b); return gr_fail(e, GR_EMEM, "out of memory for BVH"), NULL; }
  for (size_t t = 0; t < m->nf; t++) {
    b->tri[t] = (uint32_t)t;
    tri_box(m, (uint32_t)t, b->box + 6 * t);
    tri_plane(m, (uint32_t)t, b->pl + 4 * t);
    for (int a = 0; a < 3; a++)
      b->cen[3 * t + a] = (m->v[3 * m->f[3 * t] + a] + m->v[3 * m->f[3 * t + 1] + a] + m->v[3 * m->f[3 * t + 2] + a]) / 3;
  }
  build(b, 0, (int)m->nf);
  /* what only building needs goes; the nodes shrink to those made */
  free(b->box);
  free(b->cen);
  b->box = b->cen = NULL;
  bnode *nodes = realloc(b->node, (size_t)b->nnode * sizeof *b->node);
  if (nodes) b->node = nodes;
  return b;
}

void gr_bvh_free(gr_bvh *b) {
  if (!b) return;
  free(b->node);
  free(b->tri);
  free(b->cen);
  free(b->box);
  free(b->pl);
  free(b);
}


/* Closest point on a triangle by its Voronoi regions (vertex, edge, face). */
void gr_closest_on_triangle(const double p[3], const double a[3], const double b[3],
                            const double c[3], double q[3]) {
  double ab[3], ac[3], ap[3];
  for (int i = 0; i < 3; i++) { ab[i] = b[i] - a[i]; ac[i] = c[i] - a[i]; ap[i] = p[i] - a[i]; }
  double d1 = gr_dot3(ab, ap), d2 = gr_dot3(ac, ap);
  if (d1 <= 0 && d2 <= 0) { memcpy(q, a, 3 * sizeof *q); return; }
  double bp[3];
  for (int i = 0; i < 3; i++) bp[i] = p[i] - b[i];
  double d3 = gr_dot3(ab, bp), d4 = gr_dot3(ac, bp);
  if (d3 >= 0 && d4 <= d3) { memcpy(q, b, 3 * sizeof *q); return; }
  double vc = d1 * d4 - d3 * d2;
  if (vc <= 0 && d1 >= 0 && d3 <= 0) {
    double v = d1 / (d1 - d3);
    for (int i = 0; i < 3; i++) q[i] = a[i] + v * ab[i];
    return;
  }
  double cp[3];
  for (int i = 0; i < 3; i++) cp[i] = p[i] - c[i];
  double d5 = gr_dot3(ab, cp), d6 = gr_dot3(ac, cp);
  if (d6 >= 0 && d5 <= d6) { memcpy(q, c, 3 * sizeof *q); return; }
  double vb = d5 * d2 - d1 * d6;
  if (vb <= 0 && d2 >= 0 && d6 <= 0) {
    double w = d2 / (d2 - d6);
    for (int i = 0; i < 3; i++) q[i] = a[i] + w * ac[i];
    return;
  }
  double va = d3 * d6 - d5 * d4;
  if (va <= 0 && (d4 - d3) >= 0 && (d5 - d6) >= 0) {
    double w = (d4 - d3) / ((d4 - d3) + (d5 - d6));
    for (int i = 0; i < 3; i++) q[i] = b[i] + w * (c[i] - b[i]);
    return;
  }
  double den = va + vb + vc;
  if (!(fabs(den) > 0)) { memcpy(q, a, 3 * sizeof *q); return; } /* degenerate */
  double v = vb / den, w = vc / den;
  for (int i = 0; i < 3; i++) q[i] = a[i] + ab[i] * v + ac[i] * w;
}

static double box_d2(const bnode *n, const double p[3]) {
  double s = 0;
  for (int a = 0; a < 3; a++) {
    double d = p[a] < n->lo[a] ? n->lo[a] - p[a] : (p[a] > n->hi[a] ? p[a] - n->hi[a] : 0);
    s += d * d;
  }
  return s;
}

/* Squared distance from p to n's slab (a lower bound, as box_d2 is; less
 * rounding: 1e-9 relative is taken off). */
static double slab_d2(const bnode *n, const double p[3]) {
  double d = n->nrm[0] * p[0] + n->nrm[1] * p[1] + n->nrm[2] * p[2];
  double g = d < n->slo ? n->slo - d : (d > n->shi ? d - n->shi : 0);
  return g * g * (1 - 1e-9);
}

/* Largest squared distance from c to a point of n's box. */
static double box_far2(const bnode *n, const double c[3]) {
  double s = 0;
  for (int a = 0; a < 3; a++) {
    double d = gr_hi(fabs(c[a] - n->lo[a]), fabs(n->hi[a] - c[a]));
    s += d * d;
  }
  return s;
}

/* The closest point to p among the count triangles tri[] nearer than
 * sqrt(*best) (squared; updated, with h), with c: only points at least
 * sqrt(r2) from c. */
static inline void tris_closest(const gr_bvh *b, const uint32_t *tri, int count, const double p[3], const double *c,
                         double r2, double *best, gr_hit *h) {
  const gr_mesh *m = b->m;
  for (int i = 0; i < count; i++) {
    uint32_t t = tri[i];
    /* the plane's distance bounds the triangle's from below: a plane
     * beyond best (by more than rounding) holds no nearer point */
    const double *pl = b->pl + 4 * (size_t)t;
    double pd = pl[0] * p[0] + pl[1] * p[1] + pl[2] * p[2] - pl[3];
    if (pd * pd > *best * (1 + 1e-9)) continue;
    double q[3];
    gr_closest_on_triangle(p, m->v + 3 * m->f[3 * t], m->v + 3 * m->f[3 * t + 1], m->v + 3 * m->f[3 * t + 2], q);
    double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
    if (d2 <= *best && !(c && (q[0] - c[0]) * (q[0] - c[0]) + (q[1] - c[1]) * (q[1] - c[1]) + (q[2] - c[2]) * (q[2] - c[2]) < r2)) {
      *best = d2;
      h->tri = t;
      memcpy(h->q, q, sizeof h->q);
    }
  }
}

/* The closest point to p within maxdist; with c, only among points at least
 * r from c (boxes wholly nearer to c are skipped). */
static void closest(const gr_bvh *b, const double p[3], double maxdist, const double *c, double r, gr_hit *h) {
  double best = isfinite(maxdist) ? maxdist * maxdist : INFINITY, r2 = r * r;
  h->tri = -1;
  h->dist = INFINITY;
  /* nodes to visit with a lower bound of their squared distance from p (box
   * and slab, computed when pushed; checked again when popped, best may
   * have shrunk) */
  int stack[128], sp = 0;
  double sd2[128];
  stack[sp] = 0;
  sd2[sp++] = box_d2(&b->node[0], p);
  while (sp) {
    sp--;
    const bnode *n = &b->node[stack[sp]];
    if (sd2[sp] > best || (c && box_far2(n, c) < r2)) continue;
    if (n->left < 0) {
      tris_closest(b, b->tri + n->first, n->count, p, c, r2, &best, h);
      continue;
    }
    double dl = box_d2(&b->node[n->left], p), dr = box_d2(&b->node[n->right], p);
    if (sp + 2 > 128) continue; /* cannot happen for balanced trees of < 2^60 triangles */
    /* the nearer child on top; a child already beyond best is not pushed */
    int near = dl < dr ? n->left : n->right, far = dl < dr ? n->right : n->left;
    double dn = dl < dr ? dl : dr, df = dl < dr ? dr : dl;
    /* (the order stays by box distance; the slab only prunes) */
    if (df <= best && (df = gr_hi(df, slab_d2(&b->node[far], p))) <= best) { stack[sp] = far; sd2[sp++] = df; }
    if (dn <= best && (dn = gr_hi(dn, slab_d2(&b->node[near], p))) <= best) { stack[sp] = near; sd2[sp++] = dn; }
  }
  if (h->tri >= 0) h->dist = sqrt(best);
}

int gr_bvh_closest(const gr_bvh *b, const double p[3], double maxdist, gr_hit *h) {
  closest(b, p, maxdist, NULL, 0, h);
  return GR_OK;
}

int gr_bvh_closest_away(const gr_bvh *b, const double p[3], double maxdist, const double c[3], double r, gr_hit *h) {
  closest(b, p, maxdist, c, r, h);
  return GR_OK;
}


int gr_bvh_near(const gr_bvh *b, const double p[3], double r, uint32_t *out, int cap) {
  if (cap > GR_BVH_NEAR_MAX) cap = GR_BVH_NEAR_MAX;
  double r2 = r * r * (1 + 1e-9), dist2[GR_BVH_NEAR_MAX];
  int stack[128], sp = 0, k = 0;
  stack[sp++] = 0;
  const gr_mesh *m = b->m;
  while (sp) {
    const bnode *n = &b->node[stack[--sp]];
    if (box_d2(n, p) > r2 || slab_d2(n, p) > r2) continue;
    if (n->left >= 0) {
      if (sp + 2 > 128) return -1;
      stack[sp++] = n->left;
      stack[sp++] = n->right;
      continue;
    }
    for (int i = n->first; i < n->first + n->count; i++) {
      uint32_t t = b->tri[i];
      double q[3];
      gr_closest_on_triangle(p, m->v + 3 * m->f[3 * t], m->v + 3 * m->f[3 * t + 1], m->v + 3 * m->f[3 * t + 2], q);
      double d2 = (p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2]);
      if (d2 > r2) continue;
      if (k == cap) return -1;
      /* nearest first (insertion): the nearest answers most points of a
       * group first, and the others' planes are then beyond it */
      int j = k++;
      for (; j > 0 && dist2[j - 1] > d2; j--) out[j] = out[j - 1], dist2[j] = dist2[j - 1];
      out[j] = t, dist2[j] = d2;
    }
  }
  return k;
}

void gr_bvh_closest_among(const gr_bvh *b, const uint32_t *tri, int n, const double p[3], gr_hit *h) {
  double best = INFINITY;
  h->tri = -1;
  h->dist = INFINITY;
  tris_closest(b, tri, n, p, NULL, 0, &best, h);
  if (h->tri >= 0) h->dist = sqrt(best);
}
