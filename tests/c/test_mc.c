/* test_mc.c: marching cubes against analytic truth (cube configurations,
 * manifoldness of random grids, sphere area and volume). */
#include <stdlib.h>
#include <string.h>
#include <pthread.h>
#include "check.h"
#include "mc.h"

static gr_grid3 grid(int n, double h, double x0, double *v) {
  gr_grid3 g = {n, n, n, x0, x0, x0, h, h, h, v};
  return g;
}

/* Every corner sign pattern of one cube: the surface's boundary lies on the
 * cube faces (border edges only), no non-manifold or misoriented edges. */
TEST(all_256_cases) {
  double vals[3] = {0.3, 1.0, 2.5};
  for (int c = 0; c < 256; c++)
    for (int s = 0; s < 3; s++) {
      double v[8];
      for (int i = 0; i < 8; i++) v[i] = (c >> i & 1) ? vals[(i + s) % 3] : -vals[(i * 2 + s) % 3];
      gr_grid3 g = grid(2, 1, 0, v);
      gr_err e;
      gr_mesh *m = gr_mc(&g, 0, &e);
      CHECK(m != NULL, "case %d: %s", c, e.msg);
      if (!m) continue;
      gr_mesh_topo t;
      gr_mesh_topology(m, &t, &e);
      CHECK(t.nonmanifold_edges == 0 && t.misoriented_edges == 0 && t.degenerate_faces == 0,
            "case %d: nm %zu mis %zu deg %zu", c, t.nonmanifold_edges, t.misoriented_edges,
            t.degenerate_faces);
      CHECK((c == 0 || c == 255) == (m->nf == 0), "case %d: %zu faces", c, m->nf);
      /* one vertex per crossed cube edge (two coordinates 0 or 1); any
       * other vertex is a loop-centroid fallback strictly inside */
      int crossed = 0, on = 0;
      for (int a = 0; a < 8; a++)
        for (int d = 0; d < 3; d++)
          if (!(a >> d & 1) && ((c >> a & 1) != (c >> (a | 1 << d) & 1))) crossed++;
      for (size_t i = 0; i < m->nv; i++) {
        int onb = 0;
        for (int d = 0; d < 3; d++) onb += m->v[3 * i + d] == 0 || m->v[3 * i + d] == 1;
        on += onb >= 2;
        if (onb < 2)
          for (int d = 0; d < 3; d++)
            CHECK(m->v[3 * i + d] > 0 && m->v[3 * i + d] < 1, "case %d vertex %zu", c, i);
      }
      CHECK(on == crossed, "case %d: %d edge vertices, %d crossed edges", c, on, crossed);
      gr_mesh_free(m);
    }
}

/* Random grids with a negative border give closed, edge-manifold,
 * consistently oriented meshes, including ambiguous faces. */
TEST(random_closed) {
  srand(7);
  int n = 14;
  double *v = malloc(sizeof(double) * n * n * n);
  for (int trial = 0; trial < 20; trial++) {
    for (int k = 0; k < n; k++) for (int j = 0; j < n; j++) for (int i = 0; i < n; i++) {
      int border = i == 0 || j == 0 || k == 0 || i == n - 1 || j == n - 1 || k == n - 1;
      v[i + n * (j + n * k)] = border ? -1 : (double)rand() / RAND_MAX * 2 - 1;
    }
    gr_grid3 g = grid(n, 0.5, -1, v);
    gr_err e;
    gr_mesh *m = gr_mc(&g, trial % 2 ? 0.0 : 0.2, &e);
    CHECK(m != NULL, "%s", e.msg);
    gr_mesh_topo t;
    gr_mesh_topology(m, &t, &e);
    CHECK(t.boundary_edges == 0 && t.nonmanifold_edges == 0 && t.misoriented_edges == 0,
          "trial %d: b %zu nm %zu mis %zu", trial, t.boundary_edges, t.nonmanifold_edges,
          t.misoriented_edges);
    CHECK(t.degenerate_faces == 0, "trial %d: %zu degenerate", trial, t.degenerate_faces);
    /* positive region inside, normals point into it: negative volume */
    CHECK(gr_mesh_volume(m) < 0, "volume %g", gr_mesh_volume(m));
    gr_mesh_free(m);
  }
  free(v);
}

static gr_mesh *sphere(int n, double R) {
  double L = 1.2 * R, h = 2 * L / (n - 1);
  double *v = malloc(sizeof(double) * n * n * n);
  for (int k = 0; k < n; k++) for (int j = 0; j < n; j++) for (int i = 0; i < n; i++) {
    double x = -L + i * h, y = -L + j * h, z = -L + k * h;
    v[i + n * (j + n * k)] = sqrt(x * x + y * y + z * z) - R;
  }
  gr_grid3 g = grid(n, h, -L, v);
  gr_err e;
  gr_mesh *m = gr_mc(&g, 0, &e);
  free(v);
  return m;
}

/* Sphere phi = |p| - R (positive outside): closed, Euler 2, outward normals,
 * area and volume converge to 4 pi R^2 and 4/3 pi R^3. */
