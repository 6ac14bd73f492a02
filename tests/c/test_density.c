/* test_density.c: density tables against analytic truth, field files read
 * back exactly, bad files named with their index. */
#include <stdlib.h>
#include <string.h>
#include <unistd.h>
#include "check.h"
#include "density.h"
#include "fieldfile.h"

static gr_dtable *table_res(const char *surface, int kind, double cell, int res) {
  gr_dtable_opts o = gr_dtable_defaults();
  o.surface = surface;
  o.kind = kind;
  o.cell = cell;
  o.track = 0.05;
  o.res = res;
  gr_err e;
  gr_dtable *t = gr_dtable_new(&o, &e);
  if (!t) printf("    %s\n", e.msg);
  return t;
}
/* coarse for speed: about 0.5 % at T = L/100 */
static gr_dtable *table(const char *surface, int kind, double cell) { return table_res(surface, kind, cell, 48); }

/* A thin sheet of constant half-thickness T has volume ~ area * 2T: the
 * areas per unit cell (L = 1) of Schwarz P, Schoen G and Schwarz D are
 * 2.3451, 3.0915 and 3.8377. Checked at T = L/100, L = 2 mm, to 1 %. */
TEST(thin_sheets_match_surface_area) {
  const char *names[] = {"primitive", "gyroid", "diamond"};
  double area[] = {2.3451, 3.0915, 3.8377};
  for (int s = 0; s < 3; s++) {
    gr_dtable *t = table(names[s], GR_DENS_SHEET, 2);
    CHECK(t, "%s", names[s]);
    if (!t) continue;
    double T = 0.02, want = area[s] / 2.0 * 2 * T; /* area per mm^3 is area/L */
    double got = gr_dtable_rho(t, T);
    CHECK(fabs(got / want - 1) < 0.01, "%s: rho(%g) = %.5f, area * 2T = %.5f", names[s], T, got, want);
    gr_dtable_free(t);
  }
}

/* Monotone tables, rho(0) = 0 for sheets; networks at level 0 and T = 0 fill
 * half the cell for the gyroid and diamond (phi -> -phi under a half-cell
 * shift); round trip rho -> T -> rho. */
TEST(monotone_symmetric_round_trip) {
  const char *names[] = {"gyroid", "diamond"};
  for (int s = 0; s < 2; s++)
    for (int kind = 0; kind < 2; kind++) {
      gr_dtable *t = table_res(names[s], kind, 2, 32);
      if (!t) { CHECK(0, "no table"); continue; }
      double prev = -1;
      int mono = 1;
      for (int k = 0; k <= 1000; k++) {
        double r = gr_dtable_rho(t, k * 1e-3);
        mono &= r >= prev;
        prev = r;
      }
      CHECK(mono, "%s kind %d: rho(T) decreases somewhere", names[s], kind);
      if (kind == GR_DENS_SHEET) CHECK_NEAR(gr_dtable_rho(t, 0), 0, 1e-12);
      else CHECK_NEAR(gr_dtable_rho(t, 0), 0.5, 1e-4);
      double lo, hi, tlo, thi;
      gr_dtable_range(t, &lo, &hi, &tlo, &thi);
      CHECK(lo < hi && tlo < thi, "%s kind %d: range %g..%g", names[s], kind, lo, hi);
      double worst = 0;
      for (int k = 0; k <= 200; k++) {
        double r = lo + (hi - lo) * k / 200.0, T = gr_dtable_thickness(t, r);
        worst = fmax(worst, fabs(gr_dtable_rho(t, T) - r));
      }
      CHECK(worst < 1e-4, "%s kind %d: round trip error %g", names[s], kind, worst);
      gr_dtable_free(t);
    }
}

/* Feasibility: a sheet wall of one track (2T = track) is the thinnest;
 * the refusal names the value, the point, the surface, L and the range. */
