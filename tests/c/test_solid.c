/* test_solid.c: the solid of a closed mesh (solid.h) against analytic signed
 * distances (boxes exactly, a sphere within its chord error), and the
 * validation errors (open, non-manifold-free but misoriented, degenerate,
 * self-intersecting meshes). */
#include <stdlib.h>
#include <string.h>
#include "check.h"
#include "bvh.h"
#include "distance.h"
#include "solid.h"

static const double PI = 3.14159265358979323846;

/* deterministic uniform numbers in [0, 1) */
static double rnd(unsigned long long *s) {
  *s = *s * 6364136223846793005ULL + 1442695040888963407ULL;
  return (double)(*s >> 11) / 9007199254740992.0;
}

/* Axis-aligned box lo..hi appended to m; normals outward (inward when inv). */
static void add_box(gr_mesh *m, const double lo[3], const double hi[3], int inv) {
  static const int F[12][3] = {{0, 2, 3}, {0, 3, 1}, {4, 5, 7}, {4, 7, 6}, {0, 1, 5}, {0, 5, 4},
                               {2, 6, 7}, {2, 7, 3}, {0, 4, 6}, {0, 6, 2}, {1, 3, 7}, {1, 7, 5}};
  uint32_t base = (uint32_t)m->nv;
  for (int v = 0; v < 8; v++)
    gr_mesh_add_vertex(m, v & 1 ? hi[0] : lo[0], v & 2 ? hi[1] : lo[1], v & 4 ? hi[2] : lo[2]);
  for (int f = 0; f < 12; f++)
    gr_mesh_add_face(m, base + F[f][0], base + F[f][inv ? 2 : 1], base + F[f][inv ? 1 : 2]);
}

static double box_sd(const double p[3], const double lo[3], const double hi[3]) {
  double out = 0, in = -INFINITY;
  for (int a = 0; a < 3; a++) {
    double q = fabs(p[a] - 0.5 * (lo[a] + hi[a])) - 0.5 * (hi[a] - lo[a]);
    if (q > 0) out += q * q;
    in = fmax(in, q);
  }
  return sqrt(out) + fmin(in, 0);
}

/* A UV sphere of radius R about the origin, outward normals. */
static gr_mesh *uv_sphere(double R, int nlat, int nlon) {
  gr_mesh *m = gr_mesh_new();
  gr_mesh_add_vertex(m, 0, 0, R);
  for (int i = 1; i < nlat; i++)
    for (int j = 0; j < nlon; j++) {
      double th = PI * i / nlat, ph = 2 * PI * j / nlon;
      gr_mesh_add_vertex(m, R * sin(th) * cos(ph), R * sin(th) * sin(ph), R * cos(th));
    }
  uint32_t S = (uint32_t)m->nv;
  gr_mesh_add_vertex(m, 0, 0, -R);
#define RING(i, j) (uint32_t)(1 + ((i) - 1) * nlon + ((j) % nlon))
  for (int j = 0; j < nlon; j++) {
    gr_mesh_add_face(m, 0, RING(1, j), RING(1, j + 1));
    gr_mesh_add_face(m, S, RING(nlat - 1, j + 1), RING(nlat - 1, j));
    for (int i = 1; i < nlat - 1; i++) {
      gr_mesh_add_face(m, RING(i, j), RING(i + 1, j), RING(i + 1, j + 1));
      gr_mesh_add_face(m, RING(i, j), RING(i + 1, j + 1), RING(i, j + 1));
    }
  }
#undef RING
  return m;
}

/* Largest depth of the mesh below the sphere: R minus the smallest distance
 * of a face's plane from the centre (the chord error). */
static double chord_error(const gr_mesh *m, double R) {
  double worst = 0;
  for (size_t t = 0; t < m->nf; t++) {
    const double *a = m->v + 3 * m->f[3 * t], *b = m->v + 3 * m->f[3 * t + 1], *c = m->v + 3 * m->f[3 * t + 2];
    double u[3], w[3], n[3];
    for (int k = 0; k < 3; k++) { u[k] = b[k] - a[k]; w[k] = c[k] - a[k]; }
    n[0] = u[1] * w[2] - u[2] * w[1];
    n[1] = u[2] * w[0] - u[0] * w[2];
    n[2] = u[0] * w[1] - u[1] * w[0];
    double d = fabs(a[0] * n[0] + a[1] * n[1] + a[2] * n[2]) / sqrt(n[0] * n[0] + n[1] * n[1] + n[2] * n[2]);
    worst = fmax(worst, R - d);
  }
  return worst;
}

