/* domkey.c: the key of an STL domain's boundary near a voxel, see domain.h.
 *
 * What a trimmed voxel's template needs of the domain d is its boundary
 * near the voxel's window: d's value where |d| is small, its sign elsewhere
 * (domain.h, gr_domain_local_key). Two voxels whose boxes hold the same
 * boundary, translated by the voxel's origin, get the same key and share a
 * template: the faces of a part that run along cell faces (a bracket's
 * walls) repeat from voxel to voxel.
 *
 * The boundary inside the box is described without its triangulation (a
 * planar face cut into triangles one way or another is the same boundary):
 * for every planar patch of the mesh (solid.h) that a face of it crosses
 * the box with, its plane (unit normal and offset from the origin), and the
 * patch's own boundary edges (the creases of the surface) clipped to the
 * box, each oriented as its face runs. Inside a convex box, the plane's
 * section and those oriented segments fix the patch's region; with no
 * segment the patch covers the whole section. Coordinates are relative to
 * the origin and rounded to 1e-7 mm (normals to 1e-9): a part whose faces
 * match to that rounding shares, and a boundary that differs by more gets
 * another key. Records are sorted, duplicates dropped, and hashed. */
#include "domain.h"
#include "kb.h"
#include "solid.h"
#include <math.h>
#include <stdlib.h>
#include <string.h>

#define QX 1e-7      /* mm: rounding of coordinates and plane offsets */
#define QN 1e-9      /* rounding of unit normal components */
#define ALL_FACES 64 /* meshes up to this many faces are scanned whole */
enum { REC = 11 };   /* normal (3), offset, kind, a (3), b (3) */

typedef struct recs { long long *r; size_t n, cap; } recs;

static int rec_add(recs *s, const long long *x) {
  if (s->n == s->cap) {
    size_t c = s->cap ? 2 * s->cap : 64;
    long long *r = realloc(s->r, c * REC * sizeof *r);
    if (!r) return GR_EMEM;
    s->r = r;
    s->cap = c;
  }
  memcpy(s->r + s->n++ * REC, x, REC * sizeof *x);
  return GR_OK;
}

static int rec_cmp(const void *pa, const void *pb) {
  const long long *a = pa, *b = pb;
  for (int k = 0; k < REC; k++)
    if (a[k] != b[k]) return a[k] < b[k] ? -1 : 1;
  return 0;
}

/* Clip the convex polygon p (n points, local mm) to the box lo..hi in
 * place (room for n + 6 points); its new count. */
static int clip_poly(double (*p)[3], int n, const double *lo, const double *hi) {
  double q[12][3];
  for (int a = 0; a < 3 && n > 0; a++)
    for (int side = 0; side < 2 && n > 0; side++) {
      double lim = side ? hi[a] : lo[a], sg = side ? -1 : 1; /* inside: sg (x - lim) >= 0 */
      int m = 0;
      for (int i = 0; i < n; i++) {
        const double *A = p[i], *B = p[(i + 1) % n];
        double da = sg * (A[a] - lim), db = sg * (B[a] - lim);
        if (da >= 0) memcpy(q[m++], A, sizeof q[0]);
        if ((da >= 0) != (db >= 0)) {
          double t = da / (da - db);
          for (int c = 0; c < 3; c++) q[m][c] = A[c] + t * (B[c] - A[c]);
          q[m][a] = lim;
          m++;
        }
      }
      n = m;
      memcpy(p, q, (size_t)n * sizeof q[0]);
    }
  return n;
}

/* Area of polygon p (n points) in 3-D (half the length of its vector area). */
static double poly_area(const double (*p)[3], int n) {
  double s[3] = {0, 0, 0};
  for (int i = 1; i + 1 < n; i++) {
    double u[3], w[3];
    for (int c = 0; c < 3; c++) u[c] = p[i][c] - p[0][c], w[c] = p[i + 1][c] - p[0][c];
    s[0] += u[1] * w[2] - u[2] * w[1];
    s[1] += u[2] * w[0] - u[0] * w[2];
    s[2] += u[0] * w[1] - u[1] * w[0];
  }
  return 0.5 * sqrt(s[0] * s[0] + s[1] * s[1] + s[2] * s[2]);
}

/* Clip segment a-b (local mm) to the box (Liang-Barsky); 1 if a piece
 * longer than 1e-9 mm is left (in a, b). */
static int clip_seg(double *a, double *b, const double *lo, const double *hi) {
  double t0 = 0, t1 = 1, d[3];
  for (int c = 0; c < 3; c++) {
    d[c] = b[c] - a[c];
    double p[2] = {-d[c], d[c]}, q[2] = {a[c] - lo[c], hi[c] - a[c]};
    for (int k = 0; k < 2; k++) {
      if (p[k] == 0) {
        if (q[k] < 0) return 0;
      } else {
        double r = q[k] / p[k];
        if (p[k] < 0) t0 = fmax(t0, r);
        else t1 = fmin(t1, r);
      }
    }
  }
  if (!(t1 > t0)) return 0;
  double a0[3];
  memcpy(a0, a, sizeof a0);
  for (int c = 0; c < 3; c++) a[c] = a0[c] + t0 * d[c], b[c] = a0[c] + t1 * d[c];
  return (t1 - t0) * sqrt(d[0] * d[0] + d[1] * d[1] + d[2] * d[2]) > 1e-9;
}