TEST(refusal_names_the_range) {
  gr_dtable *t = table("gyroid", GR_DENS_SHEET, 2);
  if (!t) { CHECK(0, "no table"); return; }
  double lo, hi, tlo, thi;
  gr_dtable_range(t, &lo, &hi, &tlo, &thi);
  CHECK_NEAR(tlo, 0.025, 1e-12);
  CHECK_NEAR(lo, gr_dtable_rho(t, 0.025), 1e-12);
  gr_err e;
  double p[3] = {1, 2, 3};
  CHECK(gr_dtable_check(t, 0.5, p, "density", &e) == GR_OK, "0.5 refused: %s", e.msg);
  CHECK(gr_dtable_check(t, 0.03, p, "density", &e) == GR_EARG, "0.03 accepted");
  CHECK(strstr(e.msg, "density 0.03 at x=1 y=2 z=3: gyroid sheet, L=2 mm, reachable") &&
        strstr(e.msg, "with a 0.05 mm track"), "%s", e.msg);
  CHECK(gr_dtable_check(t, 0.999, p, "porosity", &e) == GR_EARG && strstr(e.msg, "porosity 0.001 at") &&
        strstr(e.msg, "reachable 0.006"), "%s", e.msg);
  double v[3] = {-0.5, 0.5, 2};
  gr_dtable_apply(t, 3, v);
  CHECK(v[0] == 0 && v[1] > 0 && v[2] == 1, "apply: %g %g %g", v[0], v[1], v[2]);
  gr_dtable_free(t);
}

/* Asymmetric gyroid sheet (inside r T, outside T): the gyroid's two sides
 * are congruent (phi -> -phi under a half-cell shift), so its density is the
 * mean of the symmetric sheets of half-thickness T and r T. */
TEST(asymmetric_sheet) {
  gr_dtable_opts o = gr_dtable_defaults();
  o.surface = "gyroid";
  o.res = 32;
  o.track = 0.05;
  gr_err e;
  gr_dtable *s = gr_dtable_new(&o, &e);
  o.ratio = 0.5;
  gr_dtable *a = gr_dtable_new(&o, &e);
  CHECK(s && a, "%s", e.msg);
  if (s && a) {
    for (double T = 0.05; T < 0.4; T += 0.05)
      CHECK_NEAR(gr_dtable_rho(a, T), 0.5 * (gr_dtable_rho(s, T) + gr_dtable_rho(s, 0.5 * T)), 2e-4);
    double lo, hi, tlo, thi;
    gr_dtable_range(a, &lo, &hi, &tlo, &thi);
    CHECK_NEAR(tlo, 0.05 / 1.5, 1e-12); /* wall (1 + r) T = one track */
  }
  gr_dtable_free(s);
  gr_dtable_free(a);
}

TEST(ring_area_in_box) {
  double sq[] = {0, 0, 4, 0, 4, 4, 0, 4, 0, 0}; /* CCW 4x4, first point repeated */
  double lo[2] = {1, 1}, hi[2] = {3, 2}, lo2[2] = {3, 3}, hi2[2] = {6, 6};
  CHECK_NEAR(gr_ring_area_in_box(sq, 5, lo, hi), 2, 1e-12);
  CHECK_NEAR(gr_ring_area_in_box(sq, 4, lo2, hi2), 1, 1e-12);
  double hole[] = {0, 0, 0, 4, 4, 4, 4, 0}; /* CW */
  CHECK_NEAR(gr_ring_area_in_box(hole, 4, lo2, hi2), -1, 1e-12);
}

/* ---- field files ---- */
static double lin(double x, double y, double z) { return 0.5 + 0.1 * x - 0.2 * y + 0.05 * z + 0.01 * x * y * z; }

static void be(unsigned char *p, double v, int size) {
  unsigned char b[8];
  if (size == 4) { float f = (float)v; memcpy(b, &f, 4); }
  else memcpy(b, &v, 8);
  for (int k = 0; k < size; k++) p[k] = b[size - 1 - k]; /* little-endian host */
}