static double eval1(gr_field *f, double x, double y, double z) {
  double v = NAN;
  gr_err e;
  gr_field_eval(f, 1, &x, &y, &z, &v, &e);
  return v;
}

/* Largest |solid - truth| over random points of the box lo..hi (all signs
 * must agree where |truth| > tol). */
static double worst_error(gr_field *f, double (*truth)(const double *, const void *), const void *ud,
                          double lo, double hi, double tol, int *wrong_sign) {
  unsigned long long s = 11;
  enum { N = 4000 };
  static double x[N], y[N], z[N], v[N];
  for (int i = 0; i < N; i++) {
    x[i] = lo + (hi - lo) * rnd(&s);
    y[i] = lo + (hi - lo) * rnd(&s);
    z[i] = lo + (hi - lo) * rnd(&s);
  }
  gr_err e;
  if (gr_field_eval(f, N, x, y, z, v, &e)) return INFINITY;
  double worst = 0;
  *wrong_sign = 0;
  for (int i = 0; i < N; i++) {
    double p[3] = {x[i], y[i], z[i]}, t = truth(p, ud);
    worst = fmax(worst, fabs(v[i] - t));
    if (fabs(t) > tol && (t > 0) != (v[i] > 0)) (*wrong_sign)++;
  }
  return worst;
}

static const double LO[3] = {-1, -1, -1}, HI[3] = {1, 2, 0.5};
static double cube_truth(const double *p, const void *ud) { (void)ud; return box_sd(p, LO, HI); }
static const double CLO[3] = {-0.5, -0.5, -0.3}, CHI[3] = {0.5, 1, 0.2};
static double cavity_truth(const double *p, const void *ud) {
  (void)ud;
  return fmax(box_sd(p, LO, HI), -box_sd(p, CLO, CHI));
}
static double sphere_truth(const double *p, const void *ud) {
  return sqrt(p[0] * p[0] + p[1] * p[1] + p[2] * p[2]) - *(const double *)ud;
}

/* The solid of m, checked exact (1e-12 mm, and every sign) against truth
 * over random points of [lo, hi]^3; NULL (a failure) when it is refused. */
static gr_field *exact_solid(const gr_mesh *m, double (*truth)(const double *, const void *), double lo,
                             double hi, const char *label) {
  gr_err e;
  gr_field *f = gr_solid_field(m, &e);
  CHECK(f != NULL, "%s: %s", label, e.msg);
  if (!f) return NULL;
  int wrong;
  double w = worst_error(f, truth, NULL, lo, hi, 1e-9, &wrong);
  CHECK(w <= 1e-12, "%s: largest error %.3g mm", label, w);
  CHECK(wrong == 0, "%s: %d wrong signs", label, wrong);
  return f;
}

TEST(box_exact) {
  for (int inv = 0; inv < 2; inv++) {
    gr_mesh *m = gr_mesh_new();
    add_box(m, LO, HI, inv);
    CHECK(inv ? gr_mesh_volume(m) < 0 : gr_mesh_volume(m) > 0, "orientation of the test box");
    gr_field *f = exact_solid(m, cube_truth, -2.5, 3, inv ? "inverted box" : "box");
    gr_mesh_free(m); /* the solid keeps its own copy */
    if (!f) continue;
    /* just outside a corner (vertex pseudo-normal) and an edge (edge pseudo-normal) */
    CHECK_NEAR(eval1(f, 1.1, 2.1, 0.6), sqrt(0.03), 1e-12);
    CHECK_NEAR(eval1(f, 1.1, 0, 0.6), sqrt(0.02), 1e-12);
    CHECK_NEAR(eval1(f, 0, 0, 0), -0.5, 1e-12);
    CHECK_NEAR(gr_field_lipschitz(f), 1, 0);
    double x = 0.3, y = 0.2, z = 0.9, gx, gy, gz;
    gr_err e;
    CHECK(gr_field_grad(f, 1, &x, &y, &z, &gx, &gy, &gz, &e) == GR_OK, "%s", e.msg);
    CHECK(fabs(gx) < 1e-12 && fabs(gy) < 1e-12 && fabs(gz - 1) < 1e-12, "gradient above the top (%g, %g, %g)", gx, gy, gz);
    gr_field_free(f);
  }
}