TEST(sphere_converges) {
  double R = 3, A = 4 * M_PI * R * R, V = 4.0 / 3 * M_PI * R * R * R;
  double pa = 1e9, pv = 1e9;
  int ns[3] = {12, 30, 80};
  for (int q = 0; q < 3; q++) {
    gr_mesh *m = sphere(ns[q], R);
    gr_mesh_topo t;
    gr_err e;
    gr_mesh_topology(m, &t, &e);
    CHECK(t.boundary_edges == 0 && t.euler == 2, "n %d: b %zu euler %ld", ns[q], t.boundary_edges, t.euler);
    /* MC areas: volume here is of the outside-pointing mesh; positive means
     * normals point to phi > 0 (outward) */
    double ea = fabs(gr_mesh_area(m) - A) / A, ev = fabs(gr_mesh_volume(m) - V) / V;
    CHECK(gr_mesh_volume(m) > 0, "volume %g", gr_mesh_volume(m));
    CHECK(ea < pa && ev < pv, "n %d: errors %g %g did not decrease", ns[q], ea, ev);
    pa = ea; pv = ev;
    gr_mesh_free(m);
  }
  CHECK(pa < 0.01 && pv < 0.01, "fine errors %g %g", pa, pv);
}
/* Sampling on several threads (gr_mc_field_mt) gives the very mesh of one
 * thread: a gyroid over 3.5 x 3 x 2.5 cells, vertices bit for bit and faces
 * index for index, with 2 and 3 threads, refined and not. */
TEST(threads_same_mesh) {
  gr_err e;
  gr_field *f = gr_field_tpms("gyroid", 2, NULL, 0.3, &e);
  CHECK(f != NULL, "%s", e.msg);
  if (!f) return;
  double lo[3] = {-0.3, 0.1, 0}, hi[3] = {6.7, 6.1, 5};
  int n[3] = {71, 61, 51};
  for (int refine = 0; refine < 2; refine++) {
    gr_mesh *a = gr_mc_field(f, lo, hi, n, refine, &e);
    CHECK(a != NULL && a->nf > 1000, "one thread: %s", e.msg);
    for (int th = 2; th <= 3 && a; th++) {
      gr_mesh *b = gr_mc_field_mt(f, lo, hi, n, refine, th, &e);
      CHECK(b != NULL, "%d threads: %s", th, e.msg);
      if (!b) continue;
      CHECK(b->nv == a->nv && b->nf == a->nf, "%d threads: %zu/%zu vertices, %zu/%zu faces", th, b->nv, a->nv, b->nf,
            a->nf);
      if (b->nv == a->nv && b->nf == a->nf)
        CHECK(!memcmp(a->v, b->v, 3 * a->nv * sizeof *a->v) && !memcmp(a->f, b->f, 3 * a->nf * sizeof *a->f),
              "%d threads, refine %d: the same vertices and faces", th, refine);
      gr_mesh_free(b);
    }
    gr_mesh_free(a);
  }
  gr_field_free(f);
}

/* A sphere of radius 2 as a field that is not thread-safe: it notes any
 * call from a thread other than the one that made it. */
typedef struct lone { pthread_t owner; int foreign; } lone;
static int lone_fn(void *ud, size_t n, const double *x, const double *y, const double *z, double *out, gr_err *e) {
  (void)e;
  lone *l = ud;
  if (!pthread_equal(pthread_self(), l->owner)) l->foreign = 1;
  for (size_t i = 0; i < n; i++) out[i] = sqrt(x[i] * x[i] + y[i] * y[i] + z[i] * z[i]) - 2;
  return GR_OK;
}

/* gr_mc_field_mt on a field that is not thread-safe samples on the calling
 * thread only, and gives the mesh of one thread. */
TEST(threads_not_threadsafe) {
  lone l = {pthread_self(), 0};
  gr_field *f = gr_field_callback(lone_fn, NULL, &l, NULL, 0, "lone sphere");
  double lo[3] = {-3, -3, -3}, hi[3] = {3, 3, 3};
  int n[3] = {31, 31, 31};
  gr_err e;
  gr_mesh *a = gr_mc_field(f, lo, hi, n, 1, &e), *b = gr_mc_field_mt(f, lo, hi, n, 1, 4, &e);
  CHECK(a && b && a->nf > 100 && a->nv == b->nv && a->nf == b->nf, "meshes made");
  if (a && b && a->nv == b->nv && a->nf == b->nf)
    CHECK(!memcmp(a->v, b->v, 3 * a->nv * sizeof *a->v) && !memcmp(a->f, b->f, 3 * a->nf * sizeof *a->f), "the same mesh");
  CHECK(!l.foreign, "never evaluated on another thread");
  gr_mesh_free(a);
  gr_mesh_free(b);
  gr_field_free(f);
}

int main(void) {
  RUN(all_256_cases);
  RUN(random_closed);
  RUN(sphere_converges);
  RUN(threads_same_mesh);
  RUN(threads_not_threadsafe);
  DONE();
}