/* Write a 4x3x2 grid (origin 1,2,3, spacing 0.5,1,2) in the given format;
 * vtk: 0 ASCII, 1 binary float, 2 binary double; npy: 3 C order, 4 Fortran. */
static void write_grid(const char *path, int fmt, int cut) {
  FILE *fp = fopen(path, "wb");
  double o[3] = {1, 2, 3}, h[3] = {0.5, 1, 2};
  if (fmt <= 2) {
    fprintf(fp, "# vtk DataFile Version 3.0\nfield\n%s\nDATASET STRUCTURED_POINTS\nDIMENSIONS 4 3 2\n"
                "ORIGIN 1 2 3\nSPACING 0.5 1 2\nPOINT_DATA 24\nSCALARS rho %s 1\nLOOKUP_TABLE default\n",
            fmt ? "BINARY" : "ASCII", fmt == 1 ? "float" : "double");
    int size = fmt == 1 ? 4 : 8, m = 0;
    for (int k = 0; k < 2; k++)
      for (int j = 0; j < 3; j++)
        for (int i = 0; i < 4; i++, m++) {
          if (m >= 24 - cut) break;
          double v = lin(o[0] + i * h[0], o[1] + j * h[1], o[2] + k * h[2]);
          if (fmt == 0) fprintf(fp, "%.17g\n", v);
          else { unsigned char b[8]; be(b, v, size); fwrite(b, 1, size, fp); }
        }
  } else {
    const char *hd = fmt == 3 ? "{'descr': '<f8', 'fortran_order': False, 'shape': (4, 3, 2), }"
                              : "{'descr': '<f4', 'fortran_order': True, 'shape': (4, 3, 2), }";
    char head[128];
    int len = snprintf(head, sizeof head, "%s", hd);
    while ((10 + len + 1) % 64) head[len++] = ' ';
    head[len++] = '\n';
    fwrite("\x93NUMPY\x01\x00", 1, 8, fp);
    unsigned char hl[2] = {(unsigned char)(len & 255), (unsigned char)(len >> 8)};
    fwrite(hl, 1, 2, fp);
    fwrite(head, 1, (size_t)len, fp);
    for (int q = 0; q < 24 - cut; q++) {
      int i, j, k;
      if (fmt == 3) { i = q / 6; j = q / 2 % 3; k = q % 2; }
      else { i = q % 4; j = q / 4 % 3; k = q / 12; }
      double v = lin(o[0] + i * h[0], o[1] + j * h[1], o[2] + k * h[2]);
      if (fmt == 3) fwrite(&v, 8, 1, fp);
      else { float f = (float)v; fwrite(&f, 4, 1, fp); }
    }
  }
  fclose(fp);
}

static gr_field *open_grid(const char *path, gr_err *e) {
  gr_fieldfile_opts o = gr_fieldfile_defaults();
  o.origin[0] = 1, o.origin[1] = 2, o.origin[2] = 3;
  o.spacing[0] = 0.5, o.spacing[1] = 1, o.spacing[2] = 2;
  return gr_field_file(path, &o, e);
}

/* Every format reads back at its grid points (float32 to its precision) and
 * is trilinear in between: a + bx + cy + dz + e xyz is reproduced exactly. */