TEST(box_with_cavity) {
  /* two shells: the cavity's normals point into it (out of the material),
   * so its edges are concave ones of the solid */
  gr_mesh *m = gr_mesh_new();
  add_box(m, LO, HI, 0);
  add_box(m, CLO, CHI, 1);
  gr_field *f = exact_solid(m, cavity_truth, -1.5, 2.5, "cavity");
  if (f) CHECK_NEAR(eval1(f, 0, 0, 0), 0.2, 1e-12); /* in the cavity: outside the part */
  gr_field_free(f);
  gr_mesh_free(m);
}

/* A thin tetrahedral spike: sharp convex edges and vertices, where the sign
 * needs the edge and vertex pseudo-normals (a face normal alone fails). */
static const double TET[4][3] = {{0, 0, 0}, {0.3, 0, 0}, {0.1, 0.25, 0}, {0.1, 0.08, 1.5}};
static const int TETF[4][3] = {{0, 2, 1}, {0, 1, 3}, {1, 2, 3}, {2, 0, 3}};
static void add_tet(gr_mesh *m, int inv) {
  uint32_t base = (uint32_t)m->nv;
  for (int v = 0; v < 4; v++) gr_mesh_add_vertex(m, TET[v][0], TET[v][1], TET[v][2]);
  for (int f = 0; f < 4; f++)
    gr_mesh_add_face(m, base + TETF[f][0], base + TETF[f][inv ? 2 : 1], base + TETF[f][inv ? 1 : 2]);
}
/* Truth independent of the BVH: brute-force distance, inside when behind
 * every face plane (the tetrahedron is convex). */
static double tet_sd(const double *p) {
  double d = INFINITY;
  int inside = 1;
  for (int f = 0; f < 4; f++) {
    const double *a = TET[TETF[f][0]], *b = TET[TETF[f][1]], *c = TET[TETF[f][2]];
    double q[3], u[3], w[3];
    gr_closest_on_triangle(p, a, b, c, q);
    d = fmin(d, sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2])));
    for (int k = 0; k < 3; k++) { u[k] = b[k] - a[k]; w[k] = c[k] - a[k]; }
    double n[3] = {u[1] * w[2] - u[2] * w[1], u[2] * w[0] - u[0] * w[2], u[0] * w[1] - u[1] * w[0]};
    if ((p[0] - a[0]) * n[0] + (p[1] - a[1]) * n[1] + (p[2] - a[2]) * n[2] > 0) inside = 0;
  }
  return inside ? -d : d;
}
static double tet_truth(const double *p, const void *ud) { (void)ud; return tet_sd(p); }
static const double TLO[3] = {-0.5, -0.5, -0.5}, THI[3] = {0.8, 0.8, 2};
static double tet_cavity_truth(const double *p, const void *ud) {
  (void)ud;
  return fmax(box_sd(p, TLO, THI), -tet_sd(p));
}

TEST(sharp_tetrahedron) {
  gr_mesh *m = gr_mesh_new();
  add_tet(m, 0);
  CHECK(gr_mesh_volume(m) > 0, "orientation of the test tetrahedron");
  gr_field *f = exact_solid(m, tet_truth, -0.3, 1.8, "spike");
  if (f) CHECK_NEAR(eval1(f, 0.1, 0.08, 1.6), 0.1, 1e-12); /* above the spike's tip */
  gr_field_free(f);
  gr_mesh_free(m);
  /* the same spike as a cavity in a box: sharp concave edges of the solid */
  m = gr_mesh_new();
  add_box(m, TLO, THI, 0);
  add_tet(m, 1);
  gr_field_free(exact_solid(m, tet_cavity_truth, -0.2, 1.7, "spike cavity"));
  gr_mesh_free(m);
}