/* The records of face t: its patch's plane, and its patch-bounding edges
 * clipped to the box (local coordinates, o subtracted). */
static int face_records(const gr_solid_view *sv, size_t t, const double *o, const double *lo, const double *hi,
                        recs *out) {
  const gr_mesh *m = sv->m;
  double P[12][3];
  for (int k = 0; k < 3; k++)
    for (int c = 0; c < 3; c++) P[k][c] = m->v[3 * (size_t)m->f[3 * t + k] + c] - o[c];
  double V[3][3];
  memcpy(V, P, sizeof V);
  int n = clip_poly(P, 3, lo, hi);
  if (n < 3 || !(poly_area((const double(*)[3])P, n) > 1e-12)) return GR_OK;
  size_t root = sv->patch[t];
  const double *nr = sv->fn + 3 * root;
  double off = 0;
  for (int c = 0; c < 3; c++) off += nr[c] * (m->v[3 * (size_t)m->f[3 * root] + c] - o[c]);
  long long r[REC] = {0};
  for (int c = 0; c < 3; c++) r[c] = llround(nr[c] / QN);
  r[3] = llround(off / QX);
  if (rec_add(out, r)) return GR_EMEM;
  r[4] = 1;
  for (int k = 0; k < 3; k++) {
    if (!(sv->bmask[t] >> k & 1)) continue;
    double a[3], b[3];
    memcpy(a, V[k], sizeof a);
    memcpy(b, V[(k + 1) % 3], sizeof b);
    if (!clip_seg(a, b, lo, hi)) continue;
    for (int c = 0; c < 3; c++) r[5 + c] = llround(a[c] / QX), r[8 + c] = llround(b[c] / QX);
    if (rec_add(out, r)) return GR_EMEM;
  }
  return GR_OK;
}

/* The faces that may cross the box: all of a small mesh, else the BVH's
 * within the box's half diagonal of its centre (-1: too many). */
static int box_faces(const gr_solid_view *sv, const double *o, const double *lo, const double *hi, uint32_t *out) {
  if (sv->m->nf <= ALL_FACES) {
    for (size_t t = 0; t < sv->m->nf; t++) out[t] = (uint32_t)t;
    return (int)sv->m->nf;
  }
  double c[3], r2 = 0;
  for (int a = 0; a < 3; a++) {
    c[a] = o[a] + 0.5 * (lo[a] + hi[a]);
    r2 += 0.25 * (hi[a] - lo[a]) * (hi[a] - lo[a]);
  }
  return gr_bvh_near(sv->bvh, c, sqrt(r2) * (1 + 1e-9), out, GR_BVH_NEAR_MAX);
}

int gr_domain_local_key(const gr_field *d, const double lo[3], const double hi[3], const double o[3], char key[65],
                        gr_err *e) {
  gr_solid_view sv;
  if (!d || !gr_solid_view_of(d, &sv)) return 0;
  uint32_t faces[ALL_FACES > GR_BVH_NEAR_MAX ? ALL_FACES : GR_BVH_NEAR_MAX];
  int nf = box_faces(&sv, o, lo, hi, faces);
  if (nf < 0) return 0;
  recs s = {NULL, 0, 0};
  int rc = GR_OK;
  for (int i = 0; i < nf && rc == GR_OK; i++) rc = face_records(&sv, faces[i], o, lo, hi, &s);
  if (rc == GR_OK && s.n == 0) {
    /* no boundary in the box: it is all inside or all outside */
    double c[3], f;
    for (int a = 0; a < 3; a++) c[a] = o[a] + 0.5 * (lo[a] + hi[a]);
    rc = gr_field_eval(d, 1, c, c + 1, c + 2, &f, e);
    long long r[REC] = {0};
    r[4] = f < 0 ? 2 : 3;
    if (rc == GR_OK && rec_add(&s, r)) rc = GR_EMEM;
  }
  if (rc) {
    free(s.r);
    return rc == GR_EMEM ? (gr_fail(e, GR_EMEM, "out of memory"), -1) : -1;
  }
  qsort(s.r, s.n, REC * sizeof *s.r, rec_cmp);
  size_t u = 0;
  for (size_t i = 0; i < s.n; i++)
    if (u == 0 || rec_cmp(s.r + (u - 1) * REC, s.r + i * REC)) memmove(s.r + u++ * REC, s.r + i * REC, REC * sizeof *s.r);
  gr_sha256_hex(s.r, u * REC * sizeof *s.r, key);
  free(s.r);
  return 1;
}