TEST(field_files_read_back) {
  char path[64];
  for (int fmt = 0; fmt <= 4; fmt++) {
    snprintf(path, sizeof path, "/tmp/gradus_test_density_%d.%s", (int)getpid(), fmt <= 2 ? "vtk" : "npy");
    write_grid(path, fmt, 0);
    gr_err e;
    gr_field *f = open_grid(path, &e);
    CHECK(f, "format %d: %s", fmt, e.msg);
    if (!f) continue;
    double tol = (fmt == 1 || fmt == 4) ? 1e-6 : 1e-12;
    double worst = 0;
    for (int q = 0; q < 24; q++) {
      double x = 1 + (q % 4) * 0.5, y = 2 + (q / 4 % 3), z = 3 + 2 * (q / 12), v;
      gr_field_eval(f, 1, &x, &y, &z, &v, &e);
      worst = fmax(worst, fabs(v - lin(x, y, z)));
    }
    CHECK(worst <= tol, "format %d: grid points off by %g", fmt, worst);
    double x = 1.3, y = 3.7, z = 4.1, v;
    CHECK(gr_field_eval(f, 1, &x, &y, &z, &v, &e) == GR_OK, "%s", e.msg);
    CHECK_NEAR(v, lin(x, y, z), 10 * tol);
    x = 9;
    CHECK(gr_field_eval(f, 1, &x, &y, &z, &v, &e) == GR_EARG && strstr(e.msg, path) && strstr(e.msg, "outside the grid"), "%s", e.msg);
    gr_field_free(f);
    unlink(path);
  }
}

/* Truncated data, a wrong shape, NaN: the message names the file and the index. */
TEST(bad_field_files) {
  char path[64];
  gr_err e;
  for (int fmt = 0; fmt <= 3; fmt += 1) {
    if (fmt == 2) continue;
    snprintf(path, sizeof path, "/tmp/gradus_test_density_bad_%d.%s", (int)getpid(), fmt <= 2 ? "vtk" : "npy");
    write_grid(path, fmt, 3); /* the last 3 values missing: first missing is value 22 */
    CHECK(!open_grid(path, &e) && strstr(e.msg, path) && strstr(e.msg, "value 22 of 24") && strstr(e.msg, "index"), "format %d: %s", fmt, e.msg);
    unlink(path);
  }
  snprintf(path, sizeof path, "/tmp/gradus_test_density_nan_%d.vtk", (int)getpid());
  FILE *fp = fopen(path, "w");
  fprintf(fp, "# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 1\nORIGIN 0 0 0\n"
              "SPACING 1 1 1\nPOINT_DATA 4\nSCALARS r float\nLOOKUP_TABLE default\n1 2 nan 4\n");
  fclose(fp);
  CHECK(!open_grid(path, &e) && strstr(e.msg, path) && strstr(e.msg, "index (0, 1, 0)"), "%s", e.msg);
  fp = fopen(path, "w");
  fprintf(fp, "# vtk DataFile Version 3.0\nx\nASCII\nDATASET STRUCTURED_POINTS\nDIMENSIONS 2 2 2\nORIGIN 0 0 0\n"
              "SPACING 1 1 1\nPOINT_DATA 4\nSCALARS r float\nLOOKUP_TABLE default\n1 2 3 4\n");
  fclose(fp);
  CHECK(!open_grid(path, &e) && strstr(e.msg, path) && strstr(e.msg, "POINT_DATA 4 does not match DIMENSIONS 2 2 2"), "%s", e.msg);
  unlink(path);
  snprintf(path, sizeof path, "/tmp/gradus_test_density_2d_%d.npy", (int)getpid());
  fp = fopen(path, "wb");
  const char *hd = "{'descr': '<f8', 'fortran_order': False, 'shape': (2, 2), }                                                     \n";
  fwrite("\x93NUMPY\x01\x00", 1, 8, fp);
  unsigned char hl[2] = {(unsigned char)strlen(hd), 0};
  fwrite(hl, 1, 2, fp);
  fwrite(hd, 1, strlen(hd), fp);
  double z[4] = {0};
  fwrite(z, 8, 4, fp);
  fclose(fp);
  CHECK(!open_grid(path, &e) && strstr(e.msg, path) && strstr(e.msg, "2 dimension(s)"), "%s", e.msg);
  unlink(path);
}

int main(void) {
  RUN(thin_sheets_match_surface_area);
  RUN(monotone_symmetric_round_trip);
  RUN(refusal_names_the_range);
  RUN(asymmetric_sheet);
  RUN(ring_area_in_box);
  RUN(field_files_read_back);
  RUN(bad_field_files);
  DONE();
}