TEST(sphere_within_chord_error) {
  double R = 3;
  for (int inv = 0; inv < 2; inv++) {
    gr_mesh *m = uv_sphere(R, 24, 48);
    if (inv)
      for (size_t t = 0; t < m->nf; t++) { uint32_t a = m->f[3 * t + 1]; m->f[3 * t + 1] = m->f[3 * t + 2]; m->f[3 * t + 2] = a; }
    CHECK(inv ? gr_mesh_volume(m) < 0 : gr_mesh_volume(m) > 0, "orientation of the test sphere");
    double tol = chord_error(m, R) + 1e-12;
    CHECK(tol > 1e-3 && tol < 0.05, "chord error %g", tol);
    gr_err e;
    gr_field *f = gr_solid_field(m, &e);
    CHECK(f != NULL, "%s", e.msg);
    if (f) {
      int wrong;
      double w = worst_error(f, sphere_truth, &R, -5, 5, tol, &wrong);
      CHECK(w <= tol, "inverted=%d: largest error %.4g mm > chord error %.4g", inv, w, tol);
      CHECK(wrong == 0, "inverted=%d: %d wrong signs", inv, wrong);
      CHECK_NEAR(eval1(f, 0, 0, 0), -R, tol);
      CHECK_NEAR(eval1(f, 0, 0, 4), 1, 1e-12); /* straight above the pole vertex */
      gr_field_free(f);
    }
    gr_mesh_free(m);
  }
}

/* The box LO..HI and the box lo..hi in one mesh (separate vertices). */
static gr_mesh *two_boxes(double x0, double y0, double z0, double x1, double y1, double z1) {
  gr_mesh *m = gr_mesh_new();
  double lo[3] = {x0, y0, z0}, hi[3] = {x1, y1, z1};
  add_box(m, LO, HI, 0);
  add_box(m, lo, hi, 0);
  return m;
}

static void expect_error(gr_mesh *m, const char *want1, const char *want2, const char *label) {
  gr_err e;
  gr_err_clear(&e);
  gr_field *f = gr_solid_field(m, &e);
  CHECK(f == NULL, "%s: accepted", label);
  CHECK(e.code == GR_EGEOM || e.code == GR_EARG, "%s: code %d", label, e.code);
  CHECK(strstr(e.msg, want1) && strstr(e.msg, want2), "%s: message '%s' lacks '%s' / '%s'", label, e.msg, want1, want2);
  gr_field_free(f);
}

TEST(invalid_meshes) {
  gr_mesh *m = gr_mesh_new();
  expect_error(m, "empty", "", "empty");
  add_box(m, LO, HI, 0);
  m->nf--; /* one face removed: its three edges are open */
  expect_error(m, "not closed", "3 edges, e.g. (", "open");
  m->nf++;
  uint32_t a = m->f[4];
  m->f[4] = m->f[5];
  m->f[5] = a; /* one face flipped */
  expect_error(m, "not consistently oriented", "3 edges", "misoriented");
  m->f[5] = m->f[4];
  expect_error(m, "1 degenerate face", "face 1 at (", "degenerate");
  gr_mesh_free(m);

  /* two cubes sharing one edge (its vertices merged): four faces use it */
  m = two_boxes(1, 2, -1, 2, 3, 0.5);
  for (size_t i = 36; i < 72; i++)
    for (uint32_t v = 0; v < 8; v++)
      if (!memcmp(m->v + 3 * (size_t)m->f[i], m->v + 3 * (size_t)v, 3 * sizeof(double))) m->f[i] = v;
  expect_error(m, "not manifold", "1 edge, e.g. (1, 2, -1)-(1, 2, 0.5)", "non-manifold");
  gr_mesh_free(m);
  /* two overlapping cubes merged into one mesh */
  m = two_boxes(0.5, 0.5, 0, 2, 3, 1);
  expect_error(m, "intersects itself", "faces ", "overlapping cubes");
  gr_mesh_free(m);
  /* a cube touching another along a whole face (coplanar overlap) */
  m = two_boxes(1, -1, -1, 2, 2, 0.5);
  expect_error(m, "intersects itself", "", "touching cubes");
  gr_mesh_free(m);
  /* disjoint cubes are fine */
  m = two_boxes(1.5, -1, -1, 2, 2, 0.5);
  gr_err e;
  gr_field *f = gr_solid_field(m, &e);
  CHECK(f != NULL, "disjoint cubes: %s", e.msg);
  if (f) CHECK_NEAR(eval1(f, 1.25, 0, 0), 0.25, 1e-12);
  gr_field_free(f);
  gr_mesh_free(m);
}

TEST(large_mesh_build_and_eval) {
  /* ~100k faces: validation (self-intersection grid) and evaluation stay fast */
  gr_mesh *m = uv_sphere(10, 160, 320);
  double t0 = gr_now();
  gr_err e;
  gr_field *f = gr_solid_field(m, &e);
  double t1 = gr_now();
  CHECK(f != NULL, "%s", e.msg);
  if (f) {
    enum { N = 20000 };
    static double x[N], y[N], z[N], v[N];
    unsigned long long s = 5;
    for (int i = 0; i < N; i++) { x[i] = 24 * rnd(&s) - 12; y[i] = 24 * rnd(&s) - 12; z[i] = 24 * rnd(&s) - 12; }
    double t2 = gr_now();
    gr_field_eval(f, N, x, y, z, v, &e);
    double t3 = gr_now();
    double R = 10, tol = chord_error(m, R) + 1e-12, worst = 0;
    for (int i = 0; i < N; i++) {
      double p[3] = {x[i], y[i], z[i]};
      worst = fmax(worst, fabs(v[i] - sphere_truth(p, &R)));
    }
    CHECK(worst <= tol, "largest error %.4g > %.4g", worst, tol);
    printf("    %zu faces: solid built in %.2f s, %.0f evaluations/s\n", m->nf, t1 - t0, N / (t3 - t2));
    CHECK(t1 - t0 < 30, "build took %.1f s", t1 - t0);
  }
  gr_field_free(f);
  gr_mesh_free(m);
}


/* An L-shaped prism (the profile (0,0)-(20,0)-(20,6)-(6,6)-(6,20)-(0,20),
 * 0 <= z <= 20): 20 large triangles, like the L-bracket of
 * recipes/plate_bracket.lua (whose L stands in the xz plane). */
static gr_mesh *l_prism(void) {
  static const double P[6][2] = {{0, 0}, {20, 0}, {20, 6}, {6, 6}, {6, 20}, {0, 20}};
  static const int CAP[4][3] = {{0, 1, 2}, {0, 2, 3}, {0, 3, 4}, {0, 4, 5}};
  gr_mesh *m = gr_mesh_new();
  for (int z = 0; z < 2; z++)
    for (int k = 0; k < 6; k++) gr_mesh_add_vertex(m, P[k][0], P[k][1], 20 * z);
  for (int t = 0; t < 4; t++) {
    gr_mesh_add_face(m, (uint32_t)CAP[t][0], (uint32_t)CAP[t][2], (uint32_t)CAP[t][1]); /* bottom: down */
    gr_mesh_add_face(m, 6 + (uint32_t)CAP[t][0], 6 + (uint32_t)CAP[t][1], 6 + (uint32_t)CAP[t][2]);
  }
  for (uint32_t k = 0; k < 6; k++) {
    uint32_t l = (k + 1) % 6;
    gr_mesh_add_face(m, k, l, 6 + l);
    gr_mesh_add_face(m, k, 6 + l, 6 + k);
  }
  return m;
}

/* Brute force: the distance to the nearest of all faces. */
static double brute_dist(const gr_mesh *m, const double p[3]) {
  double best = INFINITY;
  for (size_t t = 0; t < m->nf; t++) {
    double q[3];
    gr_closest_on_triangle(p, m->v + 3 * m->f[3 * t], m->v + 3 * m->f[3 * t + 1], m->v + 3 * m->f[3 * t + 2], q);
    best = fmin(best, sqrt((p[0] - q[0]) * (p[0] - q[0]) + (p[1] - q[1]) * (p[1] - q[1]) + (p[2] - q[2]) * (p[2] - q[2])));
  }
  return best;
}

/* n points evaluated together against brute force: every distance to
 * 1e-12 mm, and every sign against the point evaluated alone (a search of
 * the whole BVH) where it is more than 1e-9 mm from the surface; returns the
 * number of points that fail. */
static int against_brute(gr_field *f, const gr_mesh *m, size_t n, const double *x, const double *y, const double *z) {
  double *v = malloc(n * sizeof *v);
  gr_err e;
  int bad = 0;
  if (!v || gr_field_eval(f, n, x, y, z, v, &e)) bad = (int)n;
  for (size_t i = 0; i < n && !bad; i++) {
    double p[3] = {x[i], y[i], z[i]}, t = brute_dist(m, p), one = eval1(f, x[i], y[i], z[i]);
    if (fabs(fabs(v[i]) - t) > 1e-12 || (t > 1e-9 && (v[i] < 0) != (one < 0))) {
      if (!bad) printf("    (%.6f, %.6f, %.6f): %.15g, brute force %.15g, alone %.15g\n", p[0], p[1], p[2], v[i], t, one);
      bad++;
    }
  }
  free(v);
  return bad;
}

/* Windows of 102 x 102 nodes 0.025 mm apart at height z from corner o, in
 * the order the domain grid evaluates them (blocks of 4 x 4 nodes, row by
 * row of blocks; batches of 256), against brute force. */
static int windows(gr_field *f, const gr_mesh *m, const double o[2], double z) {
  enum { W = 102, NN = W * W };
  static double x[NN], y[NN], zz[NN];
  int k = 0, bad = 0;
  for (int bj = 0; bj < W; bj += 4)
    for (int bi = 0; bi < W; bi += 4)
      for (int j = bj; j < bj + 4 && j < W; j++)
        for (int i = bi; i < bi + 4 && i < W; i++, k++) x[k] = o[0] + 0.025 * i, y[k] = o[1] + 0.025 * j, zz[k] = z;
  for (int s = 0; s < NN; s += 256) bad += against_brute(f, m, NN - s < 256 ? NN - s : 256, x + s, y + s, zz + s);
  return bad;
}

TEST(few_large_faces_grouped) {
  /* a mesh of few large faces is searched by groups of nearby points
   * (solid.c), each group among the faces near it: a voxel's slice-grid
   * window (2.55 mm, in the domain grid's order) at heights through the
   * bottom, the middle and the top of the part and over its faces, edges
   * and the concave corner; clusters about random centres; and batches
   * spread over the whole part. Then a sphere of 1600 faces (lists of part
   * of the faces). Each point against the brute-force distance; this fails
   * when the faces are gathered within U + R of a group's centre instead of
   * U + 2R (13 points). */
  gr_mesh *m[2] = {l_prism(), uv_sphere(5, 20, 40)};
  gr_err e;
  gr_field *f[2] = {gr_solid_field(m[0], &e), NULL};
  CHECK(f[0] != NULL, "%s", e.msg);
  f[1] = gr_solid_field(m[1], &e);
  CHECK(f[1] != NULL, "%s", e.msg);
  static const double Z[] = {0.01, 0.3, 5.9, 6.02, 10, 19.7, 20.03}, O[][2] = {{-1, -1}, {4.8, 4.8}, {5.5, 9}, {12, 5}, {18.8, -0.5}};
  static const double SZ[] = {-4.9, -2, 0.3, 3.5}, SO[][2] = {{-1.3, -1.3}, {2.5, 2.5}, {-5.5, 1}, {3.8, -3}};
  int bad = 0, n = 0;
  for (size_t a = 0; f[0] && a < sizeof Z / sizeof *Z; a++)
    for (size_t b = 0; b < sizeof O / sizeof *O; b++, n += 102 * 102) bad += windows(f[0], m[0], O[b], Z[a]);
  for (size_t a = 0; f[1] && a < sizeof SZ / sizeof *SZ; a++)
    for (size_t b = 0; b < sizeof SO / sizeof *SO; b++, n += 102 * 102) bad += windows(f[1], m[1], SO[b], SZ[a]);
  unsigned long long sd = 7;
  double x[4096], y[4096], z[4096];
  for (int c = 0; f[0] && c < 2000; c++, n += 16) {
    double cx = 24 * rnd(&sd) - 2, cy = 24 * rnd(&sd) - 2, cz = 24 * rnd(&sd) - 2, r = c % 2 ? 0.3 : 3;
    for (int k = 0; k < 16; k++)
      x[k] = cx + r * (rnd(&sd) - 0.5), y[k] = cy + r * (rnd(&sd) - 0.5), z[k] = cz + r * (rnd(&sd) - 0.5);
    bad += against_brute(f[0], m[0], 16, x, y, z);
  }
  for (int k = 0; k < 4096; k++) x[k] = 24 * rnd(&sd) - 2, y[k] = 24 * rnd(&sd) - 2, z[k] = 24 * rnd(&sd) - 2;
  if (f[0]) bad += against_brute(f[0], m[0], 4096, x, y, z), n += 4096;
  CHECK(bad == 0, "%d of %d points differ from the brute-force distance", bad, n);
  for (int k = 0; k < 2; k++) gr_field_free(f[k]), gr_mesh_free(m[k]);
}

int main(void) {
  RUN(box_exact);
  RUN(box_with_cavity);
  RUN(sharp_tetrahedron);
  RUN(sphere_within_chord_error);
  RUN(invalid_meshes);
  RUN(large_mesh_build_and_eval);
  RUN(few_large_faces_grouped);
  DONE();
}
